// The patient's structures as the page shows them (issue 41, docs/ANATOMY.md): colours, each
// target's clearance in one cell, the commands the Structures panel composes, and the robot
// placement's axis for the slices. Pure, so the rules read (and are tested) in one place.
import { add, dot, scale, sub } from "./geometry";
import type { ClearanceState, PlacementInfo, StructureInfo, TargetState, Vec3 } from "./state";

export const kRoles = ["target", "avoid", "shown"] as const;
export const kApproachSides = ["inferior", "superior", "anterior", "posterior", "left", "right"] as const;
export const kProposalColour = "#ce93d8";
export const kPlacementColour = "#76ff03";

// A structure's colour (0-1 per channel) as CSS.
export function cssColour([r, g, b]: Vec3): string {
  const byte = (x: number) => Math.round(255 * Math.min(1, Math.max(0, x)));
  return `rgb(${byte(r)}, ${byte(g)}, ${byte(b)})`;
}

// How much room a structure leaves: the distance less its margin and the uncertainty there.
// Negative: too close (lock_plan refuses unless overridden).
export const slack_mm = (c: ClearanceState) => c.distance_mm - c.margin_mm - c.uncertainty_mm;

const distanceText = (c: ClearanceState) =>
  c.distance_mm < 0 ? `${(-c.distance_mm).toFixed(2)} mm into` : `${c.beyond_reach ? "> " : ""}${c.distance_mm.toFixed(2)} mm`;

// One line per structure, as `ignavctl targets ls` prints them.
export function clearanceLine(c: ClearanceState): string {
  return (
    `${c.structure}: ${distanceText(c)} at the ${c.part}, margin ${c.margin_mm.toFixed(1)} mm + ` +
    `uncertainty ${c.uncertainty_mm.toFixed(2)} mm${c.too_close ? ": TOO CLOSE" : ""}`
  );
}

export interface ClearanceCell {
  text: string; // the structure with the least room, and its distance; "–" without any
  too_close: boolean; // lock_plan refuses the target (no override)
  overridden: boolean; // too close, and an operator said why it may be planned
  title: string; // every structure, the refusal or the override's reason
}

// A target's clearance in one cell: the avoided structure it comes closest to after the margin
// and uncertainty (not merely the nearest), the whole list in the tooltip.
export function clearanceCell(target: TargetState): ClearanceCell {
  const rows = target.clearances ?? [];
  if (rows.length === 0) {
    return { text: "–", too_close: false, overridden: false, title: "no avoided structure (load_structures)" };
  }
  const tightest = rows.reduce((a, b) => (slack_mm(b) < slack_mm(a) ? b : a));
  const refused = (target.clearance_refusal ?? "") !== "";
  const overridden = refused && (target.clearance_override ?? "") !== "";
  const lines = rows.map(clearanceLine);
  const refusal = target.clearance_refusal ?? "";
  if (refused) lines.push(overridden ? `overridden (${target.clearance_override}): ${refusal}` : refusal);
  return {
    text: `${tightest.structure} ${distanceText(tightest)}${overridden ? " (overridden)" : refused ? ": too close" : ""}`,
    too_close: refused && !overridden,
    overridden,
    title: lines.join("\n"),
  };
}

// structure_role's text: NAME ROLE [MARGIN_MM] (avoid takes a margin, the others none).
export function roleCommand(name: string, role: string, margin_mm: number): string {
  return role === "avoid" ? `${name} ${role} ${margin_mm}` : `${name} ${role}`;
}

// propose_targets' text: STRUCTURE SPACING_MM.
export const proposeCommand = (name: string, spacing_mm: number) => `${name} ${spacing_mm}`;

// plan_seeds' text: STRUCTURE [rx=GY] [strength=U]; a value not given (NaN, ≤ 0 stays: the server
// names what is wrong) is the site's.
export function seedPlanCommand(name: string, rx_Gy: number, strength_U: number): string {
  let text = name;
  if (Number.isFinite(rx_Gy)) text += ` rx=${rx_Gy}`;
  if (Number.isFinite(strength_U)) text += ` strength=${strength_U}`;
  return text;
}

// place_robot's text: STRUCTURE [from SIDE] ("": the site's approach).
export const placeCommand = (name: string, side: string) => (side ? `${name} from ${side}` : name);

// The structures a command may be about: those the site or an operator made targets first (what
// one proposes targets in or places the robot for), then the rest.
export function structureChoices(structures: StructureInfo[]): string[] {
  const targets = structures.filter((s) => s.role === "target").map((s) => s.name);
  return [...targets, ...structures.filter((s) => s.role !== "target").map((s) => s.name)];
}

// The placement search's progress, "" when there is none to show.
export function progressText(done: number, total: number): string {
  if (total <= 0) return "";
  return `${Math.round((100 * Math.min(done, total)) / total)} % (${done} of ${total})`;
}

export const placementLabel = (index: number) => (index === 0 ? "proposed" : `alternative ${index}`);

// The proposed insertion axis for the slices: from the robot's origin through the skin's entry to
// as deep as the structure goes along it (its bounding box's farthest corner).
export function placementAxis(placement: PlacementInfo, bounds_lps: number[] | undefined): Vec3[] {
  const { origin_lps, axis_lps, entry_lps } = placement;
  let depth_mm = dot(sub(entry_lps, origin_lps), axis_lps);
  if (bounds_lps && bounds_lps.length === 6) {
    for (let corner = 0; corner < 8; ++corner) {
      const p: Vec3 = [0, 1, 2].map((i) => bounds_lps[(corner >> i) & 1 ? i + 3 : i]!) as Vec3;
      depth_mm = Math.max(depth_mm, dot(sub(p, origin_lps), axis_lps));
    }
  }
  return [origin_lps, add(origin_lps, scale(axis_lps, depth_mm))];
}
