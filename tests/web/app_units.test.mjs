// The web viewer's pure helpers (tools/ignav-web/app/src/geometry.ts and status.ts), bundled
// on the fly with the app's own esbuild and checked against closed-form cases.
//   node --test tests/web/app_units.test.mjs
import assert from "node:assert/strict";
import { createRequire } from "node:module";
import path from "node:path";
import { test } from "node:test";
import { fileURLToPath } from "node:url";

const appDir = path.join(path.dirname(fileURLToPath(import.meta.url)), "../../tools/ignav-web/app");
const esbuild = createRequire(path.join(appDir, "package.json"))("esbuild");

async function load(file) {
  const { outputFiles } = await esbuild.build({
    entryPoints: [path.join(appDir, "src", file)],
    bundle: true,
    format: "esm",
    write: false,
  });
  return import(`data:text/javascript;base64,${Buffer.from(outputFiles[0].text).toString("base64")}`);
}
const g = await load("geometry.ts");
const s = await load("status.ts");

const near = (actual, expected, tolerance = 1e-9) =>
  assert.ok(
    actual.every((x, i) => Math.abs(x - expected[i]) <= tolerance),
    `${JSON.stringify(actual)} is not ${JSON.stringify(expected)}`,
  );

test("invert: a scaled, rotated, translated matrix times its inverse is the identity", () => {
  const c = Math.cos(0.3);
  const sn = Math.sin(0.3);
  const m = [2 * c, -2 * sn, 0, 5, 2 * sn, 2 * c, 0, -7, 0, 0, 3, 11, 0, 0, 0, 1];
  const inv = g.invert(m);
  const product = [];
  for (let r = 0; r < 4; ++r)
    for (let k = 0; k < 4; ++k) product.push([0, 1, 2, 3].reduce((sum, j) => sum + m[4 * r + j] * inv[4 * j + k], 0));
  near(product, [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], 1e-12);
  assert.throws(() => g.invert([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1]), /singular/);
});

test("an axial slice: pixel (100, 50) is 0.5 mm pixels from the corner, the normal is u x v", () => {
  // u along +L (x), v along +P (y), the plane at z = 30 mm; the third column is the server's 0.
  const frame = g.sliceFrame([0.5, 0, 0, -10, 0, 0.5, 0, 20, 0, 0, 0, 30, 0, 0, 0, 1]);
  near(frame.normal, [0, 0, 1]);
  near(g.pixelToLps(frame, 100, 50), [40, 45, 30]);
  const q = g.project(frame, [40, 45, 32]);
  near([q.u, q.v, q.distance_mm], [100, 50, 2]);
});

test("a sagittal slice: v runs down (towards I), the distance is along -L", () => {
  // u along -P (anterior, y decreasing), v along -S (z decreasing): normal = (0,-1,0) x (0,0,-1).
  const frame = g.sliceFrame([0, 0, 0, 12, -0.8, 0, 0, 100, 0, -0.8, 0, 60, 0, 0, 0, 1]);
  near(frame.normal, [1, 0, 0]);
  const q = g.project(frame, [9, 100 - 0.8 * 10, 60 - 0.8 * 20]);
  near([q.u, q.v, q.distance_mm], [10, 20, -3]);
});

test("a 512 px canvas shown 400 CSS px wide: its middle is pixel 255.5 (between the two middle pixels)", () => {
  const scale = { css_width: 400, css_height: 400, width_px: 512, height_px: 512 };
  near(g.pixelFromCss(scale, 200, 200), [255.5, 255.5]);
  near(g.pixelFromCss(scale, 0, 0), [-0.5, -0.5]); // the corner of pixel 0
  near(g.cssFromPixel(scale, 17.25, 301), [(17.75 * 400) / 512, (301.5 * 400) / 512]);
  near(g.pixelFromCss(scale, ...g.cssFromPixel(scale, 17.25, 301)), [17.25, 301]);
});

test("spacingAlong: the spacing of the volume axis nearest the direction", () => {
  const ijkToLps = [0.8, 0, 0, -50, 0, 0.8, 0, -50, 0, 0, 1.25, -69, 0, 0, 0, 1];
  const spacing = [0.8, 0.8, 1.25];
  assert.equal(g.spacingAlong([0, 0, -1], ijkToLps, spacing), 1.25);
  assert.equal(g.spacingAlong([0.1, 0.99, 0.05], ijkToLps, spacing), 0.8);
});

test("the volume's centre and the pixel size that shows it whole", () => {
  const ijkToLps = [0.8, 0, 0, -50.8, 0, 0.8, 0, -50.8, 0, 0, 1.25, -69.375, 0, 0, 0, 1];
  near(g.volumeCentre(ijkToLps, [128, 128, 112]), [0, 0, 0]);
  assert.equal(g.fittingPixelMm([128, 128, 112], [0.8, 0.8, 1.25], 512), 140 / 512);
});

test("parseLps: three finite numbers separated by commas", () => {
  near(g.parseLps(" 1.5, -2 ,3e1"), [1.5, -2, 30]);
  for (const bad of ["", "1,2", "1,2,3,4", "1,,3", "a,b,c", "1,2,Infinity"]) assert.equal(g.parseLps(bad), null, bad);
});

test("target colours follow the workflow, the approval and the motion", () => {
  const target = (over = {}) => ({
    id: 3, lps: [0, 0, 0], robot: [0, 0, 0], registered: true, reachable: true, reach: "reachable",
    message: "", joints: [0, 0, 0], steps: [0, 0, 0], tre_mm: 0, tre_warning: false, order: 1,
    predicted_deviation_mm: null, status: "planned", ...over,
  });
  const pending = (target_id) => ({ status: "pending", target_id });
  const moving = (target_id) => ({ state: "moving", target_id });
  const cases = [
    [target({ registered: false, reachable: false, status: "unregistered" }), "planning", undefined, undefined, "unregistered"],
    [target({ reachable: false, status: "unreachable", reach: "beyond_max_radius" }), "planning", undefined, undefined, "unreachable"],
    [target(), "planning", undefined, undefined, "reachable"],
    [target(), "registration", undefined, undefined, "reachable"],
    [target(), "plan_locked", undefined, undefined, "planned"],
    [target(), "stopped", undefined, undefined, "planned"],
    [target(), "plan_locked", pending(3), undefined, "awaiting_approval"],
    [target(), "plan_locked", pending(4), undefined, "planned"],
    [target(), "moving", undefined, moving(3), "moving"],
    [target(), "moving", undefined, moving(4), "planned"],
    [target({ status: "reached" }), "at_target", pending(4), { state: "idle", target_id: 3 }, "reached"],
  ];
  for (const [t, phase, approval, motion, expected] of cases) {
    const shown = s.targetDisplay(t, phase, approval, motion);
    assert.equal(shown.status, expected, `${t.status} in ${phase}`);
    assert.equal(shown.colour, s.kStatusColour[expected]);
  }
  const why = s.targetDisplay(
    target({ reachable: false, status: "unreachable", reach: "beyond_max_radius", message: "3.2 mm beyond the maximum radius 26.5 mm" }),
    "planning", undefined, undefined,
  ).detail;
  assert.equal(why, "beyond_max_radius: 3.2 mm beyond the maximum radius 26.5 mm");
});

test("formatLps: rounded for people, and what rounds to zero is 0, not -0", () => {
  assert.equal(g.formatLps([-0.001, 1.25, -3.456], 2), "0.00, 1.25, -3.46");
  assert.equal(g.formatLps([-0.04, 0.05, 12]), "0.0, 0.1, 12.0");
});
