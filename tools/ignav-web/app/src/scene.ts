// The 3D view's pure parts (issue 43): the standard views in LPS, the CT's geometry and transfer
// functions from the slices' window, the scene's numbers out of the gateway's base64. No vtk.js
// here, so that each rule reads in one place and is tested on its own (tests/web/app_units).
import { column, norm } from "./geometry";
import type { Mat4 } from "./geometry";
import type { Vec3 } from "./state";

export type StandardView = "A" | "P" | "L" | "R" | "S" | "I";

// Where the camera looks from (a unit vector from the focal point, LPS) and which way is up, as
// 3D Slicer's view buttons: the patient seen from the front has the left on the screen's right;
// from above or below, anterior is up (below: the radiological axial picture).
export const kStandardViews: Record<StandardView, { from: Vec3; up: Vec3; name: string }> = {
  A: { from: [0, -1, 0], up: [0, 0, 1], name: "anterior" },
  P: { from: [0, 1, 0], up: [0, 0, 1], name: "posterior" },
  L: { from: [1, 0, 0], up: [0, 0, 1], name: "left" },
  R: { from: [-1, 0, 0], up: [0, 0, 1], name: "right" },
  S: { from: [0, 0, 1], up: [0, -1, 0], name: "superior" },
  I: { from: [0, 0, -1], up: [0, -1, 0], name: "inferior" },
};

// vtk.js's image geometry from a row-major ijk -> LPS matrix: the spacing is each index axis's
// length, the direction its unit vectors (vtk.js keeps them column after column).
export interface ImageGeometry {
  origin: Vec3;
  spacing: Vec3;
  direction: number[]; // 9: the i axis, then j, then k
}

export function imageGeometry(ijkToLps: Mat4): ImageGeometry {
  const axes = [0, 1, 2].map((j) => column(ijkToLps, j));
  const spacing = axes.map((axis) => norm(axis)) as Vec3;
  const direction = axes.flatMap((axis, j) => axis.map((c) => c / (spacing[j] || 1)));
  return { origin: column(ijkToLps, 3), spacing, direction };
}

// The CT's colour and opacity by stored value, from the window the slices use (HU): grey from
// black at the window's bottom to white at its top; transparent up to the level, then more opaque
// towards the top, so a bone window shows bone and a soft-tissue window the organs.
export interface TransferPoints {
  colour: Array<[number, number]>; // stored value, grey 0-1
  opacity: Array<[number, number]>; // stored value, opacity 0-1
}

export const kMaxOpacity = 0.8;

export function windowTransfer(window: number, level: number, valueScale: number, valueOffset: number): TransferPoints {
  const width = window > 0 ? window : 2000;
  const stored = (hu: number) => (hu - valueOffset) / (valueScale || 1);
  const lo = stored(level - width / 2);
  const mid = stored(level);
  const hi = stored(level + width / 2);
  return {
    colour: [
      [lo, 0],
      [hi, 1],
    ],
    opacity: [
      [Math.min(lo, mid), 0],
      [mid, 0],
      [hi, kMaxOpacity],
    ],
  };
}

// Standard base64 to bytes: the browser's own decoder where it has one (Uint8Array.fromBase64,
// Chromium 140 on), else atob. (A data: URL through fetch took 5.7 s for a 256-cube CT's 43 MB.)
export async function decodeBase64(text: string): Promise<ArrayBuffer> {
  const native = (Uint8Array as unknown as { fromBase64?: (text: string) => Uint8Array }).fromBase64;
  if (native) return native(text).buffer as ArrayBuffer;
  const binary = atob(text);
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; ++i) bytes[i] = binary.charCodeAt(i);
  return bytes.buffer;
}

// The buffers travel little-endian; so is every machine a browser runs on, but say so.
export function littleEndian(): boolean {
  return new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;
}

// Whether the slabs received so far make the whole volume: each slab's first slice is where the
// last ended, and together they reach the last slice.
export function slabsComplete(dims: Vec3, slabs: Array<{ first_slice: number; slice_count: number }>): boolean {
  let next = 0;
  for (const slab of slabs) {
    if (slab.first_slice !== next || slab.slice_count <= 0) return false;
    next += slab.slice_count;
  }
  return next === dims[2];
}

// A polyline as vtk.js's cell array: [n, 0, 1, ..., n-1].
export function polylineCells(count: number): Uint32Array {
  const cells = new Uint32Array(count + 1);
  cells[0] = count;
  for (let i = 0; i < count; ++i) cells[i + 1] = i;
  return cells;
}

// Triangles (three indices each) as vtk.js's cell array: [3, a, b, c, 3, ...].
export function triangleCells(triangles: Uint32Array): Uint32Array {
  const count = Math.floor(triangles.length / 3);
  const cells = new Uint32Array(4 * count);
  for (let t = 0; t < count; ++t) {
    cells[4 * t] = 3;
    cells[4 * t + 1] = triangles[3 * t] ?? 0;
    cells[4 * t + 2] = triangles[3 * t + 1] ?? 0;
    cells[4 * t + 3] = triangles[3 * t + 2] ?? 0;
  }
  return cells;
}

// Triangle strips as triangles (vtk.js's cell arrays: [n, v0 .. vn-1] each, [3, a, b, c] each),
// every other one turned so that all keep the strip's winding: vtk.js's cell picker reads
// triangles and polygons, not strips, and a tube filter makes strips.
export function stripsToTriangles(strips: Uint32Array): Uint32Array {
  const out: number[] = [];
  for (let at = 0; at < strips.length; ) {
    const n = strips[at] ?? 0;
    for (let i = 0; i + 2 < n; ++i) {
      const [a, b, c] = [strips[at + 1 + i] ?? 0, strips[at + 2 + i] ?? 0, strips[at + 3 + i] ?? 0];
      out.push(3, ...(i % 2 === 0 ? [a, b, c] : [b, a, c]));
    }
    at += n + 1;
  }
  return Uint32Array.from(out);
}

// How opaque a structure's surface is drawn: the target see-through (its seeds and paths inside
// stay visible), organs to avoid nearly solid, the rest between; a selected one more solid.
export function structureOpacity(role: string, selected: boolean): number {
  const base = role === "target" ? 0.35 : role === "avoid" ? 0.85 : 0.5;
  return selected ? Math.min(1, base + 0.35) : base;
}
