// The little linear algebra the viewer needs: row-major 4x4 matrices, the map between a slice's
// PNG pixels and LPS millimetres, and the CSS scaling of a canvas. Pure functions, no DOM.
import type { Vec3, VolumeState } from "./state";

export type Mat4 = readonly number[]; // 16 numbers, row-major

export const add = (a: Vec3, b: Vec3): Vec3 => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
export const sub = (a: Vec3, b: Vec3): Vec3 => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const scale = (a: Vec3, s: number): Vec3 => [a[0] * s, a[1] * s, a[2] * s];
export const dot = (a: Vec3, b: Vec3): number => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const norm = (a: Vec3): number => Math.hypot(a[0], a[1], a[2]);
export const cross = (a: Vec3, b: Vec3): Vec3 => [
  a[1] * b[2] - a[2] * b[1],
  a[2] * b[0] - a[0] * b[2],
  a[0] * b[1] - a[1] * b[0],
];

export function unit(a: Vec3): Vec3 {
  const n = norm(a);
  if (n === 0) throw new Error("a zero vector has no direction");
  return scale(a, 1 / n);
}

// M · (x, y, z, 1), dropping the homogeneous coordinate (the matrices here are affine).
export function transformPoint(m: Mat4, p: Vec3): Vec3 {
  const row = (r: number) => m[4 * r] * p[0] + m[4 * r + 1] * p[1] + m[4 * r + 2] * p[2] + m[4 * r + 3];
  return [row(0), row(1), row(2)];
}

export function column(m: Mat4, j: number): Vec3 {
  return [m[j], m[4 + j], m[8 + j]];
}

// The inverse by Gauss-Jordan elimination with partial pivoting; throws for a singular matrix.
export function invert(m: Mat4): number[] {
  const a = [...m];
  const inv = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
  const swapRows = (x: number[], r1: number, r2: number) => {
    for (let c = 0; c < 4; ++c) [x[4 * r1 + c], x[4 * r2 + c]] = [x[4 * r2 + c], x[4 * r1 + c]];
  };
  for (let c = 0; c < 4; ++c) {
    let pivot = c;
    for (let r = c + 1; r < 4; ++r) if (Math.abs(a[4 * r + c]) > Math.abs(a[4 * pivot + c])) pivot = r;
    if (!(Math.abs(a[4 * pivot + c]) > 1e-12)) throw new Error("the matrix is singular");
    swapRows(a, c, pivot);
    swapRows(inv, c, pivot);
    const p = a[4 * c + c];
    for (let k = 0; k < 4; ++k) {
      a[4 * c + k] /= p;
      inv[4 * c + k] /= p;
    }
    for (let r = 0; r < 4; ++r) {
      if (r === c) continue;
      const f = a[4 * r + c];
      for (let k = 0; k < 4; ++k) {
        a[4 * r + k] -= f * a[4 * c + k];
        inv[4 * r + k] -= f * inv[4 * c + k];
      }
    }
  }
  return inv;
}

// A slice's frame. The server's pixel_to_lps maps (u, v, 0, 1) to LPS, so its third column says
// nothing; the frame puts the plane's unit normal there, which makes the third coordinate of the
// inverse the signed distance from the plane in mm.
export interface SliceFrame {
  readonly pixelToLps: Mat4;
  readonly normal: Vec3; // unit, u × v
  readonly lpsToFrame: Mat4; // LPS -> (u, v, distance_mm)
}

export function sliceFrame(pixelToLps: Mat4): SliceFrame {
  if (pixelToLps.length !== 16) throw new Error("pixel_to_lps must hold 16 numbers");
  const normal = unit(cross(column(pixelToLps, 0), column(pixelToLps, 1)));
  const full = [...pixelToLps];
  for (let r = 0; r < 3; ++r) full[4 * r + 2] = normal[r];
  return { pixelToLps, normal, lpsToFrame: invert(full) };
}

export function pixelToLps(frame: SliceFrame, u: number, v: number): Vec3 {
  return transformPoint(frame.pixelToLps, [u, v, 0]);
}

export interface Projection {
  u: number; // PNG pixels, right
  v: number; // PNG pixels, down
  distance_mm: number; // signed, along the normal
}

export function project(frame: SliceFrame, lps: Vec3): Projection {
  const [u, v, distance_mm] = transformPoint(frame.lpsToFrame, lps);
  return { u, v, distance_mm };
}

// A canvas shows the PNG at its own resolution (pixel u covers [u, u + 1), its centre at u + 0.5)
// and CSS may scale it. These map a position in CSS pixels from the canvas' top left corner to
// PNG pixels and back.
export interface CanvasScale {
  css_width: number;
  css_height: number;
  width_px: number;
  height_px: number;
}

export function pixelFromCss(s: CanvasScale, x_css: number, y_css: number): [number, number] {
  return [(x_css * s.width_px) / s.css_width - 0.5, (y_css * s.height_px) / s.css_height - 0.5];
}

export function cssFromPixel(s: CanvasScale, u: number, v: number): [number, number] {
  return [((u + 0.5) * s.css_width) / s.width_px, ((v + 0.5) * s.css_height) / s.height_px];
}

// The voxel spacing along a direction: that of the volume axis most nearly parallel to it.
export function spacingAlong(direction: Vec3, ijkToLps: Mat4, spacing_mm: Vec3): number {
  let best = 0;
  let bestCos = -1;
  for (let axis = 0; axis < 3; ++axis) {
    const cos = Math.abs(dot(unit(column(ijkToLps, axis)), unit(direction)));
    if (cos > bestCos) {
      bestCos = cos;
      best = axis;
    }
  }
  return spacing_mm[best];
}

// Which volume is loaded ("" none): what the views' pictures of it were made for.
export function loadedVolumeKey(volume: VolumeState | undefined): string {
  return volume?.status === "loaded" ? JSON.stringify([volume.source, volume.dims, volume.ijk_to_lps]) : "";
}

// The LPS point at the middle of the volume (voxel centres at integer indices).
export function volumeCentre(ijkToLps: Mat4, dims: Vec3): Vec3 {
  return transformPoint(ijkToLps, [(dims[0] - 1) / 2, (dims[1] - 1) / 2, (dims[2] - 1) / 2]);
}

// Where a view centres its slice: its own pan centre (`pan`, where it was last centred) moved
// along its unit `normal` into the plane through the shared centre. Scrolling another view moves
// the shared centre along that view's normal, perpendicular to this one's: its slice stays put.
export function viewCentre(pan: Vec3, shared: Vec3, normal: Vec3): Vec3 {
  return add(pan, scale(normal, dot(sub(shared, pan), normal)));
}

// The eight corners of the volume's voxel centres (LPS).
export function volumeCorners(ijkToLps: Mat4, dims: Vec3): Vec3[] {
  const corners: Vec3[] = [];
  for (const i of [0, dims[0] - 1])
    for (const j of [0, dims[1] - 1]) for (const k of [0, dims[2] - 1]) corners.push(transformPoint(ijkToLps, [i, j, k]));
  return corners;
}

// The axis-aligned LPS box of the volume's voxel centres: [lowest, highest].
export function volumeBox(ijkToLps: Mat4, dims: Vec3): [Vec3, Vec3] {
  const corners = volumeCorners(ijkToLps, dims);
  const along = (a: number) => corners.map((p) => p[a]);
  return [
    [0, 1, 2].map((a) => Math.min(...along(a))) as Vec3,
    [0, 1, 2].map((a) => Math.max(...along(a))) as Vec3,
  ];
}

// `point` moved along the unit `normal` as little as needed to lie between the volume's first
// and last voxel centres along it: scrolling stops at the volume's edge.
export function clampAlong(point: Vec3, normal: Vec3, ijkToLps: Mat4, dims: Vec3): Vec3 {
  const along = volumeCorners(ijkToLps, dims).map((p) => dot(p, normal));
  const t = dot(point, normal);
  return add(point, scale(normal, Math.min(Math.max(...along), Math.max(Math.min(...along), t)) - t));
}

// The pixel size at which a square image of size_px shows the volume's largest extent whole.
export function fittingPixelMm(dims: Vec3, spacing_mm: Vec3, size_px: number): number {
  return Math.max(dims[0] * spacing_mm[0], dims[1] * spacing_mm[1], dims[2] * spacing_mm[2]) / size_px;
}

// "x,y,z" (spaces allowed) in mm, or null when it is not three finite numbers.
export function parseLps(text: string): Vec3 | null {
  const parts = text.split(",").map((s) => s.trim());
  if (parts.length !== 3 || parts.some((s) => s === "")) return null;
  const values = parts.map(Number);
  if (!values.every(Number.isFinite)) return null;
  return [values[0], values[1], values[2]];
}

// Rounded for people; what rounds to zero shows as 0, not -0.
export function formatLps(p: Vec3, digits = 1): string {
  return p.map((x) => (Math.abs(x) < 0.5 * 10 ** -digits ? 0 : x).toFixed(digits)).join(", ");
}
