// The web viewer end to end, in a real browser (Debian's chromium, headless, via playwright-core):
// a real ignav-server and ignav-web gateway over loopback DDS, a phantom CT with a known
// image->robot transform (ignav-plan phantom), and the operator's workflow done by clicks on the
// rendered slices. The registration and targets are checked against that ground truth, not
// against what the app says about itself. Then what issue 26 asked of the page: scrolling one
// view asks for its slice only and stops at the volume's edge; a page that joins late counts an
// approval down from the server's expiry, and an expired request cannot be approved; a double
// click approves once; with the gateway or the server gone a banner says so and nothing that
// would send a command (the emergency stop included) looks active, and a restarted gateway
// restores the page; an emergency stop puts up its own banner. And the closed loop (issue 23): a
// confirmation CT of the reached target (ignav-plan confirmation-phantom, the seed where agar,
// hidden from the server, deflects the needle) loaded from the page shows the seed beside its
// target, the error in the targets table and the summary, checked against the phantom's truth.
//
//   node tests/web/viewer_e2e.mjs --source SRC --build BUILD --out DIR [--chromium PATH] [--domain N]
//        [--app-dir DIR]   (the bundled app; default BUILD/tools/ignav-web/app)
//
// Screenshots of every stage go to --out (01-loaded.png ... 09-server-gone.png; failure.png).
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import {
  apply,
  appState,
  axialSlice,
  byTestId,
  check,
  clickLps,
  dist,
  dragLps,
  expectAccepted,
  fmt,
  goTo,
  invertRigid,
  kTimeoutMs,
  openPage,
  rows4,
  runBrowserTest,
  startBrowser,
  sleep,
  step,
  sub,
  testArgs,
  waitText,
} from "./browser_test.mjs";
import { kill, startGateway as startGatewayProcess, startServer } from "./children.mjs";

const { source, build, outDir, appDir, chromium, chromiumPath, domain } = testArgs("viewer_e2e.mjs", 150);

const kReachableRobotMm = [8, 12, -175]; // inside the workspace of configs/robots/torabi2014.yaml
const kUnreachableRobotMm = [30, 0, -180]; // 30 mm off the axis: beyond the maximum radius
const kMaxFreMm = 0.5; // clicks land on whole CSS pixels, about 0.3 mm here
const kMaxRegistrationErrorMm = 0.5; // at the fiducials and targets, against the true transform
const kMaxTipMissMm = 0.5; // motor steps are about 0.003 mm
const kMotionTimeoutMs = 40000;
// The server runs with this approval expiry (a copy of configs/server.yaml), so that the test can
// see a request expire; long enough for what is checked while the first request is pending.
const kExpiryS = 20;
const kViews = ["axial", "sagittal", "coronal"];

// How many slices each view has put on its canvas.
const slicesShown = (page) =>
  page.evaluate((views) => {
    const count = (v) => Number(document.querySelector(`canvas[data-view="${v}"]`).dataset.slicesShown ?? 0);
    return Object.fromEntries(views.map((v) => [v, count(v)]));
  }, kViews);
// A view's slice on screen: the centre it asked for and its pixel_to_lps (rows).
async function viewSlice(page, view) {
  const { centre, matrix } = await page.locator(`canvas[data-view="${view}"]`).evaluate((c) => ({
    centre: JSON.parse(c.dataset.centreLps),
    matrix: JSON.parse(c.dataset.pixelToLps),
  }));
  return { centre, m: rows4(matrix) };
}

// Waits until every view has shown more slices than `before` says.
async function waitSlicesAfter(page, before, timeout = kTimeoutMs) {
  await page.waitForFunction(
    ([views, counts]) =>
      views.every((v) => Number(document.querySelector(`canvas[data-view="${v}"]`).dataset.slicesShown) > counts[v]),
    [kViews, before],
    { timeout },
  );
}

// What on the page could send something: the enabled command buttons (workflow and target
// rows), the approve button and the emergency stop.
const controls = (page) =>
  page.evaluate(() => {
    const enabled = (selector) =>
      [...document.querySelectorAll(selector)].filter((b) => !b.disabled).map((b) => b.dataset.command ?? b.dataset.testid);
    const approve = document.querySelector('[data-testid="approve-button"]');
    const estop = document.querySelector('[data-testid="estop-button"]');
    return {
      commands: enabled("button[data-command]"),
      targetButtons: enabled("#targets-body button"),
      approve: approve.hidden ? "hidden" : approve.disabled ? "disabled" : "enabled",
      estop: { disabled: estop.disabled, unreachable: estop.classList.contains("unreachable"), text: estop.textContent.trim() },
    };
  });

const isVisible = (page, testid) =>
  page.evaluate((id) => {
    const element = document.querySelector(`[data-testid="${id}"]`);
    return element !== null && !element.hidden && element.getBoundingClientRect().height > 0;
  }, testid);

// Everything that would send a command is disabled, the E-STOP visibly so, and the banner says
// why (for `who`: "gateway" or "ignav-server").
async function checkCutOff(page, who) {
  await byTestId(page, "connection-banner").waitFor({ state: "visible", timeout: kTimeoutMs });
  const banner = await byTestId(page, "connection-banner").textContent();
  check(banner.includes(who) && /EMERGENCY STOP/.test(banner) && /hardware emergency stop/.test(banner),
    `the banner does not say that ${who} is out of reach and the E-STOP with it: "${banner}"`);
  // Full width and in view: it cannot be missed.
  const box = await byTestId(page, "connection-banner").boundingBox();
  const width = page.viewportSize().width;
  check(box.y < 200 && box.width > 0.9 * width, `the banner is not across the top (${JSON.stringify(box)})`);
  const now = await controls(page);
  check(now.commands.length === 0, `command buttons still enabled: ${now.commands}`);
  check(now.targetButtons.length === 0, `target buttons still enabled: ${now.targetButtons}`);
  check(now.approve !== "enabled", "the approve button is still enabled");
  check(now.estop.disabled && now.estop.unreachable && /NOT REACHABLE/.test(now.estop.text),
    `the E-STOP is not marked unreachable: ${JSON.stringify(now.estop)}`);
  console.log(`   banner: ${banner.slice(0, 110)}…`);
}

// The countdown a page shows ("expires in N s") against the server's expiry by the test's own
// clock (the server runs on this machine).
async function countdown(page, approval) {
  const text = await byTestId(page, "approval-expiry").textContent();
  const left_s = approval.expires_at_unix_s - Date.now() / 1000;
  const shown = Number(text.match(/expires in (\d+) s/)?.[1]);
  check(Number.isFinite(shown), `no countdown in "${text}"`);
  return { shown, left_s };
}

// Until the server has published a Health sample written after `unix_s` (its counters are then
// at least as new as everything before).
async function healthAfter(page, unix_s) {
  await page.waitForFunction((t) => (window.ignav.state().health?.server_time_unix_s ?? 0) > t, unix_s, {
    timeout: kTimeoutMs,
  });
  return (await appState(page)).health;
}

const approveEnabled = (page) =>
  page.waitForFunction(
    () => {
      const b = document.querySelector('[data-testid="approve-button"]');
      return b !== null && !b.hidden && !b.disabled;
    },
    null,
    { timeout: kTimeoutMs },
  );

// One wheel step after another over a view's canvas (deltaY > 0: along the view's normal).
async function wheel(page, view, steps) {
  const box = await page.locator(`canvas[data-view="${view}"]`).boundingBox();
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  for (let i = 0; i < Math.abs(steps); ++i) await page.mouse.wheel(0, Math.sign(steps) * 100);
}

// ---- the test ---------------------------------------------------------------------------------

async function run(pages) {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "ignav_web_e2e_"));
  console.log(`   work folder ${tmp} (kept on failure)`);
  fs.mkdirSync(outDir, { recursive: true });
  const shot = async (page, name) => {
    await page.screenshot({ path: path.join(outDir, name) });
    console.log(`   screenshot ${path.join(outDir, name)}`);
  };

  check(fs.existsSync(path.join(appDir, "app.js")), `${appDir}/app.js is missing: build the app`);
  step("phantom CT with its true image->robot transform (ignav-plan phantom)");
  const truth = JSON.parse(
    execFileSync(path.join(build, "tools/ignav-plan/ignav-plan"), [
      "phantom",
      path.join(tmp, "ct"),
      "--robot",
      path.join(source, "configs/robots/torabi2014.yaml"),
    ]).toString(),
  );
  const imageToRobotTrue = truth.image_to_robot_true;
  const robotToImageTrue = invertRigid(imageToRobotTrue);
  const fiducialsLps = truth.fiducials_lps_mm;
  check(fiducialsLps.length === 3, "the phantom has 3 fiducials");

  step(`ignav-server (approval.expiry_s ${kExpiryS} s) and ignav-web`);
  // configs/server.yaml with a short expiry, beside links to everything it names by a relative
  // path (robots/, dds/, tissues.yaml, ...).
  const configDir = path.join(tmp, "configs");
  fs.mkdirSync(configDir);
  for (const entry of fs.readdirSync(path.join(source, "configs"))) {
    if (entry !== "server.yaml") fs.symlinkSync(path.join(source, "configs", entry), path.join(configDir, entry));
  }
  const yaml = fs.readFileSync(path.join(source, "configs/server.yaml"), "utf8");
  const shortExpiry = yaml.replace(/^(\s*expiry_s:\s*)[0-9.]+/m, `$1${kExpiryS}`);
  check(shortExpiry !== yaml, "configs/server.yaml has no approval expiry_s to shorten");
  fs.writeFileSync(path.join(configDir, "server.yaml"), shortExpiry);
  const dds = path.join(source, "configs/dds/loopback.xml");
  const server = await startServer({
    build, config: path.join(configDir, "server.yaml"), domain, sessionDir: path.join(tmp, "session"), dds,
  });
  const startGateway = (port) => startGatewayProcess({ build, domain, dds, port, appDir });
  let gateway = await startGateway(0);
  const url = gateway.match[1];
  const port = Number(new URL(url).port);
  console.log(`   ${url}`);

  await startBrowser(pages, chromium, chromiumPath);
  const newPage = (name, options) => openPage(pages, url, name, options);
  const page = await newPage("page1");

  step(`load the CT by its path (${path.join(tmp, "ct")})`);
  await waitText(page, "phase", /imaging/);
  await byTestId(page, "load-path").fill(path.join(tmp, "ct"));
  await expectAccepted(page, "load_volume", () => byTestId(page, "load-path-button").click());
  // The load is a background job: the page shows its outcome (the JobOutcome topic) on the job line.
  await waitText(page, "last-job", /^CT load #\d+: done: \d+ x \d+ x \d+ voxels/);
  await waitText(page, "volume-status", /^loaded$/);
  await page.waitForFunction(() => document.querySelectorAll("canvas[data-pixel-to-lps]").length === 3, null, {
    timeout: kTimeoutMs,
  });
  await shot(page, "01-loaded.png");

  step("scroll the sagittal, then the coronal view: only that view asks for a slice; it stops at the edge");
  {
    const volume = (await appState(page)).volume;
    const ijk = rows4(volume.ijk_to_lps);
    const [ni, nj, nk] = volume.dims;
    const corners = [];
    for (const i of [0, ni - 1]) for (const j of [0, nj - 1]) for (const k of [0, nk - 1]) corners.push(apply(ijk, [i, j, k]));
    const maxY = Math.max(...corners.map((p) => p[1]));
    // The voxel spacing along x and y: of the volume axis nearest to each.
    const column = (j) => [ijk[0][j], ijk[1][j], ijk[2][j]];
    const along = (j, axis) => Math.abs(column(j)[axis]) / Math.hypot(...column(j));
    const spacingAlong = (axis) => Math.hypot(...column([0, 1, 2].sort((a, b) => along(b, axis) - along(a, axis))[0]));
    const start = await slicesShown(page);
    const sagittal0 = await viewSlice(page, "sagittal");
    await wheel(page, "sagittal", 1); // one step along the sagittal normal, -L: x decreases
    await page.waitForFunction((n) => Number(document.querySelector('canvas[data-view="sagittal"]').dataset.slicesShown) > n,
      start.sagittal, { timeout: kTimeoutMs });
    const sagittal1 = await viewSlice(page, "sagittal");
    const dx = sagittal1.centre[0] - sagittal0.centre[0];
    check(Math.abs(dx + spacingAlong(0)) < 1e-6 && sagittal1.centre[1] === sagittal0.centre[1] &&
      sagittal1.centre[2] === sagittal0.centre[2], `one step moved the sagittal centre by ${fmt(sub(sagittal1.centre, sagittal0.centre))}`);
    // The slice on screen is that plane (x is constant in a sagittal slice).
    check(Math.abs(sagittal1.m[0][3] - sagittal1.centre[0]) < 1e-6, `the sagittal slice is at x = ${sagittal1.m[0][3]}`);
    await sleep(500); // time for anything else that was (wrongly) asked for to arrive
    const afterOne = await slicesShown(page);
    console.log(`   sagittal: one step, x ${sagittal0.centre[0].toFixed(2)} -> ${sagittal1.centre[0].toFixed(2)} mm; ` +
      `slices shown ${JSON.stringify(start)} -> ${JSON.stringify(afterOne)}`);
    check(afterOne.axial === start.axial && afterOne.coronal === start.coronal && afterOne.sagittal === start.sagittal + 1,
      "a sagittal step asked other views for slices");
    // The coronal view, to beyond its edge: it stops at the last voxel centre along +P.
    const coronal0 = await viewSlice(page, "coronal");
    const steps = Math.ceil((maxY - coronal0.centre[1]) / spacingAlong(1)) + 15;
    await wheel(page, "coronal", steps);
    await page.waitForFunction(
      (y) => Math.abs(JSON.parse(document.querySelector('canvas[data-view="coronal"]').dataset.centreLps)[1] - y) < 1e-6,
      maxY, { timeout: kTimeoutMs });
    await sleep(500); // time for anything else that was (wrongly) asked for to arrive
    const coronal1 = await viewSlice(page, "coronal");
    check(Math.abs(coronal1.centre[1] - maxY) < 1e-6 && Math.abs(coronal1.m[1][3] - maxY) < 1e-6,
      `after ${steps} steps the coronal slice is at y = ${coronal1.m[1][3]}, not at the edge ${maxY}`);
    const end = await slicesShown(page);
    console.log(`   coronal: ${steps} steps, y ${coronal0.centre[1].toFixed(2)} -> ${coronal1.centre[1].toFixed(2)} mm (edge ${maxY.toFixed(2)}); slices shown ${JSON.stringify(start)} -> ${JSON.stringify(end)}`);
    check(end.axial === start.axial, `scrolling asked the axial view for ${end.axial - start.axial} slices`);
    check(end.sagittal === start.sagittal + 1, `one sagittal step showed ${end.sagittal - start.sagittal} sagittal slices`);
    check(end.coronal > start.coronal, "the coronal view showed no new slice");
  }

  step("click the three fiducials on the axial slice");
  await byTestId(page, "mode-fiducial").check();
  const offsets_mm = [[11.3, -7.9], [-9.1, 6.7], [7.7, 10.3]];
  for (const [i, lps] of fiducialsLps.entries()) {
    await goTo(page, lps, offsets_mm[i]);
    if (i < 2) {
      await clickLps(page, lps);
      await page.waitForFunction((n) => document.querySelectorAll('[data-testid="pending-fiducials"] li').length === n, i + 1);
    } else {
      await expectAccepted(page, "set_fiducials", () => clickLps(page, lps));
    }
    console.log(`   F${i + 1} at ${fmt(lps)}`);
  }
  await waitText(page, "registration-status", /^registered/);
  const fre = Number.parseFloat(await waitText(page, "fre", /mm/));
  console.log(`   FRE shown: ${fre} mm`);
  check(fre < kMaxFreMm, `FRE ${fre} mm is not below ${kMaxFreMm} mm`);
  const registered = rows4((await appState(page)).registration.image_to_robot);
  const checkPoints = [...fiducialsLps, apply(robotToImageTrue, kReachableRobotMm)];
  const worst = Math.max(...checkPoints.map((p) => dist(apply(registered, p), apply(imageToRobotTrue, p))));
  console.log(`   registered vs true transform: ${worst.toFixed(3)} mm at worst (fiducials, target)`);
  check(worst < kMaxRegistrationErrorMm, `the registration is ${worst} mm off the truth`);
  await shot(page, "02-fiducials.png");

  step("add a reachable and an unreachable target by clicking");
  await byTestId(page, "mode-target").check();
  const addTarget = async (lps, offset_mm) => {
    await goTo(page, lps, offset_mm);
    const reply = await expectAccepted(page, "add_target", () => clickLps(page, lps));
    const id = Number(reply.match(/target (\d+)/)?.[1]);
    check(id > 0, `no target id in "${reply}"`);
    return id;
  };
  // The reachable one is first clicked 4 mm off and then dragged to its place (move_target).
  const reachableLps = apply(robotToImageTrue, kReachableRobotMm);
  const { axis } = await axialSlice(page);
  const beside = reachableLps.map((x, i) => x + (4 * axis(0)[i]) / Math.hypot(...axis(0)));
  const reachable = await addTarget(beside, [-6.1, 8.2]);
  await waitText(page, `target-status-${reachable}`, /^reachable$/);
  const dropped = (await appState(page)).targets[String(reachable)].lps;
  await expectAccepted(page, "move_target", () => dragLps(page, dropped, reachableLps));
  await page.waitForFunction(
    ([id, want]) => {
      const target = window.ignav.state().targets?.[id];
      return target && Math.hypot(...target.lps.map((x, i) => x - want[i])) < 0.5;
    },
    [String(reachable), reachableLps],
    { timeout: kTimeoutMs },
  );
  await waitText(page, `target-status-${reachable}`, /^reachable$/);
  const placed = (await appState(page)).targets[String(reachable)].lps;
  console.log(`   T${reachable}: robot ${fmt(kReachableRobotMm)} = LPS ${fmt(reachableLps)}, dragged to ${fmt(placed)}`);

  const unreachableLps = apply(robotToImageTrue, kUnreachableRobotMm);
  const unreachable = await addTarget(unreachableLps, [5.3, 3.1]);
  console.log(`   T${unreachable}: robot ${fmt(kUnreachableRobotMm)} = LPS ${fmt(unreachableLps)}`);
  await waitText(page, `target-status-${unreachable}`, /^unreachable$/);
  const reason = await waitText(page, `target-reach-${unreachable}`, /radius/i);
  console.log(`   T${unreachable}: ${reason}`);
  await shot(page, "03-targets.png");

  step("a second browser shows the same targets; a reload and a dropped socket restore the view");
  const second = await newPage("page2");
  await waitText(second, `target-status-${reachable}`, /^reachable$/);
  await waitText(second, `target-status-${unreachable}`, /^unreachable$/);
  await second.reload();
  await waitText(second, `target-status-${reachable}`, /^reachable$/);
  await second.waitForFunction(() => document.querySelectorAll("canvas[data-pixel-to-lps]").length === 3, null, {
    timeout: kTimeoutMs,
  });
  const slicesBefore = Number(await page.locator('canvas[data-view="axial"]').getAttribute("data-slices-shown"));
  await page.evaluate(() => window.ignav.dropConnection());
  await page.waitForFunction(
    (n) => Number(document.querySelector('canvas[data-view="axial"]').dataset.slicesShown) > n,
    slicesBefore,
    { timeout: kTimeoutMs },
  );
  await waitText(page, "connection", /gateway: connected · server: connected/);
  await waitText(page, `target-status-${reachable}`, /^reachable$/);

  step("delete the unreachable target, lock the plan, request approval");
  await expectAccepted(page, "remove_target", () => byTestId(page, `target-delete-${unreachable}`).click());
  await byTestId(page, `target-row-${unreachable}`).waitFor({ state: "detached", timeout: kTimeoutMs });
  await expectAccepted(page, "lock_plan", () => byTestId(page, "action-lock_plan").click());
  await waitText(page, "phase", /^plan_locked$/);
  await expectAccepted(page, "request_approval", () => byTestId(page, "action-request_approval").click());
  const summary = await waitText(page, "approval-summary", new RegExp(`${reachable}`));
  console.log(`   summary: ${summary.replace(/\s+/g, " ").slice(0, 160)}`);
  await waitText(page, `target-status-${reachable}`, /^awaiting approval$/);
  await approveEnabled(page);
  const first = (await appState(page)).approval;
  const requested_s = first.expires_at_unix_s - kExpiryS; // on the server's clock
  await shot(page, "04-approval.png");

  step("a page that joins 5 s later, its clock 7 minutes off, counts down from the server's expiry");
  await sleep(Math.max(0, (requested_s + 5) * 1000 - Date.now()));
  const late = await newPage("late", { clockShift_ms: -7 * 60 * 1000 });
  await waitText(late, "approval-expiry", /expires in \d+ s/);
  // The page's estimate of the server's clock errs by how late it reads the freshest sample: its
  // 3D view's first frames (the CT and the feasible volume: WebGL contexts and shaders, seconds in
  // headless software rendering) keep its thread busy for that long. Counted once they are drawn.
  await late.waitForFunction(() => {
    const d = window.ignav.view3d.describe();
    return d.drawn_at_ms.volume !== undefined && d.drawn_at_ms.surfaces !== undefined;
  }, null, { timeout: 60000 });
  await sleep(1500); // a fresh health sample (the gateway's cached one may be a second old)
  for (const [name, p] of [["late page", late], ["first page", page]]) {
    const { shown, left_s } = await countdown(p, first);
    console.log(`   ${name}: "expires in ${shown} s", ${left_s.toFixed(2)} s left by the server's expiry`);
    // Rounded up, and from the last quarter-second tick: at most 1.25 s over, plus the delivery of
    // the freshest sample; never under (the page's estimate of the server's clock is a lower
    // bound). Counting from the request's arrival, the late page would show about 5 s more.
    check(shown - left_s >= -0.5 && shown - left_s <= 2, `${name} shows ${shown} s left; ${left_s.toFixed(2)} s are`);
  }

  step("the gateway dies (SIGKILL): a banner, nothing that sends enabled, the E-STOP marked unreachable");
  const before = { shown: await slicesShown(page), controls: await controls(page) };
  for (const command of ["unlock_plan", "request_approval", "stop"]) {
    check(before.controls.commands.includes(command), `${command} was not enabled before (${before.controls.commands})`);
  }
  check(before.controls.approve === "enabled" && !before.controls.estop.disabled, "approve or E-STOP not enabled before");
  await kill(gateway);
  await checkCutOff(page, "gateway");
  const expiryWhileDown = await byTestId(page, "approval-expiry").textContent();
  check(/not reachable/.test(expiryWhileDown), `the approval still counts down as if approvable: "${expiryWhileDown}"`);
  await shot(page, "05-gateway-gone.png");

  step("the gateway restarts on its port: the page is connected again and shows its slices");
  const restarted = Date.now();
  gateway = await startGateway(port);
  await waitText(page, "connection", /gateway: connected · server: connected/);
  await waitSlicesAfter(page, before.shown);
  console.log(`   restored ${Date.now() - restarted} ms after the restart (${JSON.stringify(before.shown)} -> ${JSON.stringify(await slicesShown(page))})`);
  check(!(await isVisible(page, "connection-banner")), "the banner is still up");
  const after = await controls(page);
  check(JSON.stringify(after.commands) === JSON.stringify(before.controls.commands),
    `the commands enabled are ${after.commands}, not ${before.controls.commands} as before`);
  check(!after.estop.disabled && !after.estop.unreachable, "the E-STOP is not back");
  if (first.expires_at_unix_s - Date.now() / 1000 > 2) await approveEnabled(page);

  step(`the request expires (approval.expiry_s ${kExpiryS}): shown expired, no active Approve, on a page that joins after too`);
  await waitText(page, "approval-expiry", /^expired/, (kExpiryS + 5) * 1000);
  const shownAt_s = Date.now() / 1000;
  check(shownAt_s >= first.expires_at_unix_s - 0.05,
    `shown expired ${(first.expires_at_unix_s - shownAt_s).toFixed(2)} s before the server's expiry`);
  await late.reload();
  await waitText(late, "connection", /gateway: connected · server: connected/);
  await waitText(late, "approval-expiry", /^expired/);
  for (const p of [page, late]) {
    const pending = (await appState(p)).approval;
    check(pending.status === "pending" && pending.plan_id === first.plan_id, "the expired request is not the one shown");
    check((await controls(p)).approve !== "enabled", "an expired request can be approved");
  }
  await late.context().close();
  pages.open.splice(pages.open.indexOf(late), 1);

  step("request approval again; a double click on Approve sends one approval; the robot moves to the target");
  await expectAccepted(page, "request_approval", () => byTestId(page, "action-request_approval").click());
  await page.waitForFunction((id) => window.ignav.state().approval?.plan_id > id, first.plan_id, { timeout: kTimeoutMs });
  await approveEnabled(page);
  const health0 = await healthAfter(page, Date.now() / 1000);
  const replies0 = Number(await byTestId(page, "last-reply").getAttribute("data-count"));
  await byTestId(page, "approve-button").dblclick();
  await page.waitForFunction((n) => Number(document.querySelector('[data-testid="last-reply"]').dataset.count) > n,
    replies0, { timeout: kTimeoutMs });
  // The server's own count, from a health sample written well after both clicks would have landed.
  const health1 = await healthAfter(page, Date.now() / 1000 + 0.5);
  const replies1 = Number(await byTestId(page, "last-reply").getAttribute("data-count"));
  const approved = (await byTestId(page, "last-reply").textContent()).trim();
  console.log(`   server: ${health1.commands_accepted - health0.commands_accepted} accepted, ` +
    `${health1.commands_rejected - health0.commands_rejected} rejected; ${replies1 - replies0} replies ("${approved}")`);
  check(health1.commands_accepted === health0.commands_accepted + 1 &&
    health1.commands_rejected === health0.commands_rejected, "the double click did not make exactly one approval");
  check(replies1 === replies0 + 1, `${replies1 - replies0} replies to one double click`);
  check(approved.startsWith("approve: accepted"), `the approval was not accepted: "${approved}"`);
  await waitText(page, `target-status-${reachable}`, /^reached$/, kMotionTimeoutMs);
  const state = await appState(page);
  const target = state.targets[String(reachable)];
  // The robot's own account (its reported steps through the kinematics and the registration).
  check(state.motion.tip_lps !== null, "no needle tip in the motion state");
  const miss = dist(state.motion.tip_lps, target.lps);
  console.log(`   tip at ${fmt(state.motion.tip_lps)}, ${miss.toFixed(3)} mm from the target (LPS)`);
  check(miss < kMaxTipMissMm, `the tip stopped ${miss} mm from the target`);
  await waitText(page, "phase", /^(at_target|done)$/);
  check(!(await isVisible(page, "phase-banner")), "a phase banner outside an emergency");
  await shot(page, "06-reached.png");

  step("a confirmation CT (agar hidden from the server): the seed beside its target, the error, the summary");
  {
    // The physical world for this session: the seed where agar deflects the needle at the joints
    // the robot went to, and the truth of where it is (ignav-plan confirmation-phantom).
    const confirmationDir = path.join(tmp, "confirmation");
    const made = JSON.parse(
      execFileSync(path.join(build, "tools/ignav-plan/ignav-plan"), [
        "confirmation-phantom", state.health.session_dir,
        "--robot", path.join(source, "configs/robots/torabi2014.yaml"),
        "--out", confirmationDir,
        "--hidden-tissue", "agar", "--tissues", path.join(source, "configs/tissues.yaml"), "--json",
      ]).toString(),
    );
    const truth = made.targets.find((t) => t.id === reachable);
    check(truth !== undefined, `the confirmation phantom has no seed for T${reachable}: ${JSON.stringify(made.targets)}`);
    // What a perfect localiser reports through the session's registration (which carries its own
    // small error, checked above): the seed's true position in that robot frame, less the plan.
    const expectedError = dist(apply(registered, truth.landing_lps_mm), target.robot);
    console.log(`   seed at LPS ${fmt(truth.landing_lps_mm)}, ${truth.landing_off_plan_mm.toFixed(3)} mm off the plan ` +
      `(true frame); ${expectedError.toFixed(3)} mm through the session's registration`);
    await byTestId(page, "confirmation-path").fill(confirmationDir);
    await expectAccepted(page, "load_confirmation", () => byTestId(page, "action-load_confirmation").click());
    await waitText(page, "verification-status", /^measured$/, 60000);

    // The table: the error column, as measured.
    const shownError = Number.parseFloat(await waitText(page, `target-error-${reachable}`, /^\d+\.\d\d$/));
    console.log(`   T${reachable}: error column ${shownError} mm; predicted ${await byTestId(page, `target-predicted-${reachable}`).textContent()}; ` +
      `aim ${await byTestId(page, `target-aim-${reachable}`).textContent()}`);
    check(Math.abs(shownError - expectedError) < 0.1 + 0.005, `the error column shows ${shownError} mm, the truth is ${expectedError.toFixed(3)} mm`);
    // The summary panel: one target, its error as mean (no SD of one), max = min = RMS; no target
    // without a seed, no extra seed; the server's sentence.
    const summary = await waitText(page, "verification-summary", /1 target\(s\): error \d+\.\d\d/);
    console.log(`   summary: ${summary}`);
    check(Math.abs(Number(summary.match(/error (\d+\.\d\d)/)[1]) - expectedError) < 0.105, `the summary says "${summary}"`);
    const mean = await byTestId(page, "verification-error").textContent();
    check(mean === `${shownError.toFixed(2)} mm`, `the error's mean shows "${mean}", the column ${shownError}`);
    const extremes = await byTestId(page, "verification-error-extremes").textContent();
    const e = shownError.toFixed(2);
    check(extremes === `max ${e} · min ${e} · RMS ${e} mm (n = 1)`, `max, min, RMS show "${extremes}"`);
    for (const [testid, want] of [["verification-missing", "none"], ["verification-extra", "none"]]) {
      const text = await byTestId(page, testid).textContent();
      check(text === want, `[data-testid=${testid}] shows "${text}", not "${want}"`);
    }
    console.log(`   registration: ${await byTestId(page, "verification-registration").textContent()}`);

    // The seed on the slices: the axial view through its true position (off the view's middle,
    // so that the mapping is tested) draws it there, on the plane, a red cross over the CT.
    for (let i = 0; i < 3; ++i) await byTestId(page, "zoom-in").click(); // about 0.14 mm per pixel
    await goTo(page, truth.landing_lps_mm, [6.3, -4.1]);
    const drawn = await page.waitForFunction(
      (id) => {
        const seeds = JSON.parse(document.querySelector('canvas[data-view="axial"]').dataset.seeds ?? "[]");
        return seeds.find((s) => s.target_id === id && s.on_plane) ?? false;
      },
      reachable,
      { timeout: kTimeoutMs },
    ).then((handle) => handle.jsonValue());
    const { m } = await axialSlice(page);
    const drawnLps = apply(m, [drawn.u, drawn.v, 0]);
    const off = dist(drawnLps, truth.landing_lps_mm);
    console.log(`   seed S${drawn.seed_id} drawn at pixel (${drawn.u.toFixed(1)}, ${drawn.v.toFixed(1)}) = LPS ${fmt(drawnLps)}, ` +
      `${off.toFixed(3)} mm from the truth`);
    check(off < 0.2, `the seed is drawn ${off} mm from where it is`);
    const [r, g, b] = await page.locator('canvas[data-view="axial"]').evaluate(
      (c, [u, v]) => [...c.getContext("2d").getImageData(Math.round(u), Math.round(v), 1, 1).data],
      [drawn.u, drawn.v],
    );
    check(r > 150 && r - Math.max(g, b) > 60, `the seed's pixel is (${r}, ${g}, ${b}), not the seed's red`);
    await shot(page, "07-confirmation.png");

    // The click fallback from the table: accept the seed as this target's.
    await expectAccepted(page, "accept_seed", () => byTestId(page, `target-accept-seed-${reachable}`).click());
    await page.waitForFunction((id) => window.ignav.state().verification?.targets.find((t) => t.target_id === id)?.matched === "accepted",
      reachable, { timeout: kTimeoutMs });
    await page.waitForFunction(
      (id) => /\(accepted\)/.test(document.querySelector(`[data-testid="target-error-${id}"]`)?.title ?? ""),
      reachable, { timeout: kTimeoutMs },
    ).catch(async () => {
      const title = await byTestId(page, `target-error-${reachable}`).getAttribute("title");
      throw new Error(`the error cell does not say the seed was accepted: "${title}"`);
    });
    // ... and reject it (not a seed of this plan): the target has none now, and says so.
    await expectAccepted(page, "reject_seed", () => byTestId(page, `target-reject-seed-${reachable}`).click());
    await waitText(page, `target-error-${reachable}`, /^no seed$/);
    await waitText(page, "verification-missing", new RegExp(`^T${reachable}$`));
    console.log(`   rejected: ${await byTestId(page, "verification-status").textContent()}; ` +
      `${await byTestId(page, "verification-summary").textContent().catch(() => "(no summary)")}`);
    await shot(page, "07-confirmation-rejected.png");
  }

  step("emergency stop: a banner says what happened and what to do");
  await expectAccepted(page, "emergency_stop", () => byTestId(page, "estop-button").click());
  await waitText(page, "phase", /^emergency$/);
  await waitText(second, "phase", /^emergency$/);
  for (const p of [page, second]) {
    await byTestId(p, "phase-banner").waitFor({ state: "visible", timeout: kTimeoutMs });
    const text = await byTestId(p, "phase-banner").textContent();
    check(/^EMERGENCY STOP/.test(text) && /Reset emergency/.test(text), `the emergency banner says "${text}"`);
  }
  check((await controls(page)).commands.includes("reset_emergency"), "reset_emergency is not offered");
  await shot(page, "08-emergency.png");

  step("the server dies (SIGKILL): the gateway says so within seconds, and the page cuts itself off");
  const killed = Date.now();
  await kill(server);
  // DDS alone would keep the dead server matched until its lease ran out (10 s): the gateway
  // goes by its health samples, which stop (3 s of silence).
  await waitText(page, "connection", /server: not connected/, 8000);
  console.log(`   the page said so ${Date.now() - killed} ms after the kill`);
  await checkCutOff(page, "ignav-server");
  const healthz = await (await fetch(new URL("/healthz", url))).json();
  check(healthz.server === false, `the gateway's /healthz says ${JSON.stringify(healthz)}`);
  await shot(page, "09-server-gone.png");

  fs.rmSync(tmp, { recursive: true, force: true });
}

await runBrowserTest("web viewer e2e", outDir, run);
