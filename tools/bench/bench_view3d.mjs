// The web viewer's 3D view as a person feels it (issue 43), in Chromium against a real
// ignav-server and ignav-web on loopback DDS:
//  - open -> scene: a page opened on a session with the phantom CT, its anatomy and the markers'
//    registration, until the CT and the surfaces are first drawn (the page's own clock, from its
//    navigation), for several pages one after another;
//  - frames per second while the scene turns (2 degrees a frame, the CT as volume rendering and
//    every surface shown), on the phantom and on a synthetic CT of --size cubed voxels (a body of
//    soft tissue with bones, written here as NRRD);
//  - the needle following motion: for each MotionState sample during an approved motion, from
//    the server's publication (its uptime, mapped to its wall clock through Health) to the 3D
//    view's frame that draws that needle.
// Headless Chromium renders WebGL in software (SwiftShader) unless --gpu is given, which asks
// Chromium for the machine's GPU (headed, on a display).
//
//   node tools/bench/bench_view3d.mjs [--build build] [--domain 156] [--size 256] [--seconds 5]
//        [--pages 5] [--chromium /usr/bin/chromium] [--gpu]
//
// A benchmark, not a test: it prints figures (docs/PERFORMANCE.md) and fails only when the view
// does not do the thing at all.
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { createRequire } from "node:module";
import { fileURLToPath } from "node:url";
import { parseArgs } from "node:util";
import { children, startGateway, startServer, stopChildren } from "../../tests/web/children.mjs";

const source = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../..");
const { values: args } = parseArgs({
  options: {
    build: { type: "string", default: path.join(source, "build") },
    domain: { type: "string", default: "156" },
    size: { type: "string", default: "256" },
    seconds: { type: "string", default: "5" },
    pages: { type: "string", default: "5" },
    chromium: { type: "string", default: "/usr/bin/chromium" },
    gpu: { type: "boolean", default: false },
  },
});
const build = path.resolve(args.build);
const dds = path.join(source, "configs/dds/loopback.xml");
const { chromium } = createRequire(path.join(source, "tools/ignav-web/app/package.json"))("playwright-core");
const kTimeoutMs = 120000;

function check(condition, message) {
  if (!condition) throw new Error(message);
}

function summary(values) {
  const sorted = [...values].sort((a, b) => a - b);
  const rank = (q) => sorted[Math.min(sorted.length - 1, Math.max(0, Math.ceil(q * sorted.length) - 1))];
  return { n: sorted.length, median: rank(0.5), p95: rank(0.95), max: sorted[sorted.length - 1] };
}
const ms = (x) => `${x.toFixed(1)} ms`;

// A CT of n³ voxels of 1 mm (int16 HU, raw NRRD): air, an elliptic body of soft tissue (40 HU,
// noise ±20), a spine and two femoral heads of bone (700 HU).
function writeSyntheticCt(file, n) {
  const voxels = new Int16Array(n * n * n);
  const c = (n - 1) / 2;
  let seed = 1;
  const noise = () => ((seed = (seed * 1103515245 + 12345) % 2147483648) / 2147483648 - 0.5) * 40;
  for (let k = 0; k < n; ++k)
    for (let j = 0; j < n; ++j)
      for (let i = 0; i < n; ++i) {
        const x = (i - c) / n;
        const y = (j - c) / n;
        const z = (k - c) / n;
        let hu = -1000;
        if ((x / 0.45) ** 2 + (y / 0.33) ** 2 < 1) hu = 40 + noise();
        if (x * x + (y - 0.22) ** 2 < 0.06 ** 2) hu = 700; // spine
        for (const side of [-1, 1]) if ((x - side * 0.25) ** 2 + y ** 2 + (z + 0.1) ** 2 < 0.08 ** 2) hu = 700;
        voxels[i + n * (j + n * k)] = Math.round(hu);
      }
  const header =
    "NRRD0004\ntype: short\ndimension: 3\nspace: left-posterior-superior\n" +
    `sizes: ${n} ${n} ${n}\nspace directions: (1,0,0) (0,1,0) (0,0,1)\nkinds: domain domain domain\n` +
    `endian: little\nencoding: raw\nspace origin: (${-c},${-c},${-c})\n\n`;
  fs.writeFileSync(file, Buffer.concat([Buffer.from(header, "latin1"), Buffer.from(voxels.buffer)]));
}

const byTestId = (page, id) => page.locator(`[data-testid="${id}"]`);
const describe = (page) => page.evaluate(() => window.ignav.view3d.describe());

async function openPage(context, url) {
  const page = await context.newPage();
  await page.goto(url);
  await page.waitForFunction(
    () => document.querySelector('[data-testid="connection"]').textContent.includes("server: connected"),
    null, { timeout: kTimeoutMs });
  return page;
}

async function sceneDrawn(page, surfaces) {
  await page.waitForFunction(
    (surfaces) => {
      const d = window.ignav.view3d.describe();
      return d.drawn_at_ms.volume !== undefined && (surfaces === 0 || d.drawn_at_ms.surfaces !== undefined) && d.surfaces.length >= surfaces;
    },
    surfaces, { timeout: kTimeoutMs });
  return describe(page);
}

// Frames while the scene turns 2 degrees a frame for `seconds`: the intervals between frames.
function turning(page, seconds) {
  return page.evaluate(async (seconds) => {
    const intervals = [];
    const end = performance.now() + seconds * 1000;
    let last = performance.now();
    while (performance.now() < end) {
      window.ignav.view3d.rotate(2);
      await new Promise((resolve) => requestAnimationFrame(resolve));
      const now = performance.now();
      intervals.push(now - last);
      last = now;
    }
    return intervals;
  }, seconds);
}

function printTurning(what, intervals) {
  const s = summary(intervals);
  const total = intervals.reduce((a, b) => a + b, 0);
  console.log(`  ${what.padEnd(44)} ${(1000 * intervals.length / total).toFixed(1).padStart(6)} frames/s ` +
    `(frame median ${ms(s.median)}, p95 ${ms(s.p95)}, ${s.n} frames)`);
}

async function main() {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "ignav_bench_view3d_"));
  let browser = null;
  try {
    await startServer({ build, config: path.join(source, "configs/server.yaml"), domain: args.domain, sessionDir: path.join(tmp, "session"), dds });
    const gateway = await startGateway({ build, domain: args.domain, dds, port: 0 });
    const url = gateway.match[1];
    const launchArgs = ["--no-sandbox", ...(args.gpu ? ["--enable-gpu", "--ignore-gpu-blocklist"] : [])];
    browser = await chromium.launch({ executablePath: args.chromium, args: launchArgs, headless: !args.gpu });
    const context = await browser.newContext({ viewport: { width: 1600, height: 1000 } });
    const page = await openPage(context, url);
    const renderer = await page.evaluate(() => {
      const gl = document.createElement("canvas").getContext("webgl2");
      const info = gl?.getExtension("WEBGL_debug_renderer_info");
      return gl ? gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER) : "no WebGL2";
    });
    console.log(`bench_view3d: ${os.cpus().length} cores (${os.cpus()[0]?.model ?? "?"}), ${new Date().toISOString().slice(0, 10)}; WebGL: ${renderer}`);

    const sendCommand = (kind, points = [], file = "") =>
      page.evaluate(([kind, points, file]) => new Promise((resolve) => {
        const ws = new WebSocket(`ws://${location.host}/ws`);
        ws.onmessage = (e) => {
          const m = JSON.parse(e.data);
          if (m.type === "hello") ws.send(JSON.stringify({ op: "command", seq: 1, kind, points, ids: [], path: file }));
          if (m.type === "reply" || m.type === "error") {
            ws.close();
            resolve(m);
          }
        };
      }), [kind, points, file]);
    console.log(`turning the scene, 2° a frame for ${args.seconds} s, the CT as volume rendering (bone window), every surface shown:`);

    // A large CT first (load_volume is allowed before motion only).
    const size = Number(args.size);
    const file = path.join(tmp, `ct${size}.nrrd`);
    writeSyntheticCt(file, size);
    const started = Date.now();
    check((await sendCommand("load_volume", [], file)).accepted, "load_volume of the synthetic CT refused");
    await page.waitForFunction((size) => /^CT (\d+) ×/.exec(window.ignav.view3d.describe().status)?.[1] === String(size), size, { timeout: kTimeoutMs });
    const large = await describe(page);
    printTurning(`synthetic ${size} × ${size} × ${size} (1 mm)`, await turning(page, Number(args.seconds)));
    const t = large.volume_timings;
    console.log(`  (loaded and first drawn ${((Date.now() - started) / 1000).toFixed(2)} s after load_volume; ${large.status}: ` +
      `its slabs received in ${(t.received_ms / 1000).toFixed(2)} s, decoded by ${(t.decoded_ms / 1000).toFixed(2)} s)`);

    // The phantom, its anatomy, registered.
    check((await sendCommand("load_volume", [], "phantom:")).accepted, "load_volume phantom: refused");
    await page.waitForFunction(() => window.ignav.state().volume?.status === "loaded" && window.ignav.state().volume.source === "phantom:", null, { timeout: kTimeoutMs });
    check((await sendCommand("load_structures", [], "phantom:")).accepted, "load_structures refused");
    await page.waitForFunction(() => window.ignav.state().structures?.status === "loaded", null, { timeout: kTimeoutMs });
    check((await sendCommand("auto_fiducials")).accepted, "auto_fiducials refused");
    await page.waitForFunction(() => window.ignav.state().registration?.status === "registered", null, { timeout: kTimeoutMs });
    await page.waitForFunction(() => window.ignav.view3d.describe().surfaces.length === 5 && /^CT 128/.test(window.ignav.view3d.describe().status), null, { timeout: kTimeoutMs });
    printTurning("phantom 128 × 128 × 112, 4 structures, feasible volume", await turning(page, Number(args.seconds)));

    const opened = [];
    for (let n = 0; n < Number(args.pages); ++n) {
      const late = await openPage(context, url);
      const d = await sceneDrawn(late, 5);
      opened.push(Math.max(d.drawn_at_ms.volume, d.drawn_at_ms.surfaces));
      await late.close();
    }
    const o = summary(opened);
    console.log(`open -> scene drawn (the phantom, its 4 structures, the feasible volume), ${o.n} pages one after another:`);
    console.log(`  median ${ms(o.median)}, max ${ms(o.max)} (from navigation to the CT and the surfaces first drawn)`);

    // An emergency stop while another page loads the scene (the gateway's views thread busy with
    // its CT and surfaces): from the click to the phase shown, and back to planning each time.
    const stops = [];
    for (let n = 0; n < Number(args.pages); ++n) {
      const busy = await context.newPage();
      const loading = busy.goto(url).catch(() => {}); // loads the 3D scene meanwhile
      await page.waitForTimeout(300);
      stops.push(await page.evaluate(() => new Promise((resolve) => {
        const phase = document.querySelector('[data-testid="phase"]');
        const t0 = performance.now();
        const observer = new MutationObserver(() => {
          if (phase.textContent !== "emergency") return;
          observer.disconnect();
          resolve(performance.now() - t0);
        });
        observer.observe(phase, { childList: true, characterData: true, subtree: true });
        document.querySelector('[data-testid="estop-button"]').click();
      })));
      check((await sendCommand("reset_emergency")).accepted, "reset_emergency refused");
      await page.waitForFunction(() => window.ignav.state().workflow?.phase === "stopped", null, { timeout: kTimeoutMs });
      check((await sendCommand("resume")).accepted, "resume refused");
      await page.waitForFunction(() => window.ignav.state().workflow?.phase === "planning", null, { timeout: kTimeoutMs });
      await loading;
      await busy.close();
    }
    const e = summary(stops);
    console.log(`emergency stop: click -> phase "emergency" shown, while another page loads the scene, ${e.n} stops:`);
    console.log(`  median ${ms(e.median)}, max ${ms(e.max)}`);

    // The needle following motion: a target, its plan approved, each MotionState sample timed
    // from its publication (the server's uptime, on its wall clock through Health's pair) to the
    // 3D view's next frame after the page holds it.
    await page.evaluate(() => {
      window.__needleDrawn = [];
      let lastKey = "";
      const watch = () => {
        const s = window.ignav.state();
        const needle = s.motion?.needle_lps ?? [];
        const key = JSON.stringify(needle);
        if (key !== lastKey && needle.length > 0 && s.health) {
          lastKey = key;
          const published_s = s.health.server_time_unix_s - s.health.uptime_s + s.motion.uptime_s;
          const frames = window.ignav.view3d.describe().frames;
          const wait = () => {
            if (window.ignav.view3d.describe().frames > frames) window.__needleDrawn.push(Date.now() - 1000 * published_s);
            else requestAnimationFrame(wait);
          };
          requestAnimationFrame(wait);
        }
        setTimeout(watch, 1);
      };
      watch();
    });
    const targetLps = await page.evaluate(() => {
      // The demo's first target, robot (8, 12, -175) mm, in LPS: m · p = q solved by Cramer's rule.
      const m = window.ignav.state().registration.image_to_robot;
      const a = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]];
      const q = [8 - m[3], 12 - m[7], -175 - m[11]];
      const det = (x) => x[0][0] * (x[1][1] * x[2][2] - x[1][2] * x[2][1]) - x[0][1] * (x[1][0] * x[2][2] - x[1][2] * x[2][0]) + x[0][2] * (x[1][0] * x[2][1] - x[1][1] * x[2][0]);
      return [0, 1, 2].map((c) => det(a.map((row, r) => row.map((v, k) => (k === c ? q[r] : v)))) / det(a));
    });
    for (const [kind, points] of [["add_target", [targetLps]], ["lock_plan", []], ["request_approval", []]]) {
      const r = await sendCommand(kind, points);
      check(r.accepted, `${kind}: ${r.message}`);
    }
    await byTestId(page, "approve-button").waitFor({ state: "visible", timeout: kTimeoutMs });
    await byTestId(page, "approve-button").click();
    await page.waitForFunction(() => window.ignav.state().workflow?.phase === "at_target", null, { timeout: kTimeoutMs });
    await page.waitForTimeout(500);
    const n = summary(await page.evaluate(() => window.__needleDrawn));
    console.log(`the needle following motion: MotionState published -> the 3D frame after it, ${n.n} samples:`);
    console.log(`  median ${ms(n.median)}, p95 ${ms(n.p95)}, max ${ms(n.max)}`);
  } finally {
    await browser?.close().catch(() => {});
    await stopChildren();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
}

try {
  await main();
} catch (error) {
  console.error(`bench_view3d: ${error.stack ?? error}`);
  for (const { name, output } of children) console.error(`---- ${name} (last 2000 characters) ----\n${output.slice(-2000)}`);
  process.exit(1);
}
