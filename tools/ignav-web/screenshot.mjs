// A picture of the web viewer as a browser shows it now (the demo leaves one in the session
// folder): Debian's chromium, headless, through playwright-core from the app's own packages.
//   node tools/ignav-web/screenshot.mjs --url URL --out FILE.png [--chromium PATH]
import { createRequire } from "node:module";
import { parseArgs } from "node:util";
import path from "node:path";
import { fileURLToPath } from "node:url";

const { values: args } = parseArgs({
  options: {
    url: { type: "string" },
    out: { type: "string" },
    chromium: { type: "string", default: "/usr/bin/chromium" },
  },
});
if (!args.url || !args.out) {
  console.error("usage: screenshot.mjs --url URL --out FILE.png [--chromium PATH]");
  process.exit(2);
}
const appDir = path.join(path.dirname(fileURLToPath(import.meta.url)), "app");
const { chromium } = createRequire(path.join(appDir, "package.json"))("playwright-core");

const browser = await chromium.launch({ executablePath: args.chromium, args: ["--no-sandbox"] });
try {
  const page = await browser.newPage({ viewport: { width: 1600, height: 1000 } });
  await page.goto(args.url);
  // Drawn: the phase is known and every view holds a slice from the server.
  await page.waitForFunction(
    () => {
      const phase = document.querySelector('[data-testid="phase"]');
      const views = document.querySelectorAll("canvas[data-pixel-to-lps]");
      return phase && phase.textContent.trim() !== "" && views.length >= 3;
    },
    null,
    { timeout: 20000 },
  );
  await page.screenshot({ path: args.out });
  console.log(`web viewer: ${args.out}`);
} finally {
  await browser.close();
}
