// Debian's chromium (CHROMIUM names another), headless with software WebGL (SwiftShader),
// driven by puppeteer-core: what the browser tests share. `missing` says why they must be
// skipped (null: both are here).
import { existsSync } from "node:fs";

export const chromium = process.env.CHROMIUM || "/usr/bin/chromium";
let loaded = null;
try {
  loaded = (await import("puppeteer-core")).default;
} catch {}
export const puppeteer = loaded;
export const missing = !existsSync(chromium) ? `no Chromium at ${chromium}`
  : !puppeteer ? "puppeteer-core not installed (npm ci)" : null;

export const SIZE = { width: 960, height: 540 };
const FLAGS = ["--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
  "--ignore-gpu-blocklist", `--window-size=${SIZE.width},${SIZE.height}`];

/** Chromium started, with `extra` flags; its process is killed when this one exits. */
export async function launch(extra = []) {
  const browser = await puppeteer.launch({ executablePath: chromium, headless: true, args: [...FLAGS, ...extra],
    timeout: 30000, protocolTimeout: 60000 });
  process.on("exit", () => browser.process()?.kill("SIGKILL"));
  return browser;
}
