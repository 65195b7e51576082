// Bundles the web viewer into OUTDIR: app.js (src/main.ts and everything it imports), index.html
// and app.css. CMake runs it after `npm ci`; so can a person: `node build.mjs /tmp/webapp`.
import { build } from "esbuild";
import { copyFile, mkdir } from "node:fs/promises";
import path from "node:path";
import { fileURLToPath } from "node:url";

const outDir = process.argv[2];
if (!outDir) {
  console.error("usage: node build.mjs OUTDIR");
  process.exit(2);
}
const here = path.dirname(fileURLToPath(import.meta.url));
await mkdir(outDir, { recursive: true });
await build({
  entryPoints: [path.join(here, "src", "main.ts")],
  outfile: path.join(outDir, "app.js"),
  bundle: true,
  format: "iife",
  target: "es2022",
  // vtk.js makes the bundle large: minified, with the map beside it (a stack trace in the
  // browser still names the .ts line; the map is fetched only by developer tools).
  minify: true,
  sourcemap: "linked",
  logLevel: "warning",
});
for (const file of ["index.html", "app.css"]) {
  await copyFile(path.join(here, file), path.join(outDir, file));
}
console.log(`web viewer bundled into ${outDir}`);
