// npm run bench:browser: decode time per chunk inside headless Chromium (Debian's, or
// CHROMIUM=), driven by puppeteer-core, for the fixture chunks of voxel_mesh_fixtures
// (VOXEL_MESH_FIXTURES, or build/bin of this checkout): the same zstd (fzstd) and mesh
// decoder as decode_bench.js, bundled by esbuild (minified, as the viewer's bundle is) into
// a page served from memory through request interception, the fixture bytes passed in, the
// timing run in the page. Method as decode_bench.js (20 warm-up runs, then samples for at
// least 300 ms and 30 samples, the median), except that Chromium coarsens performance.now()
// (100 µs, or 5 µs in a cross-origin-isolated page such as this one): a sample is a batch
// of runs that takes at least 200 clock ticks, and the median is of the batch means.
// Exit code 77 when Chromium or puppeteer-core is missing.
import { execFileSync } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";
import { build } from "esbuild";
import { findTool } from "../test/tools.js";

const web = join(dirname(fileURLToPath(import.meta.url)), "..");
const chromium = process.env.CHROMIUM || "/usr/bin/chromium";
let puppeteer = null;
try {
  puppeteer = (await import("puppeteer-core")).default;
} catch {}
if (!existsSync(chromium) || !puppeteer) {
  console.error(!puppeteer ? "puppeteer-core not installed (npm ci)" : `no Chromium at ${chromium}`);
  process.exit(77);
}
const tool = findTool("VOXEL_MESH_FIXTURES", "voxel_mesh_fixtures");
if (!tool) {
  console.error("build voxel_mesh_fixtures first (cmake --build build --target voxel_mesh_fixtures)");
  process.exit(1);
}
const dir = mkdtempSync(join(tmpdir(), "voxel-bench-browser-"));
execFileSync(tool, [dir], { stdio: "ignore" });
const names = JSON.parse(readFileSync(join(dir, "manifest.json"), "utf8")).fixtures;
const b64 = (file) => readFileSync(join(dir, file)).toString("base64");
const chunks = names.map((name) => ({ name, frame: b64(`${name}.zst`), encoding: b64(`${name}.bin`) }));
const delta = JSON.parse(readFileSync(join(dir, "delta.json"), "utf8"));
rmSync(dir, { recursive: true, force: true });

const bundle = await build({
  stdin: {
    contents: `export { decompressFull, decompressDelta } from "./src/compression.js";
               export { decodeMesh } from "./src/mesh.js";`,
    resolveDir: web,
  },
  bundle: true, format: "iife", globalName: "voxel", platform: "browser", target: ["es2022"], minify: true,
  write: false, logLevel: "warning",
});
const script = bundle.outputFiles[0].text;
const ORIGIN = "http://127.0.0.1:9/";  // never reached: every request is answered from here
const PAGE = "<!doctype html><meta charset=utf-8><title>decode bench</title><script src=bench.js></script>";

const browser = await puppeteer.launch({
  executablePath: chromium, headless: true, args: ["--headless=new", "--no-sandbox"], timeout: 30000, protocolTimeout: 600000,
});
const kill = () => browser.process()?.kill("SIGKILL");
process.on("exit", kill);
try {
  const page = await browser.newPage();
  await page.setRequestInterception(true);
  page.on("request", (req) => {
    const path = new URL(req.url()).pathname;
    // COOP and COEP make the page cross-origin isolated: a 5 µs clock rather than 100 µs.
    const headers = { "Cross-Origin-Opener-Policy": "same-origin", "Cross-Origin-Embedder-Policy": "require-corp" };
    if (path === "/") req.respond({ status: 200, contentType: "text/html", headers, body: PAGE });
    else if (path === "/bench.js") req.respond({ status: 200, contentType: "text/javascript", headers, body: script });
    else req.respond({ status: 404, body: "" });
  });
  await page.goto(ORIGIN, { timeout: 30000 });
  const result = await page.evaluate((chunks, delta) => {
    const { decompressFull, decompressDelta, decodeMesh } = window.voxel;
    const bytes = (s) => Uint8Array.from(atob(s), (c) => c.charCodeAt(0));
    const hex = (s) => Uint8Array.from(s.match(/../g) ?? [], (h) => parseInt(h, 16));
    // The clock's step: the smallest non-zero difference seen.
    let tick = Infinity;
    for (let i = 0; i < 2000; i++) {
      const a = performance.now();
      let b = a;
      while (b === a) b = performance.now();
      tick = Math.min(tick, b - a);
    }
    function time(fn, minMs = 300) {
      for (let i = 0; i < 20; i++) fn();  // warm up
      // Runs per sample: enough for 200 ticks, from the mean of 20 more runs.
      const t0 = performance.now();
      for (let i = 0; i < 20; i++) fn();
      const batch = Math.max(1, Math.ceil((200 * tick) / Math.max((performance.now() - t0) / 20, tick / 20)));
      const samples = [];
      const end = performance.now() + minMs;
      while (performance.now() < end || samples.length < 30) {
        const t = performance.now();
        for (let i = 0; i < batch; i++) fn();
        samples.push((performance.now() - t) / batch);
      }
      samples.sort((a, b) => a - b);
      return { us: samples[samples.length >> 1] * 1000, batch };
    }
    const rows = chunks.map((c) => {
      const frame = bytes(c.frame);
      const encoding = bytes(c.encoding);
      const m = decodeMesh(encoding);
      const both = time(() => decodeMesh(decompressFull(frame)));
      const only = time(() => decodeMesh(encoding));
      return { name: c.name, format: m.format, bytes: encoding.length, zst: frame.length, tris: m.triangleCount, both: both.us, only: only.us, batch: both.batch };
    });
    const base = hex(delta.base);
    const dframe = hex(delta.delta_frame);
    const d = time(() => decodeMesh(decompressDelta(dframe, base)));
    return { rows, delta: { frame: dframe.length, base: base.length, us: d.us }, tick: tick * 1000, isolated: crossOriginIsolated, agent: navigator.userAgent };
  }, chunks, { base: delta.base, delta_frame: delta.delta_frame });

  const fmt = (us) => `${us.toFixed(1).padStart(8)} µs`;
  const version = result.agent.match(/Chrome\/(\S+)/)?.[1] ?? "?";
  console.log(`Chromium ${version}, headless; clock step ${result.tick.toFixed(1)} µs (cross-origin isolated: ${result.isolated}); a sample is a batch of runs`);
  console.log("chunk                       format  bytes  zst  tris    zstd+decode   decode only  runs/sample");
  let total = 0;
  const terrain = [];
  for (const r of result.rows) {
    total += r.both;
    if (r.name.startsWith("terrain") || r.name.startsWith("lod")) terrain.push(r.both);
    console.log(`${r.name.padEnd(28)}${String(r.format).padStart(4)}${String(r.bytes).padStart(8)}${String(r.zst).padStart(6)}${String(r.tris).padStart(6)}  ${fmt(r.both)}  ${fmt(r.only)}  ${String(r.batch).padStart(6)}`);
  }
  console.log(`delta (${result.delta.frame} bytes against a ${result.delta.base}-byte base): zstd+decode ${fmt(result.delta.us)}`);
  terrain.sort((a, b) => a - b);
  console.log(`mean over the ${result.rows.length} fixtures: ${fmt(total / result.rows.length)}; median of terrain/LOD chunks: ${fmt(terrain[terrain.length >> 1])}`);
} finally {
  await Promise.race([browser.close(), new Promise((r) => setTimeout(r, 5000))]).catch(() => {});
  kill();
}
