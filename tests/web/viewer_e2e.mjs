// The web viewer end to end, in a real browser (Debian's chromium, headless, via playwright-core):
// a real ignav-server and ignav-web gateway over loopback DDS, a phantom CT with a known
// image->robot transform (ignav-plan phantom), and the operator's workflow done by clicks on the
// rendered slices. The registration and targets are checked against that ground truth, not
// against what the app says about itself.
//
//   node tests/web/viewer_e2e.mjs --source SRC --build BUILD --out DIR [--chromium PATH] [--domain N]
//        [--app-dir DIR]   (the bundled app; default BUILD/tools/ignav-web/app)
//
// Screenshots of every stage go to --out (01-loaded.png ... 06-emergency.png; failure.png).
import { spawn, execFileSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { createRequire } from "node:module";
import { parseArgs } from "node:util";

const { values: args } = parseArgs({
  options: {
    source: { type: "string" },
    build: { type: "string" },
    out: { type: "string" },
    chromium: { type: "string", default: "/usr/bin/chromium" },
    domain: { type: "string", default: "150" },
    "app-dir": { type: "string" },
  },
});
if (!args.source || !args.build || !args.out) {
  console.error("usage: viewer_e2e.mjs --source SRC --build BUILD --out DIR [--chromium PATH] [--domain N]");
  process.exit(2);
}
const source = path.resolve(args.source);
const build = path.resolve(args.build);
const outDir = path.resolve(args.out);
const appDir = path.resolve(args["app-dir"] ?? path.join(build, "tools/ignav-web/app"));
const appPackage = path.join(source, "tools/ignav-web/app/package.json");
const { chromium } = createRequire(appPackage)("playwright-core");

const kReachableRobotMm = [8, 12, -175]; // inside the workspace of configs/robots/torabi2014.yaml
const kUnreachableRobotMm = [30, 0, -180]; // 30 mm off the axis: beyond the maximum radius
const kMaxFreMm = 0.5; // clicks land on whole CSS pixels, about 0.3 mm here
const kMaxRegistrationErrorMm = 0.5; // at the fiducials and targets, against the true transform
const kMaxTipMissMm = 0.5; // motor steps are about 0.003 mm
const kTimeoutMs = 15000;
const kMotionTimeoutMs = 40000;

const started = Date.now();
let stepNumber = 0;
function step(text) {
  console.log(`[${((Date.now() - started) / 1000).toFixed(1)} s] ${++stepNumber}. ${text}`);
}
function check(condition, message) {
  if (!condition) throw new Error(message);
}

// ---- linear algebra for the ground truth (independent of the app's own geometry) -----------

const sub = (a, b) => a.map((x, i) => x - b[i]);
const dot = (a, b) => a.reduce((s, x, i) => s + x * b[i], 0);
const dist = (a, b) => Math.hypot(...sub(a, b));
const apply = (m, p) => [0, 1, 2].map((r) => m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3]);
const rows4 = (flat) => [0, 1, 2, 3].map((r) => flat.slice(4 * r, 4 * r + 4));
// The inverse of a rigid transform [R t]: [Rᵀ, -Rᵀt].
function invertRigid(m) {
  const rt = [0, 1, 2].map((r) => [0, 1, 2].map((c) => m[c][r]));
  const t = [m[0][3], m[1][3], m[2][3]];
  return [...rt.map((row) => [...row, -dot(row, t)]), [0, 0, 0, 1]];
}
const fmt = (p) => p.map((x) => x.toFixed(2)).join(", ");

// ---- processes ------------------------------------------------------------------------------

const children = [];
function startProcess(name, exe, argv, readyPattern) {
  check(fs.existsSync(exe), `${exe} is missing: build the project first`);
  const child = spawn(exe, argv, { stdio: ["ignore", "pipe", "pipe"] });
  const record = { name, child, output: "" };
  children.push(record);
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`${name} not ready in ${kTimeoutMs} ms`)), kTimeoutMs);
    const collect = (chunk) => {
      record.output += chunk.toString();
      const match = record.output.match(readyPattern);
      if (match) {
        clearTimeout(timer);
        resolve(match);
      }
    };
    child.stdout.on("data", collect);
    child.stderr.on("data", (chunk) => (record.output += chunk.toString()));
    child.on("exit", (code, signal) => {
      clearTimeout(timer);
      reject(new Error(`${name} exited (${code ?? signal}) before it was ready:\n${record.output}`));
    });
  });
}
function killChildren() {
  for (const { child } of children) if (child.exitCode === null && child.signalCode === null) child.kill("SIGKILL");
}
process.on("exit", killChildren);
for (const signal of ["SIGINT", "SIGTERM"]) process.on(signal, () => process.exit(1));

async function stopChildren() {
  await Promise.all(
    children.map(({ child }) => {
      if (child.exitCode !== null || child.signalCode !== null) return null;
      return new Promise((resolve) => {
        const force = setTimeout(() => child.kill("SIGKILL"), 3000);
        child.on("exit", () => {
          clearTimeout(force);
          resolve();
        });
        child.kill("SIGTERM");
      });
    }),
  );
}

// ---- page helpers -----------------------------------------------------------------------------

const byTestId = (page, id) => page.locator(`[data-testid="${id}"]`);

async function waitText(page, testid, pattern, timeout = kTimeoutMs) {
  try {
    await page.waitForFunction(
      ([id, source, flags]) => {
        const element = document.querySelector(`[data-testid="${id}"]`);
        return element !== null && new RegExp(source, flags).test(element.textContent ?? "");
      },
      [testid, pattern.source, pattern.flags],
      { timeout },
    );
  } catch (error) {
    const now = await byTestId(page, testid).first().textContent({ timeout: 1000 }).catch(() => "(absent)");
    throw new Error(`[data-testid=${testid}] never matched ${pattern} (it shows "${now}"): ${error.message}`);
  }
  return byTestId(page, testid).first().textContent();
}

// Does `act`, then returns the reply line it produced (the line counts replies).
async function replyTo(page, act) {
  const before = Number(await byTestId(page, "last-reply").getAttribute("data-count"));
  await act();
  await page.waitForFunction(
    (n) => Number(document.querySelector('[data-testid="last-reply"]').dataset.count) > n,
    before,
    { timeout: kTimeoutMs },
  );
  return (await byTestId(page, "last-reply").textContent()).trim();
}

async function expectAccepted(page, what, act) {
  const reply = await replyTo(page, act);
  check(reply.startsWith(`${what}: accepted`), `${what} was not accepted: "${reply}"`);
  console.log(`   reply: ${reply}`);
  return reply;
}

// The axial slice on screen: its pixel_to_lps rows and the canvas' resolution and box.
async function axialSlice(page) {
  const canvas = page.locator('canvas[data-view="axial"]');
  const { matrix, widthPx, heightPx } = await canvas.evaluate((c) => ({
    matrix: JSON.parse(c.dataset.pixelToLps),
    widthPx: c.width,
    heightPx: c.height,
  }));
  const m = rows4(matrix);
  const axis = (j) => [m[0][j], m[1][j], m[2][j]];
  return { m, axis, widthPx, heightPx, box: await canvas.boundingBox() };
}

// Centres the views on `lps` moved in the axial plane by offset_mm (along the slice's u and v),
// with the "go to" field, and waits until the axial view shows that centre. The offset puts the
// point off the middle of the view, so that a click on it is a real test of the mapping.
async function goTo(page, lps, [du_mm, dv_mm] = [0, 0]) {
  const { axis } = await axialSlice(page);
  const unit = (v) => v.map((x) => x / Math.hypot(...v));
  const centre = lps.map((x, i) => x + du_mm * unit(axis(0))[i] + dv_mm * unit(axis(1))[i]);
  await byTestId(page, "goto").fill(centre.map(String).join(","));
  await byTestId(page, "goto-button").click();
  await page.waitForFunction(
    (want) => {
      const shown = document.querySelector('canvas[data-view="axial"]')?.dataset.centreLps;
      return shown !== undefined && JSON.parse(shown).every((x, i) => Math.abs(x - want[i]) < 1e-9);
    },
    centre,
    { timeout: kTimeoutMs },
  );
}

// Where the LPS point is on the screen in the rendered axial slice: through the slice's own
// pixel_to_lps (LPS = M·(u, v, 0, 1), pixel centres at integers) and the canvas' box.
async function screenPoint(page, lps) {
  const { m, axis, widthPx, heightPx, box } = await axialSlice(page);
  const d = sub(lps, axis(3));
  // The slice's axes are orthogonal: project onto each.
  const u = dot(d, axis(0)) / dot(axis(0), axis(0));
  const v = dot(d, axis(1)) / dot(axis(1), axis(1));
  const offPlane = dist(apply(m, [u, v, 0]), lps);
  check(offPlane < 1e-6, `the axial slice does not pass through ${fmt(lps)} (off by ${offPlane} mm)`);
  check(u >= 0 && v >= 0 && u < widthPx && v < heightPx, `${fmt(lps)} is outside the axial view`);
  return { x: box.x + ((u + 0.5) * box.width) / widthPx, y: box.y + ((v + 0.5) * box.height) / heightPx };
}

async function clickLps(page, lps) {
  const { x, y } = await screenPoint(page, lps);
  await page.mouse.click(x, y);
}

async function dragLps(page, from, to) {
  const a = await screenPoint(page, from);
  const b = await screenPoint(page, to);
  await page.mouse.move(a.x, a.y);
  await page.mouse.down();
  await page.mouse.move(b.x, b.y, { steps: 8 });
  await page.mouse.up();
}

const appState = (page) => page.evaluate(() => window.ignav.state());

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

  step("ignav-server and ignav-web");
  const dds = path.join(source, "configs/dds/loopback.xml");
  await startProcess(
    "ignav-server",
    path.join(build, "server/ignav-server"),
    ["--config", path.join(source, "configs/server.yaml"), "--domain", args.domain,
     "--session-dir", path.join(tmp, "session"), "--dds-config", dds],
    /ignav-server ready/,
  );
  const [, url] = await startProcess(
    "ignav-web",
    path.join(build, "tools/ignav-web/ignav-web"),
    ["--dds-config", dds, "--domain", args.domain, "--port", "0", "--client-id", "operator",
     "--app-dir", appDir],
    /ignav-web ready url=(\S+)/,
  );
  console.log(`   ${url}`);

  step(`chromium (${args.chromium})`);
  check(fs.existsSync(args.chromium), `${args.chromium} is missing (tools/setup.sh installs Debian's chromium)`);
  const browser = await chromium.launch({ executablePath: args.chromium, args: ["--no-sandbox"] });
  pages.browser = browser;
  const newPage = async (name) => {
    const context = await browser.newContext({ viewport: { width: 1600, height: 1000 } });
    const page = await context.newPage();
    page.on("console", (m) => pages.log.push(`[${name} ${m.type()}] ${m.text()}`));
    page.on("pageerror", (e) => pages.log.push(`[${name} pageerror] ${e.message}`));
    pages.open.push(page);
    await page.goto(url);
    await waitText(page, "connection", /gateway: connected · server: connected/);
    return page;
  };
  const page = await newPage("page1");

  step(`load the CT by its path (${path.join(tmp, "ct")})`);
  await waitText(page, "phase", /imaging/);
  await byTestId(page, "load-path").fill(path.join(tmp, "ct"));
  await expectAccepted(page, "load_volume", () => byTestId(page, "load-path-button").click());
  await waitText(page, "volume-status", /^loaded$/);
  await page.waitForFunction(() => document.querySelectorAll("canvas[data-pixel-to-lps]").length === 3, null, {
    timeout: kTimeoutMs,
  });
  await shot(page, "01-loaded.png");

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
  await byTestId(page, "approve-button").waitFor({ state: "visible", timeout: kTimeoutMs });
  await shot(page, "04-approval.png");

  step("approve; the simulated robot moves to the target");
  await expectAccepted(page, "approve", () => byTestId(page, "approve-button").click());
  await waitText(page, `target-status-${reachable}`, /^reached$/, kMotionTimeoutMs);
  const state = await appState(page);
  const target = state.targets[String(reachable)];
  // The robot's own account (its reported steps through the kinematics and the registration).
  check(state.motion.tip_lps !== null, "no needle tip in the motion state");
  const miss = dist(state.motion.tip_lps, target.lps);
  console.log(`   tip at ${fmt(state.motion.tip_lps)}, ${miss.toFixed(3)} mm from the target (LPS)`);
  check(miss < kMaxTipMissMm, `the tip stopped ${miss} mm from the target`);
  await waitText(page, "phase", /^(at_target|done)$/);
  await shot(page, "05-reached.png");

  step("emergency stop");
  await expectAccepted(page, "emergency_stop", () => byTestId(page, "estop-button").click());
  await waitText(page, "phase", /^emergency$/);
  await waitText(second, "phase", /^emergency$/);
  await shot(page, "06-emergency.png");

  fs.rmSync(tmp, { recursive: true, force: true });
}

const pages = { browser: null, open: [], log: [] };
let failed = false;
try {
  await run(pages);
  console.log(`web viewer e2e: passed in ${((Date.now() - started) / 1000).toFixed(1)} s`);
} catch (error) {
  failed = true;
  console.error(`web viewer e2e: FAILED: ${error.stack ?? error}`);
  if (pages.open[0]) {
    fs.mkdirSync(outDir, { recursive: true });
    await pages.open[0].screenshot({ path: path.join(outDir, "failure.png") }).catch(() => {});
    console.error(`   screenshot ${path.join(outDir, "failure.png")}`);
  }
  console.error("---- browser console ----");
  for (const line of pages.log) console.error(line);
  for (const { name, output } of children) {
    console.error(`---- ${name} (last 3000 characters) ----\n${output.slice(-3000)}`);
  }
} finally {
  await pages.browser?.close().catch(() => {});
  await stopChildren();
}
process.exit(failed ? 1 : 0);
