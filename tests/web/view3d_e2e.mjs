// The web viewer's 3D view (issue 43), end to end in a real browser (Debian's chromium, headless,
// software WebGL through SwiftShader, via playwright-core) against a real ignav-server and
// ignav-web gateway over loopback DDS, on the built-in phantom with its anatomy. What is checked
// is pixels of the rendered canvas (a screenshot, decoded by the browser's own PNG decoder), at
// places this test projects itself from the camera the page reports (a pinhole camera written out
// here, not vtk.js's), and the standard views against anatomy: from the front the patient's left
// is on the screen's right, from the left side posterior is on the right, from above the right.
//
//   load the phantom, its anatomy and the markers' registration; two targets clicked on a slice
//   the 3D view shows the CT (volume rendering), the structures' and feasible volume's surfaces,
//     the two paths; a second page opened afterwards shows the whole scene: how long it took
//   the prostate alone: its colour where the centre of its box projects, in each standard view
//   the targets alone: their colour where they project, ordered on the screen as anatomy says
//   a click on a path selects its target's row (and the slices go to it); on the prostate, its row
//
//   node tests/web/view3d_e2e.mjs --source SRC --build BUILD --out DIR [--chromium PATH] [--domain N]
//
// Screenshots go to --out (01-scene.png, 02-prostate-*.png, 03-selected.png, 04-page.png;
// failure.png).
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import {
  apply,
  appState,
  byTestId,
  check,
  clickLps,
  expectAccepted,
  fmt,
  goTo,
  invertAffine,
  kTimeoutMs,
  openPage,
  rows4,
  runBrowserTest,
  startBrowser,
  step,
  sub,
  testArgs,
  waitText,
} from "./browser_test.mjs";
import { startGateway, startServer } from "./children.mjs";

const { source, build, outDir, appDir, chromium, chromiumPath, domain } = testArgs("view3d_e2e.mjs", 154);

const kJobTimeoutMs = 120000;
const kTargetsRobotMm = [
  [8, 12, -175],
  [-10, 15, -190],
]; // the demo's first two (configs/demo/plan.yaml): reachable
const kHueTolerance = 0.12; // of a unit RGB direction: shading scales a colour, it keeps its hue

// ---- a camera of our own ---------------------------------------------------------------------

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const unit = (a) => a.map((x) => x / Math.hypot(...a));

// Where an LPS point lands in a W x H picture of the camera: a pinhole looking from `position`
// at `focal_point`, `view_up` up, `view_angle_deg` the vertical field of view (or a parallel
// projection `parallel_scale` half-heights high). Pixels from the top left.
function project(camera, p, [W, H]) {
  const forward = unit(sub(camera.focal_point, camera.position));
  const right = unit(cross(forward, camera.view_up));
  const up = cross(right, forward);
  const d = sub(p, camera.position);
  const [x, y, z] = [dot(d, right), dot(d, up), dot(d, forward)];
  const half = camera.parallel ? camera.parallel_scale : z * Math.tan((camera.view_angle_deg * Math.PI) / 360);
  const nx = x / (half * (W / H));
  const ny = y / half;
  return [((nx + 1) / 2) * W, ((1 - ny) / 2) * H];
}

// ---- the 3D view's pixels ------------------------------------------------------------------

const describe = (page) => page.evaluate(() => window.ignav.view3d.describe());

// The 3D canvas as the screen shows it: its box on the page and a reader of its pixels (the
// screenshot's PNG decoded by the page's own image decoder, read through a 2D canvas kept in the
// page: only the pixels asked for come back).
async function canvasPicture(page, file) {
  const canvas = byTestId(page, "view-3d").locator("canvas");
  const png = await canvas.screenshot(file ? { path: file } : {});
  const box = await canvas.boundingBox(); // after the screenshot, which scrolls it into view
  const size = await page.evaluate(async (b64) => {
    const image = new Image();
    image.src = `data:image/png;base64,${b64}`;
    await image.decode();
    const c = document.createElement("canvas");
    c.width = image.width;
    c.height = image.height;
    const ctx = c.getContext("2d", { willReadFrequently: true });
    ctx.drawImage(image, 0, 0);
    window.__testPicture = ctx.getImageData(0, 0, c.width, c.height);
    return [c.width, c.height];
  }, png.toString("base64"));
  return {
    box,
    size,
    at: ([x, y]) =>
      page.evaluate(([x, y]) => {
        const p = window.__testPicture;
        const i = 4 * (Math.round(y) * p.width + Math.round(x));
        return Array.from(p.data.slice(i, i + 3));
      }, [x, y]),
    // The brightest pixel within r of (x, y): a surface's lit side, not an edge's dark one.
    brightestNear: ([x, y], r) =>
      page.evaluate(([x, y, r]) => {
        const p = window.__testPicture;
        let best = [0, 0, 0];
        for (let v = Math.round(y - r); v <= Math.round(y + r); ++v)
          for (let u = Math.round(x - r); u <= Math.round(x + r); ++u) {
            if (u < 0 || v < 0 || u >= p.width || v >= p.height) continue;
            const i = 4 * (v * p.width + u);
            const c = Array.from(p.data.slice(i, i + 3));
            if (c[0] + c[1] + c[2] > best[0] + best[1] + best[2]) best = c;
          }
        return best;
      }, [x, y, r]),
  };
}

// How far a pixel's hue is from a colour's: the distance between their unit RGB directions.
function hueOff(pixel, colour) {
  const n = Math.hypot(...pixel);
  if (n < 30) return Infinity; // black: nothing drawn there
  return Math.hypot(...unit(pixel).map((x, i) => x - unit(colour)[i]));
}

const cssRgb = (css) => [1, 3, 5].map((i) => parseInt(css.slice(i, i + 2), 16));

async function standardView(page, view, name) {
  await byTestId(page, `view3d-${view}`).click();
  await page.waitForFunction((want) => document.querySelector('[data-testid="view-3d"]')?.dataset.view === want, name);
}

async function setChecked(page, testid, on) {
  const box = byTestId(page, testid);
  if ((await box.isChecked()) !== on) await box.click();
}

// Only these layers (and structures) shown; the CT off.
async function showOnly(page, layers, structures = []) {
  await byTestId(page, "view3d-ct").selectOption("off");
  for (const layer of ["structures", "feasible", "isodose", "paths", "needle", "planes"])
    await setChecked(page, `view3d-layer-${layer}`, layers.includes(layer));
  for (const s of (await appState(page)).structures.structures)
    await setChecked(page, `view3d-structure-${s.name}`, structures.includes(s.name));
}

// ---- the test ----------------------------------------------------------------------------------

async function run(pages) {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "ignav_web_view3d_"));
  console.log(`   work folder ${tmp}`);
  fs.mkdirSync(outDir, { recursive: true });
  check(fs.existsSync(path.join(appDir, "app.js")), `${appDir}/app.js is missing: build the app`);

  step("ignav-server and ignav-web");
  const dds = path.join(source, "configs/dds/loopback.xml");
  await startServer({ build, config: path.join(source, "configs/server.yaml"), domain, sessionDir: path.join(tmp, "session"), dds });
  const gateway = await startGateway({ build, domain, dds, port: 0, appDir });
  const url = gateway.match[1];
  await startBrowser(pages, chromium, chromiumPath);
  const page = await openPage(pages, url, "page");

  step("the phantom, its anatomy, the markers' registration, two targets clicked on the axial slice");
  await waitText(page, "phase", /imaging/);
  await expectAccepted(page, "load_volume", () => byTestId(page, "load-phantom").click());
  await waitText(page, "volume-status", /^loaded$/, kJobTimeoutMs);
  await expectAccepted(page, "load_structures", () => byTestId(page, "load-phantom-structures").click());
  await waitText(page, "structures-status", /^loaded: phantom:/, kJobTimeoutMs);
  await expectAccepted(page, "auto_fiducials", () => byTestId(page, "action-auto_fiducials").click());
  await waitText(page, "registration-status", /^registered/, kJobTimeoutMs);
  const robotToLps = invertAffine(rows4((await appState(page)).registration.image_to_robot));
  const targetsLps = kTargetsRobotMm.map((p) => apply(robotToLps, p));
  await byTestId(page, "mode-target").check();
  for (const lps of targetsLps) {
    await goTo(page, lps, [9, -6]);
    await expectAccepted(page, "add_target", () => clickLps(page, lps));
  }
  await page.waitForFunction(
    () => Object.values(window.ignav.state().targets ?? {}).filter((t) => (t.path_lps ?? []).length > 2).length === 2,
    null, { timeout: kTimeoutMs });
  const state = await appState(page);
  const targets = Object.values(state.targets).sort((a, b) => a.id - b.id);
  console.log(`   targets ${targets.map((t) => `T${t.id} at ${fmt(t.lps)}`).join(", ")}`);

  step("the 3D view: the CT, five surfaces (four structures, the feasible volume), two paths");
  await page.waitForFunction(
    () => {
      const d = window.ignav.view3d.describe();
      return d.volume && d.surfaces.length === 5 && d.paths >= 4;
    },
    null, { timeout: kJobTimeoutMs });
  const scene = await describe(page);
  console.log(`   ${scene.status}; surfaces: ${scene.surfaces.map((s) => `${s.kind} ${s.name}`).join(", ")}`);
  check(scene.surfaces.filter((s) => s.kind === "structure").length === 4, "not four structures' surfaces");
  check(scene.surfaces.some((s) => s.kind === "feasible"), "no feasible volume surface");
  await canvasPicture(page, path.join(outDir, "01-scene.png"));

  step("a page opened now: the scene appears (CT and surfaces) — how long it takes");
  {
    const started = Date.now();
    const late = await openPage(pages, url, "late page");
    await late.waitForFunction(() => {
      const d = window.ignav.view3d.describe();
      return d.volume && d.surfaces.length === 5;
    }, null, { timeout: kJobTimeoutMs });
    const elapsed_s = (Date.now() - started) / 1000;
    const { drawn_at_ms: drawn, status } = await describe(late);
    console.log(`   drawn ${(drawn.volume / 1000).toFixed(2)} s (CT) and ${(drawn.surfaces / 1000).toFixed(2)} s (surfaces) after the page was opened; ` +
      `seen here ${elapsed_s.toFixed(2)} s after asking for it (${status})`);
    await late.close();
  }

  // The prostate alone, from each standard view: its colour where its box's centre projects (the
  // surface in front of it), and nothing drawn far outside it.
  const prostate = state.structures.structures.find((s) => s.name === "prostate");
  const prostateCentre = [0, 1, 2].map((i) => (prostate.bounds_lps[i] + prostate.bounds_lps[i + 3]) / 2);
  const prostateRgb = prostate.colour_rgb.map((c) => 255 * c);
  await showOnly(page, ["structures"], ["prostate"]);
  for (const [view, name] of [["A", "anterior"], ["L", "left"], ["S", "superior"], ["P", "posterior"]]) {
    step(`the prostate alone from ${name}: its colour where its centre projects`);
    await standardView(page, view, name);
    const camera = await describe(page);
    const picture = await canvasPicture(page, path.join(outDir, `02-prostate-${name}.png`));
    const at = project(camera, prostateCentre, picture.size);
    const pixel = await picture.brightestNear(at, 3);
    const corner = await picture.at([4, picture.size[1] - 4]); // below the floating controls
    console.log(`   centre ${fmt(prostateCentre)} -> pixel (${at.map((x) => x.toFixed(1))}): rgb ${pixel}; corner ${corner}`);
    check(hueOff(pixel, prostateRgb) < kHueTolerance, `from ${name}: rgb ${pixel} where the prostate projects, its colour is ${prostateRgb.map(Math.round)}`);
    check(Math.hypot(...corner) < 30, `from ${name}: the corner is ${corner}, not the black background`);
  }

  step("the targets alone: their colour where they project, ordered on the screen as anatomy says");
  await showOnly(page, ["paths"]);
  // (view, name, what screen x grows with, what screen y grows with): from the front the patient's
  // left is on the right and superior up; from the left side posterior is on the right; from above
  // the patient's right is on the right and anterior up.
  const orders = [
    ["A", "anterior", (p) => p[0], (p) => -p[2]],
    ["L", "left", (p) => p[1], (p) => -p[2]],
    ["S", "superior", (p) => -p[0], (p) => p[1]],
  ];
  for (const [view, name, screenX, screenY] of orders) {
    await standardView(page, view, name);
    const camera = await describe(page);
    const picture = await canvasPicture(page);
    const at = targets.map((t) => project(camera, t.lps, picture.size));
    for (const [n, t] of targets.entries()) {
      const pixel = await picture.brightestNear(at[n], 2);
      const want = cssRgb(await byTestId(page, `target-status-${t.id}`).evaluate((e) => {
        const [r, g, b] = getComputedStyle(e).color.match(/\d+/g).map(Number);
        return `#${[r, g, b].map((x) => x.toString(16).padStart(2, "0")).join("")}`;
      }));
      console.log(`   from ${name}: T${t.id} -> (${at[n].map((x) => x.toFixed(1))}) rgb ${pixel} (its colour ${want})`);
      check(hueOff(pixel, want) < kHueTolerance, `from ${name}: T${t.id}'s pixel is ${pixel}, its colour ${want}`);
    }
    const [a, b] = targets.map((t) => t.lps);
    const dx = at[1][0] - at[0][0];
    const dy = at[1][1] - at[0][1];
    const wantX = screenX(b) - screenX(a);
    const wantY = screenY(b) - screenY(a);
    console.log(`   from ${name}: T2 - T1 on screen (${dx.toFixed(1)}, ${dy.toFixed(1)}) px; by anatomy the signs of (${wantX.toFixed(1)}, ${wantY.toFixed(1)}) mm`);
    if (Math.abs(wantX) > 2) check(Math.sign(dx) === Math.sign(wantX), `from ${name}: T2 is ${dx > 0 ? "right" : "left"} of T1 on screen, anatomy says otherwise`);
    if (Math.abs(wantY) > 2) check(Math.sign(dy) === Math.sign(wantY), `from ${name}: T2 is ${dy > 0 ? "below" : "above"} T1 on screen, anatomy says otherwise`);
  }

  step("a click on T2's path selects T2's row; the slices go to T2");
  await standardView(page, "A", "anterior");
  {
    const camera = await describe(page);
    const picture = await canvasPicture(page);
    const t2 = targets[1];
    const path_lps = t2.path_lps;
    const mid = path_lps[Math.floor(path_lps.length / 2)];
    const [x, y] = project(camera, mid, picture.size);
    const under = await page.evaluate(([x, y]) => window.ignav.view3d.pickAt(x, y), [picture.box.x + x, picture.box.y + y]);
    console.log(`   under (${x.toFixed(1)}, ${y.toFixed(1)}): ${JSON.stringify(under)}; pixel ${await picture.brightestNear([x, y], 0)}`);
    await page.mouse.click(picture.box.x + x, picture.box.y + y);
    await page.waitForFunction((id) => document.querySelector(`[data-testid="target-row-${id}"]`)?.classList.contains("selected"), t2.id, { timeout: kTimeoutMs });
    const selection = await page.evaluate(() => window.ignav.view3d.selection());
    check(selection?.kind === "target" && selection.id === t2.id, `the selection is ${JSON.stringify(selection)}`);
    check(!(await byTestId(page, `target-row-${targets[0].id}`).evaluate((e) => e.classList.contains("selected"))), "T1's row is selected too");
    const centre = (await byTestId(page, "centre").textContent()).split(",").map(Number);
    console.log(`   clicked (${x.toFixed(1)}, ${y.toFixed(1)}) on T${t2.id}'s path at ${fmt(mid)}; slices centred at ${centre}`);
    check(Math.hypot(...sub(centre, t2.lps)) < 0.1, `the slices are centred at ${centre}, not T${t2.id} ${fmt(t2.lps)}`);
  }

  step("a click on the prostate selects its row");
  await showOnly(page, ["structures"], ["prostate"]);
  {
    const camera = await describe(page);
    const picture = await canvasPicture(page);
    const [x, y] = project(camera, prostateCentre, picture.size);
    const under = await page.evaluate(([x, y]) => window.ignav.view3d.pickAt(x, y), [picture.box.x + x, picture.box.y + y]);
    console.log(`   under (${x.toFixed(1)}, ${y.toFixed(1)}): ${JSON.stringify(under)}; pixel ${await picture.brightestNear([x, y], 0)}`);
    await page.mouse.click(picture.box.x + x, picture.box.y + y);
    await page.waitForFunction(() => document.querySelector('[data-testid="structure-row-prostate"]')?.classList.contains("selected"), null, { timeout: kTimeoutMs });
    check(!(await byTestId(page, `target-row-${targets[1].id}`).evaluate((e) => e.classList.contains("selected"))), "T2 is still selected");
  }

  step("everything shown: the CT as volume rendering, the surfaces, the paths, the planes");
  await byTestId(page, "view3d-ct").selectOption("volume");
  for (const layer of ["structures", "feasible", "paths", "planes", "needle"]) await setChecked(page, `view3d-layer-${layer}`, true);
  for (const s of state.structures.structures) await setChecked(page, `view3d-structure-${s.name}`, true);
  await standardView(page, "A", "anterior");
  await page.evaluate(() => window.ignav.view3d.rotate(-35));
  await canvasPicture(page, path.join(outDir, "03-selected.png"));
  await page.evaluate(() => window.scrollTo(0, 0));
  await page.screenshot({ path: path.join(outDir, "04-page.png") });
}

await runBrowserTest("view3d_e2e", outDir, run);
