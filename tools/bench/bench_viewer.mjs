// The web viewer as a person feels it (issue 26), in headless Chromium against a real
// ignav-server and ignav-web on loopback DDS, on the phantom CT (ignav-plan phantom), registered
// (auto_fiducials) so that every slice carries the feasible region:
//  - scroll -> image: one wheel step on a view, from the wheel event to the new slice drawn on
//    that view's canvas (in the page's own clock), one step at a time with a pause between (a
//    person stepping through slices), for each view; and how many slices the other views showed
//    meanwhile (none is right). Twice: as the viewer runs (a scrolled view fetches its next
//    slice ahead), and with that off, when every step waits for the server's slice;
//  - gateway restart -> page restored: ignav-web killed (SIGKILL), the page showing its banner,
//    then started again on its port; until the page says connected and every view has drawn a
//    new slice. Timed from the new gateway's spawn and from its ready line.
//
//   node tools/bench/bench_viewer.mjs [--build build] [--domain 151] [--rounds 60] [--pause-ms 100]
//        [--restarts 10] [--chromium /usr/bin/chromium] [--dds-config configs/dds/loopback.xml]
//        [--app-dir DIR]   (another bundle of the app, e.g. an older one; --restarts 0 for one
//                           without the banner)
//
// A benchmark, not a test: it prints figures (docs/PERFORMANCE.md) and fails only when the
// viewer does not do the thing at all.
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { createRequire } from "node:module";
import { fileURLToPath } from "node:url";
import { parseArgs } from "node:util";
import { children, kill, startGateway as startGatewayProcess, startServer, stopChildren } from "../../tests/web/children.mjs";

const source = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../..");
const { values: args } = parseArgs({
  options: {
    build: { type: "string", default: path.join(source, "build") },
    domain: { type: "string", default: "151" },
    rounds: { type: "string", default: "60" },
    "pause-ms": { type: "string", default: "100" },
    restarts: { type: "string", default: "10" },
    chromium: { type: "string", default: "/usr/bin/chromium" },
    "dds-config": { type: "string", default: path.join(source, "configs/dds/loopback.xml") },
    "app-dir": { type: "string" },
  },
});
const build = path.resolve(args.build);
const rounds = Number(args.rounds);
const pauseMs = Number(args["pause-ms"]);
const restarts = Number(args.restarts);
const dds = path.resolve(args["dds-config"]);
const { chromium } = createRequire(path.join(source, "tools/ignav-web/app/package.json"))("playwright-core");
const kViews = ["axial", "sagittal", "coronal"];
const kTimeoutMs = 15000;

function check(condition, message) {
  if (!condition) throw new Error(message);
}

// ---- statistics ---------------------------------------------------------------------------------

function summary(values) {
  const sorted = [...values].sort((a, b) => a - b);
  const rank = (q) => sorted[Math.min(sorted.length - 1, Math.ceil(q * sorted.length) - 1)];
  return { n: sorted.length, median: rank(0.5), p95: rank(0.95), max: sorted[sorted.length - 1] };
}
const ms = (x) => `${x.toFixed(1)} ms`.padStart(10);

// ---- the page -------------------------------------------------------------------------------------

const byTestId = (page, id) => page.locator(`[data-testid="${id}"]`);
const slicesShown = (page) =>
  page.evaluate(
    (views) => views.map((v) => Number(document.querySelector(`canvas[data-view="${v}"]`).dataset.slicesShown ?? 0)),
    kViews,
  );

// One wheel step on `view` (dir ±1); resolves with the time to the new slice on its canvas.
function scrollOnce(page, view, dir) {
  return page.evaluate(
    ([view, dir, timeout]) =>
      new Promise((resolve, reject) => {
        const canvas = document.querySelector(`canvas[data-view="${view}"]`);
        const before = Number(canvas.dataset.slicesShown);
        let t0 = 0;
        const observer = new MutationObserver(() => {
          if (Number(canvas.dataset.slicesShown) <= before) return;
          observer.disconnect();
          clearTimeout(timer);
          resolve(performance.now() - t0);
        });
        observer.observe(canvas, { attributes: true, attributeFilter: ["data-slices-shown"] });
        const timer = setTimeout(() => {
          observer.disconnect();
          reject(new Error(`no new ${view} slice within ${timeout} ms of a wheel step`));
        }, timeout);
        const box = canvas.getBoundingClientRect();
        t0 = performance.now();
        canvas.dispatchEvent(
          new WheelEvent("wheel", {
            deltaY: 100 * dir,
            clientX: box.x + box.width / 2,
            clientY: box.y + box.height / 2,
            bubbles: true,
            cancelable: true,
          }),
        );
      }),
    [view, dir, kTimeoutMs],
  );
}

// Resolves (in the page) with Date.now() once the page is connected and every view has drawn a
// slice after `before`.
function watchRestored(page, before) {
  return page.evaluate(
    ([views, before]) => {
      window.__benchRestored = new Promise((resolve) => {
        const done = () =>
          document.querySelector('[data-testid="connection"]').textContent.includes("gateway: connected · server: connected") &&
          views.every((v, i) => Number(document.querySelector(`canvas[data-view="${v}"]`).dataset.slicesShown) > before[i]);
        const poll = () => (done() ? resolve(Date.now()) : setTimeout(poll, 1));
        poll();
      });
    },
    [kViews, before],
  );
}

// ---- the run --------------------------------------------------------------------------------------

async function main() {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "ignav_bench_viewer_"));
  let browser = null;
  try {
    execFileSync(path.join(build, "tools/ignav-plan/ignav-plan"), [
      "phantom",
      path.join(tmp, "ct"),
      "--robot",
      path.join(source, "configs/robots/torabi2014.yaml"),
    ]);
    await startServer({
      build, config: path.join(source, "configs/server.yaml"), domain: args.domain, sessionDir: path.join(tmp, "session"),
      dds,
    });
    const appDir = args["app-dir"] ? path.resolve(args["app-dir"]) : undefined;
    const startGateway = (port) => startGatewayProcess({ build, domain: args.domain, dds, port, appDir });
    let gateway = await startGateway(0);
    const url = gateway.match[1];
    const port = Number(new URL(url).port);

    browser = await chromium.launch({ executablePath: args.chromium, args: ["--no-sandbox"] });
    const page = await (await browser.newContext({ viewport: { width: 1600, height: 1000 } })).newPage();
    await page.goto(url);
    await page.waitForFunction(
      () => document.querySelector('[data-testid="connection"]').textContent.includes("server: connected"),
      null,
      { timeout: kTimeoutMs },
    );
    await byTestId(page, "load-path").fill(path.join(tmp, "ct"));
    await byTestId(page, "load-path-button").click();
    await page.waitForFunction(() => document.querySelectorAll("canvas[data-pixel-to-lps]").length === 3, null, {
      timeout: kTimeoutMs,
    });
    // Registered, every slice carries the feasible region (as in use).
    await byTestId(page, "action-auto_fiducials").click();
    await page.waitForFunction(
      () => /^registered/.test(document.querySelector('[data-testid="registration-status"]')?.textContent ?? ""),
      null,
      { timeout: kTimeoutMs },
    );
    const before = await slicesShown(page);
    await page.waitForFunction(
      ([views, before]) =>
        views.every((v, i) => Number(document.querySelector(`canvas[data-view="${v}"]`).dataset.slicesShown) > before[i]),
      [kViews, before],
      { timeout: kTimeoutMs },
    ).catch(() => {}); // the region's slices, if they were not in already

    console.log(`bench_viewer: ${os.cpus().length} cores (${os.cpus()[0]?.model ?? "?"}), domain ${args.domain}, ` +
      `${new Date().toISOString().slice(0, 10)}`);
    console.log(`scroll -> new image on the scrolled view, ${rounds} single wheel steps per view, ${pauseMs} ms ` +
      "apart (in the page: wheel event -> slice drawn):");
    console.log(`  ${"view".padEnd(28)} ${"median".padStart(10)} ${"p95".padStart(10)} ${"max".padStart(10)}   other views' slices`);
    // An app without the switch (before issue 26) runs as it is.
    const modes = (await page.evaluate(() => typeof window.ignav.setPrefetching)) === "function" ? [true, false] : [null];
    for (const prefetching of modes) {
      if (prefetching !== null) await page.evaluate((on) => window.ignav.setPrefetching(on), prefetching);
      for (const [index, view] of kViews.entries()) {
        const times = [];
        const start = await slicesShown(page);
        for (let i = 0; i < rounds; ++i) {
          // Back and forth in runs of 20 steps, so as to stay inside the volume.
          const dir = Math.floor(i / 20) % 2 === 0 ? 1 : -1;
          times.push(await scrollOnce(page, view, dir));
          await page.waitForTimeout(pauseMs);
        }
        await page.waitForTimeout(300); // anything wrongly asked of the other views arrives
        const end = await slicesShown(page);
        const others = end.reduce((sum, n, i) => sum + (i === index ? 0 : n - start[i]), 0);
        const s = summary(times);
        const label = `${view}${prefetching === false ? " (no fetching ahead)" : ""}`;
        console.log(`  ${label.padEnd(28)} ${ms(s.median)} ${ms(s.p95)} ${ms(s.max)}   ${others}`);
      }
    }
    if (modes[0] !== null) await page.evaluate(() => window.ignav.setPrefetching(true));
    if (restarts === 0) return;

    const fromSpawn = [];
    const fromReady = [];
    for (let r = 0; r < restarts; ++r) {
      await kill(gateway);
      await byTestId(page, "connection-banner").waitFor({ state: "visible", timeout: kTimeoutMs });
      await watchRestored(page, await slicesShown(page));
      const spawned = Date.now();
      gateway = await startGateway(port);
      const ready = Date.now();
      const restored = await page.evaluate(() => window.__benchRestored);
      fromSpawn.push(restored - spawned);
      fromReady.push(restored - ready);
      await page.waitForTimeout(500);
    }
    const a = summary(fromSpawn);
    const b = summary(fromReady);
    console.log(`gateway restart -> page restored (connected, all three views drawn again), ${restarts} restarts:`);
    console.log(`  from the new ignav-web's spawn: median ${ms(a.median)}, p95 ${ms(a.p95)}, max ${ms(a.max)}`);
    console.log(`  from its ready line:            median ${ms(b.median)}, p95 ${ms(b.p95)}, max ${ms(b.max)}`);
  } finally {
    await browser?.close().catch(() => {});
    await stopChildren();
    fs.rmSync(tmp, { recursive: true, force: true });
  }
}

try {
  await main();
} catch (error) {
  console.error(`bench_viewer: ${error.stack ?? error}`);
  for (const { name, output } of children) console.error(`---- ${name} (last 2000 characters) ----\n${output.slice(-2000)}`);
  process.exit(1);
}
