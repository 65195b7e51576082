// The closed loop as the page shows it (issue 23): where each seed of the confirmation CT lies on
// the planning CT, next to its planned target, and the targeting error in words. Pure, so the
// rule reads in one place.
import { invert, transformPoint } from "./geometry";
import type { ErrorStats, MeasuredTargetState, RegistrationState, TargetState, Vec3, VerificationState } from "./state";

export interface SeedMarker {
  seed_id: number;
  target_id: number; // 0: an extra seed (matched to no target)
  lps: Vec3; // on the planning CT, where the slices come from
  planned_lps: Vec3 | null; // its target's marker (the line is drawn between them)
  error_mm: number | null;
}

// The seeds to draw on the planning CT's slices: each matched one beside its target, and each
// extra one that nobody rejected. A seed's own LPS is on the confirmation CT; its robot
// coordinates through the planning registration's inverse put it on the planning CT exactly
// (the robot frame is the one both scans share), so the line to its target is the measured error
// vector. Without a registration (none, or rejected since) the confirmation CT's LPS is the best
// there is: the same frame when the registration was reused.
export function seedMarkers(
  verification: VerificationState | undefined,
  registration: RegistrationState | undefined,
  targets: Record<string, TargetState> | undefined,
): SeedMarker[] {
  if (!verification || (verification.status !== "measured" && verification.status !== "unmatched")) return [];
  let robotToImage: number[] | null = null;
  if (registration?.status === "registered" && registration.image_to_robot.length === 16) {
    try {
      robotToImage = invert(registration.image_to_robot);
    } catch {
      robotToImage = null;
    }
  }
  const onPlanningCt = (robot: Vec3, confirmationLps: Vec3): Vec3 =>
    robotToImage ? transformPoint(robotToImage, robot) : confirmationLps;
  const markers: SeedMarker[] = verification.targets.map((row) => ({
    seed_id: row.seed_id,
    target_id: row.target_id,
    lps: onPlanningCt(row.actual_robot, row.actual_lps),
    planned_lps: targets?.[String(row.target_id)]?.lps ?? row.planned_lps,
    error_mm: row.error_mm,
  }));
  const extra = new Set(verification.extra_seeds);
  for (const seed of verification.seeds) {
    if (seed.rejected || !extra.has(seed.id)) continue;
    markers.push({ seed_id: seed.id, target_id: 0, lps: onPlanningCt(seed.robot, seed.lps), planned_lps: null, error_mm: null });
  }
  return markers;
}

// Each measured target's row, by target id.
export function measuredByTarget(verification: VerificationState | undefined): Map<number, MeasuredTargetState> {
  return new Map((verification?.targets ?? []).map((row) => [row.target_id, row]));
}

// "2.41 ± 1.00 mm" (sample SD; one value has none), "–" without values.
export function meanSd(stats: ErrorStats | undefined, signed = false): string {
  if (!stats || stats.count === 0) return "–";
  const mean = fixed(stats.mean_mm, 2, signed);
  return stats.count > 1 ? `${mean} ± ${fixed(stats.sd_mm, 2)} mm` : `${mean} mm`;
}

// "max 4.63 · min 1.18 · RMS 2.60 mm (n = 21)".
export function extremes(stats: ErrorStats | undefined, signed = false): string {
  if (!stats || stats.count === 0) return "–";
  return (
    `max ${fixed(stats.max_mm, 2, signed)} · min ${fixed(stats.min_mm, 2, signed)} · ` +
    `RMS ${fixed(stats.rms_mm, 2)} mm (n = ${stats.count})`
  );
}

// "0.49 ± 0.12" (a parameter and its standard error).
export function withSe(value: number, se: number, digits = 3): string {
  return `${fixed(value, digits)} ± ${fixed(se, digits)}`;
}

// Rounded for people: what rounds to zero is 0.00, not -0.00; `signed` writes a + too.
export function fixed(x: number, digits: number, signed = false): string {
  const text = x.toFixed(digits);
  const zero = Number(text) === 0;
  if (zero) return (0).toFixed(digits);
  return signed && x > 0 ? `+${text}` : text;
}

// What the registration of the confirmation CT was.
export function registrationText(v: VerificationState): string {
  // A scan given with its registration compared no markers: the shift is NaN (null in JSON).
  if (v.marker_shift_mm === null || Number.isNaN(v.marker_shift_mm)) {
    return "the one given with the scan (markers not compared)";
  }
  return v.registration_reused
    ? `the session's (markers moved ${fixed(v.marker_shift_mm, 2)} mm)`
    : `its own markers (FRE ${fixed(v.fre_mm, 2)} mm, markers moved ${fixed(v.marker_shift_mm, 2)} mm)`;
}
