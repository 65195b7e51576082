// The patient's structures in the web viewer (issue 41), end to end in a real browser (Debian's
// chromium, headless, via playwright-core) against a real ignav-server and ignav-web gateway over
// loopback DDS, on the built-in phantom with its anatomy. Checked against references the app does
// not compute: the roles and margins of configs/sites/prostate.yaml; the colours, volumes and
// voxels of the Slicer segmentation the server wrote (phantom_anatomy.seg.nrrd, read here with
// node's zlib); the Slicer markups files of the session (robot_placement.mrk.json,
// proposed_targets.mrk.json); and the slice's own pixel_to_lps for what is drawn where.
//
//   load the phantom and its anatomy: a row per structure in its colour, roles and margins as the
//     site gives them, volumes as the segmentation's voxels; the urethra's outline in its colour
//     on the axial slice; a margin changed from its row
//   place the robot (prostate, from superior): progress, the poses as the markups file has them,
//     the proposed skin entry drawn where the slice puts it; registered, the mounted robot measured
//   plan seeds at 0.7 U: progress, then as many proposals as the plan's message says (issue 42)
//   propose targets at 8 mm: every proposal as the markups file has it and inside the prostate's
//     voxels, drawn on its slice; one accepted, then all; their dose as seeds (Dose): its metrics
//     in the page as the state has them
//   a target clicked where the demo's needle crosses the urethra: its clearance cell names the
//     urethra, too close; lock_plan refuses it; overridden with a reason, the plan locks
//
//   node tests/web/structures_e2e.mjs --source SRC --build BUILD --out DIR [--chromium PATH] [--domain N]
//
// Screenshots go to --out (01-structures.png ... 04-overridden.png; failure.png).
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import zlib from "node:zlib";
import {
  apply,
  appState,
  byTestId,
  check,
  clickLps,
  dist,
  expectAccepted,
  fmt,
  goTo,
  invert3,
  invertAffine,
  kTimeoutMs,
  openPage,
  replyTo,
  rows4,
  runBrowserTest,
  sleep,
  slicePixel,
  startBrowser,
  step,
  sub,
  testArgs,
  waitText,
} from "./browser_test.mjs";
import { startGateway, startServer } from "./children.mjs";

const { source, build, outDir, appDir, chromium, chromiumPath, domain } = testArgs("structures_e2e.mjs", 152);

const kJobTimeoutMs = 120000; // a placement search takes seconds; more beside busy loops
const kUrethralRobotMm = [22, 0, -180]; // the demo's target whose stylet crosses the urethra
const kColourTolerance = 40; // of 255 per channel, against what the PNG's scaling blends
const kProposalSpacingMm = 8;

// ---- references the app does not compute ----------------------------------------------------

// configs/sites/prostate.yaml's structures: { name: { role, margin_mm } } (its flow-style lines).
function siteRoles(file) {
  const roles = {};
  for (const line of fs.readFileSync(file, "utf8").split("\n")) {
    const name = line.match(/^\s*- \{name: ([^,}]+)/);
    if (!name) continue;
    const margin = line.match(/margin_mm: ([0-9.]+)/);
    roles[name[1].trim()] = { role: line.match(/role: (\w+)/)[1], margin_mm: margin ? Number(margin[1]) : 0 };
  }
  return roles;
}

// A 3D Slicer segmentation (.seg.nrrd, gzip, unsigned char, 3D or 4D with the layers first): its
// segments (name, colour 0-1, layer, label), the voxel grid and the voxels.
function readSegNrrd(file) {
  const bytes = fs.readFileSync(file);
  const end = bytes.indexOf("\n\n");
  check(end > 0, `${file}: no NRRD header`);
  const header = bytes.subarray(0, end).toString("latin1").split("\n");
  // "name: value" fields and "name:=value" key/value pairs
  const field = (name) => header.find((l) => l.startsWith(`${name}: `))?.slice(name.length + 1).trim();
  const pair = (name) => header.find((l) => l.startsWith(`${name}:=`))?.slice(name.length + 2).trim();
  check(field("type") === "unsigned char" && field("encoding") === "gzip", `${file}: not gzip unsigned char`);
  const sizes = field("sizes").split(/\s+/).map(Number);
  const vectors = [...field("space directions").matchAll(/\(([^)]+)\)/g)].map((m) => m[1].split(",").map(Number));
  const origin = field("space origin").match(/\(([^)]+)\)/)[1].split(",").map(Number);
  const layers = sizes.length === 4 ? sizes[0] : 1;
  const dims = sizes.slice(-3);
  const segments = [];
  for (let n = 0; pair(`Segment${n}_Name`) !== undefined; ++n) {
    segments.push({
      name: pair(`Segment${n}_Name`),
      colour: pair(`Segment${n}_Color`).split(/\s+/).map(Number),
      layer: Number(pair(`Segment${n}_Layer`) ?? 0),
      label: Number(pair(`Segment${n}_LabelValue`)),
    });
  }
  const voxels = zlib.gunzipSync(bytes.subarray(end + 2));
  check(voxels.length === layers * dims[0] * dims[1] * dims[2], `${file}: ${voxels.length} bytes for ${sizes}`);
  // LPS = origin + D·(i, j, k), D's columns the space directions.
  const D = [0, 1, 2].map((r) => vectors.map((v) => v[r]));
  const { inverse, det } = invert3(D);
  const at = (segment, [i, j, k]) => voxels[segment.layer + layers * (i + dims[0] * (j + dims[1] * k))];
  return {
    segments,
    voxelCm3: Math.abs(det) / 1000,
    count(segment) {
      let n = 0;
      for (let v = segment.layer; v < voxels.length; v += layers) if (voxels[v] === segment.label) ++n;
      return n;
    },
    // The nearest voxel's verdict (as the server clips its proposals); outside the grid: false.
    contains(segment, lps) {
      const d = sub(lps, origin);
      const ijk = inverse.map((row) => Math.round(row[0] * d[0] + row[1] * d[1] + row[2] * d[2]));
      if (ijk.some((x, a) => x < 0 || x >= dims[a])) return false;
      return at(segment, ijk) === segment.label;
    },
    centroid(segment) {
      const sum = [0, 0, 0];
      let n = 0;
      for (let k = 0; k < dims[2]; ++k)
        for (let j = 0; j < dims[1]; ++j)
          for (let i = 0; i < dims[0]; ++i) {
            if (at(segment, [i, j, k]) !== segment.label) continue;
            for (let r = 0; r < 3; ++r) sum[r] += origin[r] + D[r][0] * i + D[r][1] * j + D[r][2] * k;
            ++n;
          }
      return sum.map((x) => x / n);
    },
  };
}

// A Slicer markups file's control points: [{ label, position (LPS) }].
function markups(file) {
  const json = JSON.parse(fs.readFileSync(file, "utf8"));
  const markup = json.markups[0];
  check(markup.coordinateSystem === "LPS", `${file}: ${markup.coordinateSystem}, not LPS`);
  return markup.controlPoints.map((p) => ({ label: p.label, position: p.position }));
}

// The session's exports are written by the server's reports thread after the state is published.
async function waitForFile(file) {
  for (let tries = 0; !fs.existsSync(file) && tries < 100; ++tries) await sleep(100);
  check(fs.existsSync(file), `${file} was not written within 10 s`);
  return file;
}

// The markups file once it holds `count` points (the reports thread rewrites it per proposal).
async function waitForMarkups(file, count) {
  let points = [];
  for (let tries = 0; tries < 100; ++tries) {
    try {
      points = markups(file);
      if (points.length === count) return points;
    } catch {
      // not there yet, or being written
    }
    await sleep(100);
  }
  check(false, `${file} holds ${points.length} points, not ${count}, after 10 s`);
}

const parseLps = (text) => text.split(",").map(Number);
// A point the page shows to 0.1 mm (formatLps) is this exact point.
const shownAs = (shown, exact) => shown.length === 3 && shown.every((x, i) => Math.abs(x - exact[i]) <= 0.05 + 1e-6);
const rgb255 = (colour) => colour.map((x) => Math.round(255 * x));

// Pixels of the axial canvas within `radius_px` of (u, v) (from `from_px`; below v only when
// `below`) whose colour is within the tolerance of `rgb` (0-255).
function pixelsNear(page, [u, v], radius_px, rgb, { from_px = 0, below = false } = {}) {
  return page.locator('canvas[data-view="axial"]').evaluate(
    (canvas, [u, v, radius, from, below, rgb, tolerance]) => {
      const ctx = canvas.getContext("2d");
      const image = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
      let n = 0;
      for (let y = Math.floor(below ? v + 1 : v - radius); y <= Math.ceil(v + radius); ++y)
        for (let x = Math.floor(u - radius); x <= Math.ceil(u + radius); ++x) {
          const r = Math.hypot(x - u, y - v);
          if (r > radius || r < from || x < 0 || y < 0 || x >= canvas.width || y >= canvas.height) continue;
          const o = 4 * (y * canvas.width + x);
          if ([0, 1, 2].every((c) => Math.abs(image[o + c] - rgb[c]) <= tolerance)) ++n;
        }
      return n;
    },
    [u, v, radius_px, from_px, below, rgb, kColourTolerance],
  );
}

// Waits until the axial view shows a slice drawn after `count` slices.
async function waitAxialRedrawn(page, count) {
  await page.waitForFunction(
    (n) => Number(document.querySelector('canvas[data-view="axial"]').dataset.slicesShown) > n,
    count,
    { timeout: kTimeoutMs },
  );
}
const axialShown = (page) =>
  page.locator('canvas[data-view="axial"]').evaluate((c) => Number(c.dataset.slicesShown ?? 0));

// ---- the test ---------------------------------------------------------------------------------

async function run(pages) {
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "ignav_web_structures_"));
  console.log(`   work folder ${tmp}`);
  fs.mkdirSync(outDir, { recursive: true });
  const shot = async (page, name) => {
    await page.evaluate(() => window.scrollTo(0, 0)); // the slices, whatever a click scrolled to
    await page.screenshot({ path: path.join(outDir, name) });
    console.log(`   screenshot ${path.join(outDir, name)}`);
  };
  check(fs.existsSync(path.join(appDir, "app.js")), `${appDir}/app.js is missing: build the app`);

  step("ignav-server (configs/server.yaml: the prostate site) and ignav-web");
  const dds = path.join(source, "configs/dds/loopback.xml");
  const sessionDir = path.join(tmp, "session");
  await startServer({ build, config: path.join(source, "configs/server.yaml"), domain, sessionDir, dds });
  const gateway = await startGateway({ build, domain, dds, port: 0, appDir });
  const url = gateway.match[1];
  await startBrowser(pages, chromium, chromiumPath);
  const page = await openPage(pages, url, "page");

  step("load the built-in phantom, then its anatomy");
  await waitText(page, "phase", /imaging/);
  await expectAccepted(page, "load_volume", () => byTestId(page, "load-phantom").click());
  await waitText(page, "volume-status", /^loaded$/, kJobTimeoutMs);
  await expectAccepted(page, "load_structures", () => byTestId(page, "load-phantom-structures").click());
  await waitText(page, "structures-status", /^loaded: phantom: \(site: prostate brachytherapy\)/, kJobTimeoutMs);
  const session = (await appState(page)).health.session_dir;
  const seg = readSegNrrd(path.join(session, "phantom_anatomy.seg.nrrd"));
  const site = siteRoles(path.join(source, "configs/sites/prostate.yaml"));
  check(seg.segments.length === 4, `the phantom's segmentation has ${seg.segments.length} segments, not 4`);
  for (const segment of seg.segments) {
    const name = segment.name;
    const row = byTestId(page, `structure-row-${name}`);
    const swatch = await row.locator(".swatch").evaluate((e) => getComputedStyle(e).backgroundColor);
    check(swatch === `rgb(${rgb255(segment.colour).join(", ")})`, `${name}'s swatch is ${swatch}, the file says ${segment.colour}`);
    const role = await byTestId(page, `structure-role-${name}`).inputValue();
    const margin = Number(await byTestId(page, `structure-margin-${name}`).inputValue());
    check(site[name] && role === site[name].role, `${name}: role ${role}, the site file says ${site[name]?.role}`);
    check(margin === site[name].margin_mm, `${name}: margin ${margin} mm, the site file says ${site[name].margin_mm}`);
    const shown = parseFloat(await byTestId(page, `structure-volume-${name}`).textContent());
    const voxels_cm3 = seg.count(segment) * seg.voxelCm3;
    check(Math.abs(shown - voxels_cm3) <= 0.051, `${name}: ${shown} cm³ shown, the segmentation's voxels ${voxels_cm3.toFixed(3)}`);
    const what = `${role}${role === "avoid" ? ` ${margin} mm` : ""}`;
    console.log(`   ${name}: ${what}, ${shown} cm³ (voxels: ${voxels_cm3.toFixed(3)}), ${swatch}`);
  }

  step("the urethra's outline in its colour around its voxels on the axial slice");
  const urethra = seg.segments.find((s) => s.name === "urethra");
  const urethraCentre = seg.centroid(urethra);
  {
    const before = await axialShown(page);
    await goTo(page, urethraCentre, [20, 0]); // the crosshair away from the outline
    await waitAxialRedrawn(page, before);
    const { u, v, slice } = await slicePixel(page, urethraCentre);
    const pixel_mm = Math.hypot(...slice.axis(0));
    const colour = rgb255(urethra.colour);
    // Its section is about 3 mm in radius (an ellipse on this oblique grid): the outline within 6 mm,
    // none of its colour from 12 to 20 mm below it (the prostate, the rectum and the arch are other
    // colours; its name is written above it).
    const near = await pixelsNear(page, [u, v], 6 / pixel_mm, colour);
    const far = await pixelsNear(page, [u, v], 20 / pixel_mm, colour, { from_px: 12 / pixel_mm, below: true });
    console.log(`   ${near} pixels of the urethra's colour within 6 mm of its centroid, ${far} from 12 to 20 mm below`);
    check(near >= 10 && far === 0, `the urethra's outline: ${near} pixels near its centroid, ${far} far from it`);
  }
  await shot(page, "01-structures.png");

  step("a margin changed from its row: pubic_arch avoid 4 mm");
  await byTestId(page, "structure-margin-pubic_arch").fill("4");
  await expectAccepted(page, "structure_role", () => byTestId(page, "structure-set-pubic_arch").click());
  await page.waitForFunction(
    () => window.ignav.state().structures?.structures.find((s) => s.name === "pubic_arch")?.margin_mm === 4,
    null, { timeout: kTimeoutMs });
  check(Number(await byTestId(page, "structure-margin-pubic_arch").inputValue()) === 4, "the row does not show 4 mm");

  step("place the robot for the prostate, from superior; progress; the poses as robot_placement.mrk.json has them");
  await byTestId(page, "placement-structure").selectOption("prostate");
  await byTestId(page, "placement-side").selectOption("superior");
  await expectAccepted(page, "place_robot", () => byTestId(page, "action-place_robot").click());
  const placing = await waitText(page, "placement-status", /^(placing|placed)/, kJobTimeoutMs);
  console.log(`   ${placing.slice(0, 120)}`);
  await waitText(page, "placement-status", /^placed: /, kJobTimeoutMs);
  check(await byTestId(page, "placement-progress").isHidden(), "the progress bar stays after the placement");
  const poses = (await appState(page)).structures.placements;
  const placementFile = path.join(session, "robot_placement.mrk.json");
  const entries = markups(await waitForFile(placementFile));
  check(entries.length === poses.length && poses.length >= 1, `${poses.length} poses, ${entries.length} in ${placementFile}`);
  for (let n = 0; n < entries.length; ++n) {
    const shown = parseLps(await byTestId(page, `placement-entry-${n}`).textContent());
    const coverage = parseFloat(await byTestId(page, `placement-coverage-${n}`).textContent());
    check(shownAs(shown, entries[n].position), `pose ${n}: entry ${fmt(shown)} shown, ${fmt(entries[n].position)} in the file`);
    check(entries[n].label.includes(`${coverage.toFixed(1)} %`), `pose ${n}: ${coverage} % shown, "${entries[n].label}" in the file`);
    console.log(`   ${n === 0 ? "proposed" : `alternative ${n}`}: ${coverage} %, entry ${fmt(shown)}`);
  }

  step("the proposed skin entry drawn where the axial slice puts it (a row's click goes there)");
  {
    const before = await axialShown(page);
    await byTestId(page, "placement-row-0").click();
    await waitAxialRedrawn(page, before);
    const entry = entries[0].position;
    const drawn = JSON.parse(await page.locator('canvas[data-view="axial"]').getAttribute("data-placement-entry"));
    const { u, v } = await slicePixel(page, entry);
    check(drawn.on_plane && Math.hypot(drawn.u - u, drawn.v - v) < 0.01,
      `the entry drawn at (${drawn.u}, ${drawn.v}), on the plane ${drawn.on_plane}; it is at (${u}, ${v})`);
  }
  await shot(page, "02-placed.png");

  step("register (auto-detect fiducials): the mounted robot is measured against the proposal");
  await expectAccepted(page, "auto_fiducials", () => byTestId(page, "action-auto_fiducials").click());
  await waitText(page, "registration-status", /^registered/, kJobTimeoutMs);
  const mounted = await waitText(page, "mounted", /^the mounted robot: .*covers/, kJobTimeoutMs);
  console.log(`   ${mounted}`);

  step("plan seeds for the prostate at 0.7 U (the site's prescription): progress, then the seeds as proposals");
  await byTestId(page, "proposal-structure").selectOption("prostate");
  await byTestId(page, "seed-strength").fill("0.7");
  await expectAccepted(page, "plan_seeds", () => byTestId(page, "action-plan_seeds").click());
  // The plan takes seconds: its progress reaches the page while it runs.
  await page.waitForFunction(() => (window.ignav.state().structures?.proposal_progress_total ?? 0) > 0, null, {
    timeout: kJobTimeoutMs,
  });
  const seeded = await waitText(page, "proposal-status", /^proposed: seed plan: \d+ seeds of oncura_6711 at 0\.7 U for 145 Gy/, kJobTimeoutMs);
  const seeds = Number(seeded.match(/seed plan: (\d+) seeds/)[1]);
  const seedRows = await page.locator('[data-testid^="proposal-row-"]').count();
  check(seeds > 20 && (await appState(page)).structures.proposed.length === seeds && seedRows === seeds,
    `${seeds} seeds said, ${seedRows} rows`);
  console.log(`   ${seeded.slice(0, 160)}…`);
  // Exported for Slicer as any proposal is; removed so the next proposal's file is its own.
  const seedFile = path.join((await appState(page)).health.session_dir, "proposed_targets.mrk.json");
  await waitForMarkups(seedFile, seeds);
  fs.rmSync(seedFile);

  step(`propose targets filling the prostate at ${kProposalSpacingMm} mm: as proposed_targets.mrk.json, inside its voxels`);
  await byTestId(page, "proposal-spacing").fill(String(kProposalSpacingMm));
  await expectAccepted(page, "propose_targets", () => byTestId(page, "action-propose_targets").click());
  // Its own outcome, not the seed plan's before it.
  await waitText(page, "proposal-status", /^proposed: \d+ targets proposed:/, kJobTimeoutMs);
  const proposed = (await appState(page)).structures.proposed;
  const proposalFile = path.join(session, "proposed_targets.mrk.json");
  const file = markups(await waitForFile(proposalFile));
  check(proposed.length > 0 && file.length === proposed.length, `${proposed.length} proposed, ${file.length} in the file`);
  const prostate = seg.segments.find((s) => s.name === "prostate");
  for (let n = 0; n < file.length; ++n) {
    const id = Number(file[n].label.slice(1));
    const shown = parseLps(await byTestId(page, `proposal-lps-${id}`).textContent());
    check(shownAs(shown, file[n].position), `P${id}: ${fmt(shown)} shown, ${fmt(file[n].position)} in the file`);
    check(seg.contains(prostate, file[n].position), `P${id} at ${fmt(file[n].position)} is not in the prostate's voxels`);
  }
  console.log(`   ${file.length} proposals, each shown as in the file and inside the prostate's voxels`);
  {
    // The first proposal on its slice: the ring drawn around it in the proposals' colour.
    const first = file[0].position;
    const before = await axialShown(page);
    await byTestId(page, `proposal-row-${Number(file[0].label.slice(1))}`).click();
    await waitAxialRedrawn(page, before);
    const { u, v } = await slicePixel(page, first);
    const ring = await pixelsNear(page, [u, v], 9, [0xce, 0x93, 0xd8], { from_px: 5 });
    check(ring >= 8, `${ring} pixels of the proposals' colour around ${file[0].label}`);
  }
  await shot(page, "03-proposed.png");

  step("accept one proposal, then all: each a target where it was proposed, every clearance kept");
  const firstId = proposed[0].id;
  await expectAccepted(page, "accept_proposals", () => byTestId(page, `proposal-accept-${firstId}`).click());
  await page.waitForFunction((n) => Object.keys(window.ignav.state().targets ?? {}).length === n, 1, { timeout: kTimeoutMs });
  await expectAccepted(page, "accept_proposals", () => byTestId(page, "accept-all-proposals").click());
  await page.waitForFunction((n) => Object.keys(window.ignav.state().targets ?? {}).length === n, proposed.length, {
    timeout: kTimeoutMs,
  });
  const targets = Object.values((await appState(page)).targets);
  for (const p of file) {
    const t = targets.find((x) => dist(x.lps, p.position) < 1e-6);
    check(t, `no target at ${p.label} (${fmt(p.position)})`);
    const cell = byTestId(page, `target-clearance-${t.id}`);
    await cell.waitFor({ timeout: kTimeoutMs });
    const className = await cell.getAttribute("class");
    check(!className.includes("warning"), `T${t.id} (${p.label}) is shown too close: ${await cell.textContent()}`);
  }

  step("those targets' dose as seeds of 0.7 U (Dose): computed on the server, its metrics in the page");
  await expectAccepted(page, "compute_dose", () => byTestId(page, "action-compute_dose").click());
  const dosed = await waitText(page, "dose-status", /^computed: dose of oncura_6711 at 0\.7 U for 145 Gy to 'prostate'/, kJobTimeoutMs);
  const planned = (await appState(page)).structures.dose.find((d) => d.structure === "prostate" && d.which === "planned");
  const metrics = await byTestId(page, "dose-metrics-prostate-planned").textContent();
  check(planned && metrics.includes(`D90 ${planned.d90_percent.toFixed(1)} %`) &&
    metrics.includes(`V100 ${(100 * planned.v100).toFixed(1)} %`), `the page shows "${metrics}"`);
  console.log(`   ${dosed.slice(0, 160)}…`);

  step(`a target clicked where the demo's needle crosses the urethra (robot ${fmt(kUrethralRobotMm)} mm)`);
  const registration = (await appState(page)).registration;
  const robotToImage = invertAffine(rows4(registration.image_to_robot));
  const urethralLps = apply(robotToImage, kUrethralRobotMm);
  await byTestId(page, "mode-target").check();
  await goTo(page, urethralLps, [15, 10]);
  const added = await replyTo(page, () => clickLps(page, urethralLps));
  check(/^add_target: accepted \(target \d+\)/.test(added), `the click was not a target: "${added}"`);
  const urethralId = Number(added.match(/target (\d+)/)[1]);
  const cell = await waitText(page, `target-clearance-${urethralId}`, /^urethra .*: too close$/);
  check((await byTestId(page, `target-clearance-${urethralId}`).getAttribute("class")).includes("warning"), "not shown as a warning");
  const status = await byTestId(page, `target-status-${urethralId}`).textContent();
  const reach = await byTestId(page, `target-reach-${urethralId}`).textContent();
  check(status === "too close", `T${urethralId} shows "${status}": ${reach}`);
  console.log(`   T${urethralId} at ${fmt(urethralLps)}: ${cell}`);
  const refused = await replyTo(page, () => byTestId(page, "action-lock_plan").click());
  check(/^lock_plan: rejected: too_close:/.test(refused) && refused.includes(`target ${urethralId}`) &&
    refused.includes("urethra"),
    `lock_plan: "${refused}"`);
  await shot(page, "04-too-close.png");

  step("overridden with a reason from the page, the plan locks");
  const empty = await replyTo(page, () => byTestId(page, `target-override-${urethralId}`).click());
  check(/^override_clearance: rejected: .*why its path may pass so close/.test(empty), `an override without a reason: "${empty}"`);
  const reason = "urethral catheter in place; the tip stops short of it";
  await byTestId(page, "override-reason").fill(reason);
  await expectAccepted(page, "override_clearance", () => byTestId(page, `target-override-${urethralId}`).click());
  await waitText(page, `target-clearance-${urethralId}`, /^urethra .*\(overridden\)$/);
  const title = await byTestId(page, `target-clearance-${urethralId}`).getAttribute("title");
  check(title.includes(`overridden (${reason})`), `the cell's tooltip does not carry the reason: ${title}`);
  await expectAccepted(page, "lock_plan", () => byTestId(page, "action-lock_plan").click());
  await waitText(page, "phase", /^(plan_locked|awaiting_approval)$/);
  await shot(page, "05-overridden.png");
}

await runBrowserTest("web structures e2e", outDir, run);
