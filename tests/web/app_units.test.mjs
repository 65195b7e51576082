// The web viewer's pure helpers (tools/ignav-web/app/src/geometry.ts, status.ts, clock.ts,
// approval.ts, alerts.ts, verification.ts, structures.ts and the 3D view's scene.ts), bundled on the fly with the app's own esbuild and checked against
// closed-form cases.
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
const clock = await load("clock.ts");
const ap = await load("approval.ts");
const alerts = await load("alerts.ts");
const ver = await load("verification.ts");
const st = await load("structures.ts");
const sc = await load("scene.ts");

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

test("viewCentre: a view keeps its own pan and follows the shared centre only along its normal", () => {
  const pan = [10, 20, 30];
  const shared = [1, 2, 3];
  near(g.viewCentre(pan, shared, [0, 0, 1]), [10, 20, 3]); // axial: only z follows
  near(g.viewCentre(pan, shared, [-1, 0, 0]), [1, 20, 30]); // sagittal: only x
  near(g.viewCentre(pan, shared, [0, 1, 0]), [10, 2, 30]); // coronal: only y
  // An oblique normal (1, 1, 0)/√2: the offset (2, 0, 5) has √2 along it, i.e. (1, 1, 0).
  near(g.viewCentre([0, 0, 0], [2, 0, 5], [Math.SQRT1_2, Math.SQRT1_2, 0]), [1, 1, 0], 1e-12);
  // Scrolling the sagittal view (the shared centre moves along x) moves no other view's plane.
  const moved = [shared[0] + 0.8, shared[1], shared[2]];
  near(g.viewCentre(pan, moved, [0, 0, 1]), g.viewCentre(pan, shared, [0, 0, 1]));
  near(g.viewCentre(pan, moved, [0, 1, 0]), g.viewCentre(pan, shared, [0, 1, 0]));
  // Centred on one point, every view asks for exactly that point.
  assert.deepEqual(g.viewCentre([1.1, -2.3, 7.7], [1.1, -2.3, 7.7], [-1, 0, 0]), [1.1, -2.3, 7.7]);
});

test("clampAlong: scrolling stops at the first and last voxel centres along the normal", () => {
  // 128 x 128 x 112 voxels of 0.8 x 0.8 x 1.25 mm, centred on the origin: the voxel centres span
  // x, y in [-50.8, 50.8] and z in [-69.375, 69.375].
  const ijkToLps = [0.8, 0, 0, -50.8, 0, 0.8, 0, -50.8, 0, 0, 1.25, -69.375, 0, 0, 0, 1];
  const dims = [128, 128, 112];
  near(g.clampAlong([3, 4, 100], [0, 0, 1], ijkToLps, dims), [3, 4, 69.375]);
  near(g.clampAlong([3, 4, -100], [0, 0, 1], ijkToLps, dims), [3, 4, -69.375]);
  near(g.clampAlong([60, 4, 5], [-1, 0, 0], ijkToLps, dims), [50.8, 4, 5]);
  near(g.clampAlong([3, -51, 5], [0, 1, 0], ijkToLps, dims), [3, -50.8, 5]);
  // Inside, nothing moves (and nothing is rounded).
  assert.deepEqual(g.clampAlong([1.3, -2.7, 9.1], [0, 0, 1], ijkToLps, dims), [1.3, -2.7, 9.1]);
  // Only the component along the normal is clamped: a point beyond the edge in x stays so when
  // scrolled along z.
  near(g.clampAlong([200, 4, 70], [0, 0, 1], ijkToLps, dims), [200, 4, 69.375]);
  // A volume turned 90° about S: i runs along +P (1 mm), j along -L (2 mm), k along +S (3 mm).
  const turned = [0, -2, 0, 0, 1, 0, 0, 0, 0, 0, 3, 0, 0, 0, 0, 1];
  near(g.clampAlong([5, 20, 1], [1, 0, 0], turned, [10, 5, 4]), [0, 20, 1]); // x = -2j in [-8, 0]
  near(g.clampAlong([5, 20, 1], [0, 1, 0], turned, [10, 5, 4]), [5, 9, 1]); // y = i in [0, 9]
  near(g.clampAlong([-9, 20, 1], [-1, 0, 0], turned, [10, 5, 4]), [-8, 20, 1]);
});

test("ServerClock: the largest lower bound on the offset, from the least delayed sample", () => {
  // The server's clock runs exactly 1000 s ahead of the page's; samples arrive 0.3 s, 0.05 s and
  // 0.6 s after they were written.
  const c = new clock.ServerClock();
  assert.equal(c.now_s(5), null);
  c.observe(1009.7, 10); // written at server 1009.7 = local 9.7
  assert.ok(Math.abs(c.now_s(10) - 1009.7) < 1e-9);
  c.observe(1010.95, 11);
  c.observe(1011.4, 12);
  assert.ok(Math.abs(c.now_s(12) - 1011.95) < 1e-9, String(c.now_s(12))); // 0.05 s behind, never ahead
  // Junk (a server that does not say, a NaN) changes nothing.
  c.observe(0, 12.5);
  c.observe(Number.NaN, 12.5);
  assert.ok(Math.abs(c.now_s(12) - 1011.95) < 1e-9);
});

test("ServerClock: a late page counts from the server's clock, not from when the request arrived", () => {
  // A request published 15 s before this page joined (expires_at 1120 s, 120 s after it was
  // published at server time 1000); the page receives it at local 2 with the health sample of
  // server time 1014.6 (written 0.4 s before). The server runs 1013 s ahead of the page.
  const published_s = clock.approvalPublishedAt_s(1120, 120);
  assert.equal(published_s, 1000);
  const c = new clock.ServerClock();
  c.observe(published_s, 2);
  // From the request alone the page would think 118 s are left at local 4 (the bug of issue 26);
  assert.equal(1120 - c.now_s(4), 118);
  // with the health sample it knows 103.4 s are (true: 1120 - 1017 = 103; the 0.4 s of delay).
  c.observe(1014.6, 2);
  assert.ok(Math.abs(1120 - c.now_s(4) - 103.4) < 1e-9);
  assert.ok(Number.isNaN(clock.approvalPublishedAt_s(0, 120))); // a server that does not say
});

test("ServerClock: the estimate follows the clocks' drift after the window", () => {
  const c = new clock.ServerClock(30);
  c.observe(105, 0); // offset 105 exactly
  c.observe(135.9, 31); // the server's clock has since lost 0.1 s: offset 104.9
  assert.ok(Math.abs(c.now_s(31) - 135.9) < 1e-9); // the first sample is out of the window
  const d = new clock.ServerClock(30);
  d.observe(105, 0);
  d.observe(114.9, 10); // within the window the larger bound stands
  assert.ok(Math.abs(d.now_s(10) - 115) < 1e-9);
  // With nothing newer, the last sample stays however old.
  assert.ok(Math.abs(d.now_s(1000) - 1105) < 1e-9);
});

test("approvalView: the countdown, expiry and the approve button", () => {
  const base = { expires_at_unix_s: 1000, server_now_s: 894.8, connected: true, may_approve: true, in_flight: false };
  let v = ap.approvalView(base);
  assert.equal(v.expiry_text, "expires in 106 s"); // 105.2 s left, rounded up
  assert.deepEqual([v.expired, v.urgent, v.approve_hidden, v.approve_disabled], [false, false, false, false]);
  v = ap.approvalView({ ...base, server_now_s: 991 });
  assert.deepEqual([v.expiry_text, v.urgent, v.approve_disabled], ["expires in 9 s", true, false]);
  for (const now of [1000, 1000.5, 1200]) {
    v = ap.approvalView({ ...base, server_now_s: now });
    assert.equal(v.expiry_text, "expired: request approval again", String(now));
    assert.deepEqual([v.expired, v.approve_hidden, v.approve_disabled], [true, true, true]);
  }
  v = ap.approvalView({ ...base, in_flight: true });
  assert.deepEqual([v.approve_hidden, v.approve_disabled, v.approve_label], [false, true, "Approving…"]);
  v = ap.approvalView({ ...base, connected: false });
  assert.deepEqual([v.approve_hidden, v.approve_disabled, v.urgent], [false, true, true]);
  assert.match(v.expiry_text, /not reachable/);
  v = ap.approvalView({ ...base, may_approve: false });
  assert.equal(v.approve_hidden, true);
  v = ap.approvalView({ ...base, server_now_s: null });
  assert.deepEqual([v.expired, v.approve_disabled], [false, true]);
});

test("connectionView and phaseBanner: a banner whenever the page cannot reach the server", () => {
  const up = alerts.connectionView({ open: true }, true);
  assert.deepEqual([up.connected, up.banner, up.header], [true, null, "gateway: connected · server: connected"]);
  for (const [status, server, says] of [
    [{ open: false, retry_in_ms: 250 }, null, /cannot reach the ignav-web gateway.*retrying in 0\.3 s/],
    [{ open: false, retry_in_ms: 0 }, null, /gateway: connecting/],
    [{ open: true }, false, /the gateway cannot reach ignav-server/],
    [{ open: true }, null, /waiting for the gateway/],
  ]) {
    const view = alerts.connectionView(status, server);
    assert.equal(view.connected, false);
    assert.match(view.banner, says);
    assert.match(view.banner, /not even its EMERGENCY STOP: use the robot's hardware emergency stop/);
  }
  assert.match(alerts.phaseBanner("emergency", ""), /^EMERGENCY STOP.*Reset emergency/);
  assert.match(alerts.phaseBanner("fault", "motor 2 following error"), /^ROBOT FAULT: motor 2 following error/);
  for (const phase of ["planning", "plan_locked", "moving", "stopped", ""]) assert.equal(alerts.phaseBanner(phase, ""), null);
});

test("targets outside the CT, and paths that leave it", () => {
  const target = (over = {}) => ({
    id: 5, lps: [0, 0, 0], robot: [0, 0, 0], registered: true, reachable: true, reach: "reachable",
    message: "", joints: [0, 0, 0], steps: [0, 0, 0], tre_mm: 0, tre_warning: false, order: 1,
    predicted_deviation_mm: null, status: "planned", outside_volume: false, path_warning: "", ...over,
  });
  // Outside the CT beats every other verdict: it is never imaged, whatever the robot could do.
  for (const over of [
    { status: "outside_volume", outside_volume: true },
    { status: "outside_volume", outside_volume: true, registered: false, reachable: false },
    { status: "unreachable", reachable: false, outside_volume: true },
  ]) {
    const shown = s.targetDisplay(target(over), "planning", undefined, undefined);
    assert.equal(shown.status, "outside_volume", JSON.stringify(over));
    assert.equal(shown.label, "outside the CT");
    assert.equal(shown.colour, s.kStatusColour.outside_volume);
  }
  assert.equal(
    s.targetDisplay(target({ status: "outside_volume", outside_volume: true }), "planning").detail,
    "outside the loaded CT: lock_plan refuses it",
  );
  const named = s.targetDisplay(
    target({ status: "outside_volume", outside_volume: true, reach: "reachable", message: "4.2 mm beyond the CT (S)" }),
    "planning",
  );
  assert.equal(named.detail, "4.2 mm beyond the CT (S)");
  // A reachable target whose path leaves the CT: still reachable, and the warning is said.
  const warning = "the path leaves the CT for 12.5 mm near the entry";
  const warned = s.targetDisplay(target({ path_warning: warning }), "planning");
  assert.deepEqual([warned.status, warned.path_warning], ["reachable", warning]);
  assert.equal(warned.detail, `reachable; ${warning}`);
  // The server's message already ends with it: said once.
  const message = `target 5: reachable; warning: ${warning}`;
  assert.equal(s.targetDisplay(target({ path_warning: warning, message }), "planning").detail, message);
  // Where the needle has been stays reached, outside the CT or not (the server's rule).
  assert.equal(s.targetDisplay(target({ status: "reached", outside_volume: true }), "at_target").status, "reached");
  // Servers before issue 26 send neither field.
  const old = target();
  delete old.outside_volume;
  delete old.path_warning;
  assert.deepEqual([s.targetDisplay(old, "planning").status, s.targetDisplay(old, "planning").path_warning], ["reachable", ""]);
  assert.equal(s.kStatusColour.outside_volume !== s.kStatusColour.unreachable, true);
});

// ---- the closed loop (issue 23) --------------------------------------------------------------

const stats = (count, mean_mm, sd_mm, min_mm, max_mm, rms_mm) => ({ count, mean_mm, sd_mm, min_mm, max_mm, rms_mm });

test("seedMarkers: a seed's robot point through the planning registration's inverse lands on the planning CT", () => {
  // image -> robot: rotate 90° about z, scale 2, translate (5, -7, 11): robot = 2·(-y, x, z) + t.
  const image_to_robot = [0, -2, 0, 5, 2, 0, 0, -7, 0, 0, 2, 11, 0, 0, 0, 1];
  const registration = { status: "registered", image_to_robot };
  // The seed at planning LPS (1, 2, 3) is at robot 2·(-2, 1, 3) + t = (1, -5, 17).
  const row = {
    target_id: 4, seed_id: 9, matched: "detected", planned_robot: [0, 0, 0], actual_robot: [1, -5, 17],
    planned_lps: [50, 50, 50], actual_lps: [99, 99, 99], error_mm: 1.5,
  };
  const verification = {
    status: "measured", targets: [row], extra_seeds: [12, 13],
    seeds: [
      { id: 9, lps: [99, 99, 99], robot: [1, -5, 17], rejected: false, target_id: 4 },
      { id: 12, lps: [0, 0, 0], robot: [5, -7, 11], rejected: false, target_id: 0 }, // planning LPS 0
      { id: 13, lps: [0, 0, 0], robot: [5, -7, 11], rejected: true, target_id: 0 }, // rejected: not drawn
    ],
  };
  const targets = { 4: { id: 4, lps: [1.5, 2, 3] } };
  const markers = ver.seedMarkers(verification, registration, targets);
  assert.equal(markers.length, 2);
  assert.equal(markers[0].seed_id, 9);
  assert.equal(markers[0].target_id, 4);
  near(markers[0].lps, [1, 2, 3], 1e-12);
  near(markers[0].planned_lps, [1.5, 2, 3]); // the target's marker, where the line goes
  assert.equal(markers[1].seed_id, 12);
  assert.equal(markers[1].target_id, 0);
  near(markers[1].lps, [0, 0, 0], 1e-12);
  assert.equal(markers[1].planned_lps, null);
  // Without a registration: the confirmation CT's LPS (the same frame when it was reused); a
  // target gone from the plan: the row's planned LPS.
  const bare = ver.seedMarkers(verification, { status: "none", image_to_robot: [] }, {});
  near(bare[0].lps, [99, 99, 99]);
  near(bare[0].planned_lps, [50, 50, 50]);
  // Nothing measured (none, measuring): nothing drawn.
  assert.deepEqual(ver.seedMarkers({ ...verification, status: "measuring" }, registration, targets), []);
  assert.deepEqual(ver.seedMarkers(undefined, registration, targets), []);
});

test("the summary's numbers: mean ± sample SD, max, min, RMS; one value has no SD; signed depth", () => {
  // Errors 1, 2, 3, 4 mm: mean 2.5, sample SD √(5/3) = 1.29, RMS √7.5 = 2.74.
  const e = stats(4, 2.5, Math.sqrt(5 / 3), 1, 4, Math.sqrt(7.5));
  assert.equal(ver.meanSd(e), "2.50 ± 1.29 mm");
  assert.equal(ver.extremes(e), "max 4.00 · min 1.00 · RMS 2.74 mm (n = 4)");
  assert.equal(ver.meanSd(stats(1, 2.345, 0, 2.345, 2.345, 2.345)), "2.35 mm");
  assert.equal(ver.meanSd(stats(0, 0, 0, 0, 0, 0)), "–");
  assert.equal(ver.meanSd(undefined), "–");
  // Depth is signed: + deeper than planned; what rounds to zero is 0.00.
  assert.equal(ver.meanSd(stats(2, 0.5, 0.1, -0.001, 1, 0.7), true), "+0.50 ± 0.10 mm");
  assert.equal(ver.extremes(stats(2, -0.5, 0.1, -1.2, -0.001, 0.7), true), "max 0.00 · min -1.20 · RMS 0.70 mm (n = 2)");
  assert.equal(ver.withSe(0.49, 0.1234), "0.490 ± 0.123");
  assert.equal(ver.fixed(-0.004, 2), "0.00");
});

test("registrationText: reused, anew, or given with the scan (the shift null in JSON)", () => {
  const v = { registration_reused: true, marker_shift_mm: 0.123, fre_mm: 0.2 };
  assert.equal(ver.registrationText(v), "the session's (markers moved 0.12 mm)");
  assert.equal(ver.registrationText({ ...v, registration_reused: false, marker_shift_mm: 4.5 }),
    "its own markers (FRE 0.20 mm, markers moved 4.50 mm)");
  assert.equal(ver.registrationText({ ...v, registration_reused: false, marker_shift_mm: null }),
    "the one given with the scan (markers not compared)");
});

test("measuredByTarget: each measured target's row by id", () => {
  const rows = ver.measuredByTarget({ targets: [{ target_id: 3, error_mm: 1 }, { target_id: 7, error_mm: 2 }] });
  assert.equal(rows.get(7).error_mm, 2);
  assert.equal(rows.has(4), false);
  assert.equal(ver.measuredByTarget(undefined).size, 0);
});

test("the job line: a started job, then its outcome as the server gave it", () => {
  assert.equal(s.jobStartedText("load_volume", 2), "load_volume: job #2 running…");
  const outcome = { type: "job_outcome", job: 2, kind: "CT load", input: "volume_loaded", revision: 3 };
  assert.equal(s.jobOutcomeText({ ...outcome, status: "done", message: "128 x 128 x 112 voxels" }),
    "CT load #2: done: 128 x 128 x 112 voxels");
  assert.equal(s.jobOutcomeText({ ...outcome, status: "failed", message: "no DICOM files in /x" }),
    "CT load #2: failed: no DICOM files in /x");
  assert.equal(s.jobOutcomeText({ ...outcome, status: "stale", message: "" }), "CT load #2: stale (changed nothing)");
});

test("the reply line: accepted (a new target's id, a started job's message), refused, or failed", () => {
  const reply = { type: "reply", seq: 1, error_code: "", target_id: 0, revision: 4, job: 0, message: "ok" };
  assert.equal(s.replyText("lock_plan", { ...reply, accepted: true }), "lock_plan: accepted");
  assert.equal(s.replyText("add_target", { ...reply, accepted: true, target_id: 3 }), "add_target: accepted (target 3)");
  assert.equal(s.replyText("load_volume", { ...reply, accepted: true, job: 4, message: "loading phantom:" }),
    "load_volume: accepted: loading phantom:");
  assert.equal(s.replyText("add_target", { ...reply, accepted: false, error_code: "wrong_phase", message: "not now" }),
    "add_target: rejected: wrong_phase: not now");
  assert.equal(s.replyText("stop", { type: "error", seq: 2, code: "timeout", message: "no answer" }),
    "stop: failed: timeout: no answer");
});

// ---- structures.ts (issue 41) ----------------------------------------------------------------

const clearance = (structure, distance_mm, margin_mm, uncertainty_mm, extra = {}) => ({
  structure, distance_mm, margin_mm, uncertainty_mm, part: "stylet", needle_lps: [0, 0, 0],
  structure_lps: [0, 0, 0], beyond_reach: false, too_close: distance_mm < margin_mm + uncertainty_mm, ...extra,
});

test("a target's clearance cell: the structure with the least room after margin and uncertainty, not the nearest", () => {
  // The rectum is nearer (4 mm) but leaves 4 - 1 - 0.5 = 2.5 mm; the urethra, at 5 mm, 1.5 mm.
  const target = {
    clearances: [clearance("rectum", 4, 1, 0.5), clearance("urethra", 5, 3, 0.5), clearance("pubic_arch", 9, 2, 0.5)],
    clearance_refusal: "", clearance_override: "",
  };
  const cell = st.clearanceCell(target);
  assert.equal(cell.text, "urethra 5.00 mm");
  assert.equal(cell.too_close, false);
  assert.equal(cell.title.split("\n").length, 3);
  assert.match(cell.title, /^rectum: 4\.00 mm at the stylet, margin 1\.0 mm \+ uncertainty 0\.50 mm$/m);
  assert.equal(st.slack_mm(target.clearances[1]), 1.5);
});

test("a clearance cell: into a structure and refused, then overridden; a lower bound; none at all", () => {
  const refusal = "too_close: the stylet passes 1.20 mm into 'urethra' …";
  const into = { clearances: [clearance("urethra", -1.2, 3, 0.4), clearance("rectum", 20, 5, 0.4)], clearance_refusal: refusal, clearance_override: "" };
  const cell = st.clearanceCell(into);
  assert.equal(cell.text, "urethra 1.20 mm into: too close");
  assert.equal(cell.too_close, true);
  assert.match(cell.title, /urethra: 1\.20 mm into .*: TOO CLOSE/);
  assert.ok(cell.title.endsWith(refusal));
  const overridden = st.clearanceCell({ ...into, clearance_override: "catheter in place" });
  assert.equal(overridden.text, "urethra 1.20 mm into (overridden)");
  assert.equal(overridden.too_close, false);
  assert.equal(overridden.overridden, true);
  assert.match(overridden.title, /overridden \(catheter in place\): too_close/);
  const far = st.clearanceCell({ clearances: [clearance("rectum", 30, 5, 0.4, { beyond_reach: true })] });
  assert.equal(far.text, "rectum > 30.00 mm");
  assert.equal(st.clearanceCell({ clearances: [] }).text, "–");
  assert.equal(st.clearanceCell({}).text, "–"); // a server before issue 41
});

test("a target refused for a structure shows as too close until overridden; reached stays reached", () => {
  // As the server gives it: within reach (`reach`), not plannable (`reachable`, status) while refused.
  const base = { id: 1, status: "unreachable", registered: true, reachable: false, reach: "reachable", message: "m",
    clearance_refusal: "too_close: …", clearance_override: "" };
  assert.equal(s.targetDisplay(base, "planning", undefined, undefined).status, "too_close");
  assert.equal(s.withinReach(base), true);
  const overridden = { ...base, status: "planned", reachable: true, clearance_override: "why" };
  assert.equal(s.targetDisplay(overridden, "planning", undefined, undefined).status, "reachable");
  assert.equal(s.targetDisplay({ ...overridden, status: "reached" }, "at_target", undefined, undefined).status, "reached");
  const beyond = { ...base, reach: "beyond_max_radius" }; // out of reach: that is what it shows
  assert.equal(s.targetDisplay(beyond, "planning", undefined, undefined).status, "unreachable");
  assert.equal(s.withinReach(beyond), false);
  // Reached, then refused by structures loaded after the motion: still where the needle has been.
  assert.equal(s.targetDisplay({ ...base, status: "reached" }, "at_target", undefined, undefined).status, "reached");
});

test("the panel's commands: structure_role, propose_targets, plan_seeds and place_robot texts", () => {
  assert.equal(st.roleCommand("pubic arch", "avoid", 4), "pubic arch avoid 4");
  assert.equal(st.roleCommand("prostate", "target", 4), "prostate target"); // only avoid takes a margin
  assert.equal(st.proposeCommand("prostate", 7.5), "prostate 7.5");
  assert.equal(st.seedPlanCommand("prostate", NaN, NaN), "prostate"); // the site's dosimetry
  assert.equal(st.seedPlanCommand("prostate", 145, 0.6), "prostate rx=145 strength=0.6");
  assert.equal(st.seedPlanCommand("prostate", 0, NaN), "prostate rx=0"); // the server refuses it
  assert.equal(st.placeCommand("prostate", "superior"), "prostate from superior");
  assert.equal(st.placeCommand("prostate", ""), "prostate"); // the site's approach
  const structures = [{ name: "urethra", role: "avoid" }, { name: "prostate", role: "target" }, { name: "skin", role: "shown" }];
  assert.deepEqual(st.structureChoices(structures), ["prostate", "urethra", "skin"]);
});

test("colours, progress and the placement axis through the structure's far corner", () => {
  assert.equal(st.cssColour([1, 0.5, 0]), "rgb(255, 128, 0)");
  assert.equal(st.cssColour([2, -1, 0.2]), "rgb(255, 0, 51)");
  assert.equal(st.progressText(0, 0), "");
  assert.equal(st.progressText(31, 124), "25 % (31 of 124)");
  assert.equal(st.placementLabel(0), "proposed");
  assert.equal(st.placementLabel(2), "alternative 2");
  // The axis along +S from (0, 0, 0), the skin at 50 mm: a box up to z = 100 mm ends it there.
  const placement = { origin_lps: [0, 0, 0], axis_lps: [0, 0, 1], entry_lps: [0, 0, 50] };
  near(st.placementAxis(placement, [-5, -5, 60, 5, 5, 100])[1], [0, 0, 100]);
  // Tilted 45° in x-z: the farthest corner (5, 5, 100) is (5 + 100)/√2 along it.
  const c = Math.SQRT1_2;
  const tilted = st.placementAxis({ ...placement, axis_lps: [c, 0, c] }, [-5, -5, 60, 5, 5, 100]);
  near(tilted[1], [105 * c * c, 0, 105 * c * c], 1e-9);
  // No structure known: to the skin's entry.
  near(st.placementAxis(placement, undefined)[1], [0, 0, 50]);
});

// ---- the 3D view's pure parts (scene.ts) ----------------------------------------------------

test("standard views: right-handed cameras whose screen right and up are anatomy's", () => {
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  // Screen right = (direction of projection) x up, the direction of projection = -from.
  const right = (v) => cross(v.from.map((x) => -x), v.up);
  // From the front (anterior, -y in LPS) the patient's left (+x) is on the right, superior up.
  near(right(sc.kStandardViews.A), [1, 0, 0]);
  near(sc.kStandardViews.A.up, [0, 0, 1]);
  // From behind, the patient's right; from the left side, posterior (+y); from the right, anterior.
  near(right(sc.kStandardViews.P), [-1, 0, 0]);
  near(right(sc.kStandardViews.L), [0, 1, 0]);
  near(right(sc.kStandardViews.R), [0, -1, 0]);
  // From above, anterior up and the patient's right on the right; from below the axial picture
  // of radiology: anterior up, the patient's left on the right.
  near(right(sc.kStandardViews.S), [-1, 0, 0]);
  near(right(sc.kStandardViews.I), [1, 0, 0]);
  for (const v of Object.values(sc.kStandardViews)) assert.equal(Math.abs(v.from.reduce((a, x, i) => a + x * v.up[i], 0)), 0);
});

test("imageGeometry: spacing and direction columns from an oblique ijk -> LPS matrix", () => {
  const c = Math.cos(0.4);
  const n = Math.sin(0.4);
  // Columns: i axis 0.8 mm along (c, n, 0), j 0.9 mm along (-n, c, 0), k 1.5 mm along z.
  const m = [0.8 * c, -0.9 * n, 0, 10, 0.8 * n, 0.9 * c, 0, -20, 0, 0, 1.5, 30, 0, 0, 0, 1];
  const geometry = sc.imageGeometry(m);
  near(geometry.spacing, [0.8, 0.9, 1.5], 1e-12);
  near(geometry.origin, [10, -20, 30]);
  near(geometry.direction, [c, n, 0, -n, c, 0, 0, 0, 1], 1e-12);
});

test("windowTransfer: grey across the window in stored values, transparent up to the level", () => {
  // A stored value v is v * 2 - 1024 HU: the window 400 / 40 HU is -160..240 HU, 432..632 stored.
  const t = sc.windowTransfer(400, 40, 2, -1024);
  assert.deepEqual(t.colour, [[432, 0], [632, 1]]);
  assert.deepEqual(t.opacity, [[432, 0], [532, 0], [632, sc.kMaxOpacity]]);
});

test("stripsToTriangles: every triangle of a strip, wound as its first", () => {
  // One strip of 5 vertices (3 triangles) and one of 3 (1 triangle).
  const cells = sc.stripsToTriangles(Uint32Array.from([5, 10, 11, 12, 13, 14, 3, 20, 21, 22]));
  assert.deepEqual(Array.from(cells), [3, 10, 11, 12, 3, 12, 11, 13, 3, 12, 13, 14, 3, 20, 21, 22]);
});

test("slabsComplete: slabs that follow each other to the last slice, and no others", () => {
  assert.equal(sc.slabsComplete([4, 4, 10], [{ first_slice: 0, slice_count: 6 }, { first_slice: 6, slice_count: 4 }]), true);
  assert.equal(sc.slabsComplete([4, 4, 10], [{ first_slice: 0, slice_count: 6 }]), false);
  assert.equal(sc.slabsComplete([4, 4, 10], [{ first_slice: 0, slice_count: 6 }, { first_slice: 5, slice_count: 5 }]), false);
});

test("triangleCells and polylineCells: vtk.js's cell arrays", () => {
  assert.deepEqual(Array.from(sc.triangleCells(Uint32Array.from([0, 1, 2, 2, 1, 3]))), [3, 0, 1, 2, 3, 2, 1, 3]);
  assert.deepEqual(Array.from(sc.polylineCells(3)), [3, 0, 1, 2]);
});

test("decodeBase64: RFC 4648's vectors, as bytes", async () => {
  const text = (buffer) => Buffer.from(buffer).toString("latin1");
  assert.equal(text(await sc.decodeBase64("")), "");
  assert.equal(text(await sc.decodeBase64("Zg==")), "f");
  assert.equal(text(await sc.decodeBase64("Zm9vYmFy")), "foobar");
  assert.deepEqual(Array.from(new Uint8Array(await sc.decodeBase64("//4A"))), [0xff, 0xfe, 0x00]);
});

test("volumeBox: the box of an oblique volume's voxel centres", () => {
  // i along (0.6, 0.8, 0) at 1 mm, j along (-0.8, 0.6, 0), k 2 mm along z; 11 x 6 x 4 voxels at (5, 0, -3).
  const m = [0.6, -0.8, 0, 5, 0.8, 0.6, 0, 0, 0, 0, 2, -3, 0, 0, 0, 1];
  const [lo, hi] = g.volumeBox(m, [11, 6, 4]);
  near(lo, [5 - 0.8 * 5, 0, -3]);
  near(hi, [5 + 0.6 * 10, 0.8 * 10 + 0.6 * 5, 3]);
});
