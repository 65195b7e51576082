// How a target is shown: one status, one colour, derived from the target and the workflow, the
// approval and the motion around it. Pure, so the rule reads in one place.
import type { Answer, ApprovalState, JobOutcomeMessage, MotionState, TargetState } from "./state";

export type DisplayStatus =
  | "outside_volume" // outside the loaded CT: never imaged, so lock_plan refuses it
  | "unregistered" // no registration yet: no robot coordinates
  | "unreachable" // outside the workspace (the server says why)
  | "too_close" // its needle passes closer to an avoided structure than the margin: lock_plan refuses it
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
  too_close: "too close",
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
  too_close: "#ff5722",
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

// The robot reaches the target (its joints are known), whether or not the plan may take it:
// `reachable` is "plannable" (within reach, and no structure or compensation refuses it).
export function withinReach(target: TargetState): boolean {
  return target.registered && (target.reachable || target.reach === "reachable");
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
  // Within reach but refused for a structure until an operator overrides it (issue 41; the
  // server's `reachable` and status then say not plannable); a reached one stays reached.
  if (withinReach(target) && target.clearance_refusal && !target.clearance_override && target.status !== "reached") {
    return "too_close";
  }
  // Where the needle has been stays reached, whatever is refused about it since (structures
  // loaded after the motion make `reachable`, "plannable", false).
  if (target.status === "reached") return "reached";
  if (target.status === "unreachable" || !target.reachable) return "unreachable";
  if (motion?.state === "moving" && motion.target_id === target.id) return "moving";
  if (approval?.status === "pending" && approval.target_id === target.id) return "awaiting_approval";
  return isPlanLocked(phase) ? "planned" : "reachable";
}

// The reply line: "accepted" (with the new target's id, or what a background job started says) or
// the server's reason.
export function replyText(what: string, answer: Answer): string {
  if (answer.type === "reply") {
    if (!answer.accepted) return `${what}: rejected: ${answer.error_code}: ${answer.message}`;
    const target = answer.target_id ? ` (target ${answer.target_id})` : "";
    return `${what}: accepted${target}${answer.job > 0 ? `: ${answer.message}` : ""}`;
  }
  if (answer.type === "error") return `${what}: failed: ${answer.code}: ${answer.message}`;
  return `${what}: unexpected answer ${answer.type}`;
}

// The job line: the background job a command of this page started, then what became of it (the
// server's JobOutcome: done, failed with why, or stale: no longer awaited, it changed nothing).
export function jobStartedText(command: string, job: number): string {
  return `${command}: job #${job} running…`;
}

export function jobOutcomeText(outcome: JobOutcomeMessage): string {
  const verdict = outcome.status === "stale" ? "stale (changed nothing)" : outcome.status;
  return `${outcome.kind} #${outcome.job}: ${verdict}${outcome.message ? `: ${outcome.message}` : ""}`;
}
