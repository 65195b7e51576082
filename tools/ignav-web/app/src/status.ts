// How a target is shown: one status, one colour, derived from the target and the workflow, the
// approval and the motion around it. Pure, so the rule reads in one place.
import type { ApprovalState, MotionState, TargetState } from "./state";

export type DisplayStatus =
  | "outside_volume" // outside the loaded CT: never imaged, so lock_plan refuses it
  | "unregistered" // no registration yet: no robot coordinates
  | "unreachable" // outside the workspace (the server says why)
  | "reachable" // feasible, the plan still editable
  | "planned" // feasible, in a locked plan
  | "awaiting_approval" // the pending approval request moves the robot to it
  | "moving" // an approved motion to it is under way
  | "reached";

export interface TargetDisplay {
  status: DisplayStatus;
  label: string;
  colour: string; // CSS colour of its marker, path and status cell
  detail: string; // for a tooltip: the server's reason or message, and any path warning
  path_warning: string; // "" or: the planned path leaves the loaded CT (where, for how long)
}

const kLabel: Record<DisplayStatus, string> = {
  outside_volume: "outside the CT",
  unregistered: "unregistered",
  unreachable: "unreachable",
  reachable: "reachable",
  planned: "planned",
  awaiting_approval: "awaiting approval",
  moving: "moving",
  reached: "reached",
};

export const kStatusColour: Record<DisplayStatus, string> = {
  outside_volume: "#8d6e63",
  unregistered: "#9e9e9e",
  unreachable: "#f44336",
  reachable: "#4caf50",
  planned: "#00bcd4",
  awaiting_approval: "#ff9800",
  moving: "#2196f3",
  reached: "#e040fb",
};

// Phases in which the plan is still being edited; in every other phase it has been locked (or
// the workflow has not got as far as a plan).
const kEditablePhases = new Set(["startup", "imaging", "registration", "planning"]);

export function isPlanLocked(phase: string): boolean {
  return !kEditablePhases.has(phase);
}

export function targetDisplay(
  target: TargetState,
  phase: string,
  approval: ApprovalState | undefined,
  motion: MotionState | undefined,
): TargetDisplay {
  const status = displayStatus(target, phase, approval, motion);
  const reason = target.reach && target.reach !== "reachable" ? `${target.reach}: ` : "";
  let detail = target.message ? `${reason}${target.message}` : target.reach;
  // The server's message names the distance when it has one; without, the verdict still shows.
  if (status === "outside_volume" && !target.message) detail = "outside the loaded CT: lock_plan refuses it";
  const path_warning = target.path_warning ?? "";
  // The server's message carries the warning already; older messages, or none, may not.
  if (path_warning && !detail.includes(path_warning)) detail = detail ? `${detail}; ${path_warning}` : path_warning;
  return { status, label: kLabel[status], colour: kStatusColour[status], detail, path_warning };
}

function displayStatus(
  target: TargetState,
  phase: string,
  approval: ApprovalState | undefined,
  motion: MotionState | undefined,
): DisplayStatus {
  // As the server rules (Target::status): where the needle has been stays "reached".
  if (target.status === "outside_volume" || (target.outside_volume && target.status !== "reached")) {
    return "outside_volume";
  }
  if (target.status === "unregistered" || !target.registered) return "unregistered";
  if (target.status === "unreachable" || !target.reachable) return "unreachable";
  if (motion?.state === "moving" && motion.target_id === target.id) return "moving";
  if (approval?.status === "pending" && approval.target_id === target.id) return "awaiting_approval";
  if (target.status === "reached") return "reached";
  return isPlanLocked(phase) ? "planned" : "reachable";
}
