// The viewer in a real headless Chromium (Debian's, software WebGL) against a real voxeld
// (in memory, HTTP on a free port, serving a bundle built here into a temporary folder):
// the view completes with triangles drawn, a click with the explode tool makes a crater
// (a chunk's version and triangle count change), a second page sees it as it happens, a
// screenshot is not one colour, and the frame rate of a level-of-detail view is measured.
// Skipped when Chromium, puppeteer-core or voxeld is missing. voxeld and Chromium are
// killed at the end, also on failure; every wait has a deadline.
import assert from "node:assert/strict";
import { execFileSync, spawn } from "node:child_process";
import { createPrivateKey, createPublicKey, sign } from "node:crypto";
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";
import { after, before, test } from "node:test";
import { findTool } from "../test/tools.js";
import { SIZE, launch, missing } from "./chromium.js";

const here = dirname(fileURLToPath(import.meta.url));
const voxeld = findTool("VOXELD", "voxeld");
const skip = missing ? missing
  : !voxeld ? "voxeld not built (VOXELD unset)" : false;

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

let dir;
let server;
let serverLog = "";
let browser;
let base;
const pageErrors = [];

async function readPort(file, deadline) {
  for (;;) {
    if (server.exitCode !== null) throw new Error(`voxeld exited ${server.exitCode}: ${serverLog}`);
    if (Date.now() > deadline) throw new Error(`voxeld wrote no ${file} in time: ${serverLog}`);
    try {
      const port = Number(readFileSync(file, "utf8").trim());
      if (port) return port;
    } catch {}
    await sleep(50);
  }
}

/** Starts voxeld serving the bundle on that HTTP port ("auto": a free one), with more flags. */
function startServer(httpPort, ...more) {
  rmSync(join(dir, "http-port"), { force: true });
  server = spawn(voxeld, ["--in-memory", "--seed", "1", "--threads", "2", "--port", "0", "--port-file", join(dir, "port"),
    "--http-port", String(httpPort), "--http-port-file", join(dir, "http-port"), "--http-root", join(dir, "web"), ...more], {
    cwd: dir, stdio: ["ignore", "pipe", "pipe"],
  });
  server.stdout.on("data", (d) => { serverLog += d; });
  server.stderr.on("data", (d) => { serverLog += d; });
}

/**
 * An Ed25519 key pair and a player token signed with it (PROTOCOL §4.8), made here.
 * @returns {{publicKey: string, token: string}} both unpadded base64url
 */
function keyAndToken(playerId, name) {
  const seed = Buffer.alloc(32, 7);
  const key = createPrivateKey({ key: Buffer.concat([Buffer.from("302e020100300506032b657004220420", "hex"), seed]), format: "der", type: "pkcs8" });
  const publicKey = createPublicKey(key).export({ format: "der", type: "spki" }).subarray(-32);
  const pid = Buffer.from(playerId);
  const nm = Buffer.from(name);
  const claims = Buffer.alloc(18);
  claims[0] = 1;
  claims.writeBigInt64LE(BigInt(Math.floor(Date.now() / 1000) + 3600), 1);
  claims[9] = 1;  // player; edit_rate and edit_burst 0: the role's
  const body = Buffer.concat([claims, Buffer.from([pid.length]), pid, Buffer.from([nm.length]), nm]);
  const signature = sign(null, Buffer.concat([Buffer.from("voxeld-token-v1"), body]), key);
  return { publicKey: publicKey.toString("base64url"), token: Buffer.concat([body, signature]).toString("base64url") };
}

before(async () => {
  if (skip) return;
  dir = mkdtempSync(join(tmpdir(), "voxeld-viewer-"));
  const web = join(dir, "web");
  execFileSync(process.execPath, [join(here, "..", "tools", "build_viewer.js"), web], { stdio: "pipe", timeout: 60000 });
  assert.ok(existsSync(join(web, "index.html")) && existsSync(join(web, "viewer.js")), "the bundle was built");
  startServer("auto");
  process.on("exit", () => {
    server?.kill("SIGKILL");
    browser?.process()?.kill("SIGKILL");
  });
  const httpPort = await readPort(join(dir, "http-port"), Date.now() + 20000);
  base = `http://127.0.0.1:${httpPort}/`;
  browser = await launch();
});

after(async () => {
  if (browser) {
    const proc = browser.process();
    await Promise.race([browser.close(), sleep(5000)]).catch(() => {});
    proc?.kill("SIGKILL");
  }
  if (server && server.exitCode === null) {
    server.kill("SIGKILL");
    await new Promise((r) => server.once("exit", r));
  }
  if (dir && !process.env.KEEP_VIEWER_TEST_DIR) rmSync(dir, { recursive: true, force: true });
});

/** Opens the viewer with URL parameters and waits for its first complete view. */
async function open(query, timeoutMs = 60000) {
  const page = await browser.newPage();
  await page.setViewport(SIZE);
  page.on("pageerror", (e) => pageErrors.push(e.message));
  const t0 = Date.now();
  await page.goto(`${base}?${query}`, { timeout: 20000 });
  await page.waitForFunction(() => window.voxelViewer?.stats().viewComplete, { timeout: timeoutMs, polling: 100 });
  const stats = await page.evaluate(() => window.voxelViewer.stats());
  return { page, stats, loadMs: Date.now() - t0 };
}

const chunksOf = (page) => page.evaluate(() => window.voxelViewer.chunks());

/** Resolves with a key whose version and triangle count both differ from `before`. */
async function changedChunk(page, before, timeoutMs) {
  const handle = await page.waitForFunction((prev) => {
    const now = window.voxelViewer.chunks();
    return Object.keys(prev).find((k) => now[k] && BigInt(now[k].version) > BigInt(prev[k].version)
      && now[k].triangles !== prev[k].triangles) ?? false;
  }, { timeout: timeoutMs, polling: 100 }, before);
  return handle.jsonValue();
}

let first;
let second;

test("the view completes with terrain drawn", { skip, timeout: 90000 }, async (t) => {
  first = await open("radius=3&lod=3&pos=0,56,0&name=first");
  const s = first.stats;
  t.diagnostic(`radius 3 + lod 3: view complete ${s.firstViewMs} ms after navigation, ${s.chunks} chunks, ${s.triangles} triangles`);
  assert.ok(s.connected);
  assert.ok(s.chunks > 20, `chunks held: ${s.chunks}`);
  assert.ok(s.triangles > 50000, `triangles held: ${s.triangles}`);
  assert.deepEqual(pageErrors, []);
});

test("a click with the explode tool makes a crater that a second page sees", { skip, timeout: 90000 }, async (t) => {
  assert.ok(first, "the first page is open");
  second = await open("radius=3&lod=3&pos=0,56,0&name=second");
  const { page } = first;
  await page.evaluate(() => {
    const v = window.voxelViewer;
    v.toolbar.select("explode");
    v.toolbar.set("radius", 8);
    v.toolbar.set("strength", 4);
    v.controls.setAngles(0, -1.0);  // look down: the centre of the screen is terrain close by
  });
  const before1 = await chunksOf(page);
  const before2 = await chunksOf(second.page);
  await page.mouse.click(SIZE.width / 2, SIZE.height / 2);
  await page.waitForFunction(() => window.voxelViewer.edits.length > 0, { timeout: 20000, polling: 50 });
  const [edit] = await page.evaluate(() => window.voxelViewer.edits);
  t.diagnostic(`explosion at ${edit.point.map((c) => c.toFixed(1))}: ${edit.status} in ${edit.ms} ms, ${edit.changed} chunks`);
  assert.equal(edit.status, "ACCEPTED");
  assert.ok(edit.changed > 0);
  const key = await changedChunk(page, before1, 20000);
  const key2 = await changedChunk(second.page, before2, 20000);
  // Both pages hold the same meshes once the deltas are in.
  await second.page.waitForFunction((k, tris) => window.voxelViewer.chunks()[k]?.triangles === tris,
    { timeout: 20000, polling: 100 }, key, (await chunksOf(page))[key].triangles);
  t.diagnostic(`crater: chunk ${key} on the editor, ${key2} on the second page`);
  const results = await page.$eval("#results", (e) => e.textContent);
  assert.match(results, /explosion: accepted/);
  assert.deepEqual(pageErrors, []);
});

test("a screenshot shows terrain under a sky", { skip, timeout: 60000 }, async () => {
  assert.ok(first, "the first page is open");
  const { page } = first;
  await page.evaluate(() => window.voxelViewer.controls.setAngles(0, -0.35));
  await sleep(1500);
  const png = await page.screenshot({ type: "png" });
  const out = process.env.VIEWER_SCREENSHOT || join(dir, "viewer.png");
  writeFileSync(out, png);
  // The browser decodes the PNG: distinct colours, the sky's share at the top and the bottom.
  const stats = await page.evaluate(async (b64) => {
    const blob = await (await fetch(`data:image/png;base64,${b64}`)).blob();
    const image = await createImageBitmap(blob);
    const canvas = new OffscreenCanvas(image.width, image.height);
    const g = canvas.getContext("2d");
    g.drawImage(image, 0, 0);
    const { data } = g.getImageData(0, 0, image.width, image.height);
    const colours = new Set();
    let green = 0;
    for (let i = 0; i < data.length; i += 4) {
      colours.add((data[i] >> 3) << 10 | (data[i + 1] >> 3) << 5 | data[i + 2] >> 3);
      if (data[i + 1] > data[i + 2] + 10) green++;  // grass and dirt: more green than blue; sky: bluer
    }
    return { colours: colours.size, terrainShare: green / (data.length / 4) };
  }, png.toString("base64"));
  assert.ok(stats.colours > 200, `distinct colours: ${stats.colours}`);
  assert.ok(stats.terrainShare > 0.2 && stats.terrainShare < 0.98, `terrain share of the pixels: ${stats.terrainShare}`);
});

test("frame rate of a level-of-detail view (software WebGL)", { skip, timeout: 150000 }, async (t) => {
  for (const p of [first, second]) await p?.page.close();
  const lod = await open("radius=4&lod=6&pos=0,64,0&name=lod", 120000);
  const s = lod.stats;
  const fps = await lod.page.evaluate(() => new Promise((resolve) => {
    let n = 0;
    const t0 = performance.now();
    const step = (now) => (now - t0 >= 3000 ? resolve((n * 1000) / (now - t0)) : (n++, requestAnimationFrame(step)));
    requestAnimationFrame(step);
  }));
  t.diagnostic(`lod 6 (to ±${64 * 2 ** 6} voxels): complete ${s.firstViewMs} ms after navigation, ${s.chunks} chunks, ${s.triangles} triangles, ${fps.toFixed(1)} frames/s at ${SIZE.width}x${SIZE.height}`);
  assert.ok(s.triangles > 100000, `triangles: ${s.triangles}`);
  assert.ok(fps > 0.3, `frames per second: ${fps}`);
  assert.deepEqual(pageErrors, []);
  await lod.page.close();
});

test("the page says when the server goes away, reconnects, and asks for a token when one is needed", { skip, timeout: 120000 }, async () => {
  const { page } = await open("radius=2&lod=0&pos=0,16,0&name=back");
  const status = () => page.$eval("#status", (e) => e.textContent);
  const waitStatus = (re, ms) => page.waitForFunction((src) => new RegExp(src).test(document.getElementById("status").textContent),
    { timeout: ms, polling: 100 }, re.source);
  const httpPort = new URL(base).port;
  server.kill("SIGKILL");
  await new Promise((r) => server.once("exit", r));
  await waitStatus(/reconnecting in/, 10000);

  // Back with tokens required: the page says why and waits for one (no retry loop).
  const { publicKey, token } = keyAndToken("tester-1", "Tester");
  writeFileSync(join(dir, "game.pub"), `${publicKey}\n`);
  startServer(httpPort, "--auth-public-key", join(dir, "game.pub"));
  await readPort(join(dir, "http-port"), Date.now() + 20000);
  await waitStatus(/AUTH_REQUIRED.*token/, 30000);
  await sleep(2500);
  assert.match(await status(), /AUTH_REQUIRED/, "no reconnection loop after a token refusal");

  await page.type("#token", token);
  await page.click("#token-form button");
  await page.waitForFunction(() => window.voxelViewer.stats().viewComplete, { timeout: 60000, polling: 100 })
    .catch(async (e) => assert.fail(`${e.message}; status: ${await status()}; ${JSON.stringify(await page.evaluate(() => window.voxelViewer.stats()))}; ${serverLog.slice(-1500)}`));
  assert.match(await status(), /connected/);
  const s = await page.evaluate(() => window.voxelViewer.stats());
  assert.ok(s.triangles > 1000, `triangles after reconnecting: ${s.triangles}`);
  assert.deepEqual(pageErrors, []);
});
