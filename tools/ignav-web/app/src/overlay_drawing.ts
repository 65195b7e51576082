// What the slice views draw over the server's slice (views.ts): markers, planned paths that are
// solid where they cross the plane, the seeds found on a confirmation CT. Pure drawing on a
// canvas context, in PNG pixels.
import { type SliceFrame, add, norm, project, scale, sub } from "./geometry";
import type { Vec3 } from "./state";
import type { SeedMarker } from "./verification";

const kMarkerRadiusPx = 7;
export const kSeedColour = "#ff1744"; // a matched seed: red, as in the targeting figure
export const kExtraSeedColour = "#ff9100"; // a seed matched to no target

export interface DrawnSeed {
  seed_id: number;
  target_id: number;
  u: number;
  v: number;
  on_plane: boolean;
}

// A labelled marker: full size and opaque on the plane, smaller and faint off it.
export function drawMarker(
  ctx: CanvasRenderingContext2D,
  [u, v]: readonly [number, number],
  onPlane: boolean,
  colour: string,
  label: string,
  shape: "disc" | "ring" | "square" | "cross",
): void {
  const r = onPlane ? kMarkerRadiusPx : kMarkerRadiusPx - 3;
  ctx.globalAlpha = onPlane ? 1 : 0.35;
  ctx.setLineDash([]);
  ctx.lineWidth = 2;
  ctx.strokeStyle = colour;
  ctx.fillStyle = colour;
  ctx.beginPath();
  switch (shape) {
    case "disc":
      ctx.arc(u, v, r, 0, 2 * Math.PI);
      ctx.fill();
      ctx.strokeStyle = "#000";
      ctx.lineWidth = 1;
      ctx.stroke();
      break;
    case "ring":
      ctx.setLineDash([3, 2]);
      ctx.arc(u, v, r, 0, 2 * Math.PI);
      ctx.stroke();
      break;
    case "square":
      ctx.rect(u - r, v - r, 2 * r, 2 * r);
      ctx.stroke();
      break;
    case "cross":
      ctx.moveTo(u - r, v - r);
      ctx.lineTo(u + r, v + r);
      ctx.moveTo(u - r, v + r);
      ctx.lineTo(u + r, v - r);
      ctx.stroke();
      break;
  }
  ctx.setLineDash([]);
  ctx.font = "bold 13px sans-serif";
  ctx.textAlign = "left";
  ctx.fillStyle = colour;
  ctx.strokeStyle = "#000";
  ctx.lineWidth = 3;
  ctx.strokeText(label, u + r + 3, v - r);
  ctx.fillText(label, u + r + 3, v - r);
  ctx.globalAlpha = 1;
}

// A polyline, solid where it runs within the tolerance of the plane and dashed and faint
// elsewhere, in pieces of about one tolerance so that a crossing shows where it crosses.
export function drawPath(
  ctx: CanvasRenderingContext2D,
  frame: SliceFrame,
  path: Vec3[],
  colour: string,
  tolerance: number,
): void {
  ctx.strokeStyle = colour;
  ctx.lineWidth = 2;
  for (let i = 1; i < path.length; ++i) {
    const a = path[i - 1]!;
    const b = path[i]!;
    const step = sub(b, a);
    const pieces = Math.max(1, Math.ceil(norm(step) / tolerance));
    for (let k = 0; k < pieces; ++k) {
      const p = add(a, scale(step, k / pieces));
      const q = add(a, scale(step, (k + 1) / pieces));
      const mid = add(p, scale(sub(q, p), 0.5));
      const onPlane = Math.abs(project(frame, mid).distance_mm) <= tolerance;
      ctx.globalAlpha = onPlane ? 1 : 0.35;
      ctx.setLineDash(onPlane ? [] : [4, 4]);
      const pp = project(frame, p);
      const qq = project(frame, q);
      ctx.beginPath();
      ctx.moveTo(pp.u, pp.v);
      ctx.lineTo(qq.u, qq.v);
      ctx.stroke();
    }
  }
  ctx.globalAlpha = 1;
  ctx.setLineDash([]);
}

// The seeds last: what was measured lies over what was planned. A thin line from each target to
// its seed (solid when both are on the plane), and the seed's cross. Returns where each seed was
// drawn (PNG pixels), which the canvas tells tests and tools.
export function drawSeeds(
  ctx: CanvasRenderingContext2D,
  seeds: SeedMarker[],
  at: (p: Vec3) => readonly [number, number],
  near: (p: Vec3) => boolean,
): DrawnSeed[] {
  const drawn: DrawnSeed[] = [];
  for (const seed of seeds) {
    const colour = seed.target_id ? kSeedColour : kExtraSeedColour;
    const [u, v] = at(seed.lps);
    const onPlane = near(seed.lps);
    if (seed.planned_lps) {
      const [pu, pv] = at(seed.planned_lps);
      ctx.strokeStyle = colour;
      ctx.lineWidth = 1;
      ctx.globalAlpha = onPlane && near(seed.planned_lps) ? 0.9 : 0.35;
      ctx.setLineDash(onPlane ? [] : [3, 3]);
      ctx.beginPath();
      ctx.moveTo(pu, pv);
      ctx.lineTo(u, v);
      ctx.stroke();
      ctx.globalAlpha = 1;
      ctx.setLineDash([]);
    }
    drawMarker(ctx, [u, v], onPlane, colour, seed.target_id ? "" : `S${seed.seed_id}?`, "cross");
    drawn.push({ seed_id: seed.seed_id, target_id: seed.target_id, u, v, on_plane: onPlane });
  }
  return drawn;
}
