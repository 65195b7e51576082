// What the browser tests share (viewer_e2e.mjs, structures_e2e.mjs): their arguments, steps and
// checks, the linear algebra of the ground truth (independent of the app's own geometry), page
// helpers (a testid's text, the reply line, where an LPS point is on the axial canvas), a page
// opened on the gateway, and the run itself: on failure a screenshot, the browser's console and
// the processes' output; every process stopped however it ends.
import fs from "node:fs";
import path from "node:path";
import { createRequire } from "node:module";
import { parseArgs } from "node:util";
import { children, stopChildren } from "./children.mjs";

export const kTimeoutMs = 15000;

// --source SRC --build BUILD --out DIR [--chromium PATH] [--domain N] [--app-dir DIR]
export function testArgs(usage, defaultDomain) {
  const { values: args } = parseArgs({
    options: {
      source: { type: "string" },
      build: { type: "string" },
      out: { type: "string" },
      chromium: { type: "string", default: "/usr/bin/chromium" },
      domain: { type: "string", default: String(defaultDomain) },
      "app-dir": { type: "string" },
    },
  });
  if (!args.source || !args.build || !args.out) {
    console.error(`usage: ${usage} --source SRC --build BUILD --out DIR [--chromium PATH] [--domain N]`);
    process.exit(2);
  }
  const source = path.resolve(args.source);
  const build = path.resolve(args.build);
  return {
    source,
    build,
    outDir: path.resolve(args.out),
    appDir: path.resolve(args["app-dir"] ?? path.join(build, "tools/ignav-web/app")),
    chromiumPath: args.chromium,
    domain: args.domain,
    // playwright-core as the app's lock file pins it
    chromium: createRequire(path.join(source, "tools/ignav-web/app/package.json"))("playwright-core").chromium,
  };
}

const started = Date.now();
let stepNumber = 0;
export function step(text) {
  console.log(`[${((Date.now() - started) / 1000).toFixed(1)} s] ${++stepNumber}. ${text}`);
}
export function check(condition, message) {
  if (!condition) throw new Error(message);
}

// ---- linear algebra for the ground truth (independent of the app's own geometry) -----------

export const sub = (a, b) => a.map((x, i) => x - b[i]);
const dot = (a, b) => a.reduce((s, x, i) => s + x * b[i], 0);
export const dist = (a, b) => Math.hypot(...sub(a, b));
export const apply = (m, p) => [0, 1, 2].map((r) => m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3]);
export const rows4 = (flat) => [0, 1, 2, 3].map((r) => flat.slice(4 * r, 4 * r + 4));
// The inverse of a rigid transform [R t]: [Rᵀ, -Rᵀt].
export function invertRigid(m) {
  const rt = [0, 1, 2].map((r) => [0, 1, 2].map((c) => m[c][r]));
  const t = [m[0][3], m[1][3], m[2][3]];
  return [...rt.map((row) => [...row, -dot(row, t)]), [0, 0, 0, 1]];
}
// The inverse of a 3x3 matrix (rows) by its cofactors, and its determinant.
export function invert3(a) {
  const minor = (r, c) => {
    const rows = [0, 1, 2].filter((x) => x !== r);
    const cols = [0, 1, 2].filter((x) => x !== c);
    return a[rows[0]][cols[0]] * a[rows[1]][cols[1]] - a[rows[0]][cols[1]] * a[rows[1]][cols[0]];
  };
  const det = a[0][0] * minor(0, 0) - a[0][1] * minor(0, 1) + a[0][2] * minor(0, 2);
  const inverse = [0, 1, 2].map((r) => [0, 1, 2].map((c) => ((r + c) % 2 ? -minor(c, r) : minor(c, r)) / det));
  return { inverse, det };
}

// The inverse of an affine [A t] given by its rows (the registration: a similarity).
export function invertAffine(m) {
  const { inverse } = invert3(m.slice(0, 3).map((row) => row.slice(0, 3)));
  const t = [m[0][3], m[1][3], m[2][3]];
  return inverse.map((row) => [...row, -(row[0] * t[0] + row[1] * t[1] + row[2] * t[2])]);
}

export const fmt = (p) => p.map((x) => x.toFixed(2)).join(", ");

// ---- page helpers -----------------------------------------------------------------------------

export const byTestId = (page, id) => page.locator(`[data-testid="${id}"]`);

export async function waitText(page, testid, pattern, timeout = kTimeoutMs) {
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
export async function replyTo(page, act) {
  const before = Number(await byTestId(page, "last-reply").getAttribute("data-count"));
  await act();
  await page.waitForFunction(
    (n) => Number(document.querySelector('[data-testid="last-reply"]').dataset.count) > n,
    before,
    { timeout: kTimeoutMs },
  );
  return (await byTestId(page, "last-reply").textContent()).trim();
}

export async function expectAccepted(page, what, act) {
  const reply = await replyTo(page, act);
  check(reply.startsWith(`${what}: accepted`), `${what} was not accepted: "${reply}"`);
  console.log(`   reply: ${reply}`);
  return reply;
}

// The axial slice on screen: its pixel_to_lps rows and the canvas' resolution and box.
export async function axialSlice(page) {
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
export async function goTo(page, lps, [du_mm, dv_mm] = [0, 0]) {
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

// Where the LPS point is in the rendered axial slice, in its PNG pixels (pixel centres at
// integers): through the slice's own pixel_to_lps (LPS = M·(u, v, 0, 1)), the point on the plane.
export async function slicePixel(page, lps) {
  const slice = await axialSlice(page);
  const { m, axis, widthPx, heightPx } = slice;
  const d = sub(lps, axis(3));
  // The slice's axes are orthogonal: project onto each.
  const u = dot(d, axis(0)) / dot(axis(0), axis(0));
  const v = dot(d, axis(1)) / dot(axis(1), axis(1));
  const offPlane = dist(apply(m, [u, v, 0]), lps);
  check(offPlane < 1e-6, `the axial slice does not pass through ${fmt(lps)} (off by ${offPlane} mm)`);
  check(u >= 0 && v >= 0 && u < widthPx && v < heightPx, `${fmt(lps)} is outside the axial view`);
  return { u, v, slice };
}

// Where the LPS point is on the screen: its slice pixel through the canvas' box.
export async function screenPoint(page, lps) {
  const { u, v, slice } = await slicePixel(page, lps);
  const { widthPx, heightPx, box } = slice;
  return { x: box.x + ((u + 0.5) * box.width) / widthPx, y: box.y + ((v + 0.5) * box.height) / heightPx };
}

export async function clickLps(page, lps) {
  const { x, y } = await screenPoint(page, lps);
  await page.mouse.click(x, y);
}

export async function dragLps(page, from, to) {
  const a = await screenPoint(page, from);
  const b = await screenPoint(page, to);
  await page.mouse.move(a.x, a.y);
  await page.mouse.down();
  await page.mouse.move(b.x, b.y, { steps: 8 });
  await page.mouse.up();
}

export const appState = (page) => page.evaluate(() => window.ignav.state());
export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

// Debian's chromium, headless, through playwright-core; closed by runBrowserTest.
export async function startBrowser(pages, chromium, chromiumPath) {
  step(`chromium (${chromiumPath})`);
  check(fs.existsSync(chromiumPath), `${chromiumPath} is missing (tools/setup.sh installs Debian's chromium)`);
  pages.browser = await chromium.launch({ executablePath: chromiumPath, args: ["--no-sandbox"] });
}

// A new browser context and page on the gateway's URL, its console kept for a failure report,
// once the page says it reaches the server. clockShift_ms: the page's Date.now() is off by this
// much (a browser machine's wrong clock).
export async function openPage(pages, url, name, { clockShift_ms = 0 } = {}) {
  const context = await pages.browser.newContext({ viewport: { width: 1600, height: 1000 } });
  if (clockShift_ms) {
    await context.addInitScript((shift) => {
      const real = Date.now.bind(Date);
      Date.now = () => real() + shift;
    }, clockShift_ms);
  }
  const page = await context.newPage();
  page.on("console", (m) => pages.log.push(`[${name} ${m.type()}] ${m.text()}`));
  page.on("pageerror", (e) => pages.log.push(`[${name} pageerror] ${e.message}`));
  pages.open.push(page);
  await page.goto(url);
  await waitText(page, "connection", /gateway: connected · server: connected/);
  return page;
}

// Runs `run(pages)` and exits: 0 when it passed; on failure 1, with the first page's screenshot,
// the browsers' console and the last of every process's output.
export async function runBrowserTest(name, outDir, run) {
  const pages = { browser: null, open: [], log: [] };
  let failed = false;
  try {
    await run(pages);
    console.log(`${name}: passed in ${((Date.now() - started) / 1000).toFixed(1)} s`);
  } catch (error) {
    failed = true;
    console.error(`${name}: FAILED: ${error.stack ?? error}`);
    if (pages.open[0]) {
      fs.mkdirSync(outDir, { recursive: true });
      await pages.open[0].screenshot({ path: path.join(outDir, "failure.png") }).catch(() => {});
      console.error(`   screenshot ${path.join(outDir, "failure.png")}`);
    }
    console.error("---- browser console ----");
    for (const line of pages.log) console.error(line);
    for (const { name: child, output } of children) {
      console.error(`---- ${child} (last 3000 characters) ----\n${output.slice(-3000)}`);
    }
  } finally {
    await pages.browser?.close().catch(() => {});
    await stopChildren();
  }
  process.exit(failed ? 1 : 0);
}
