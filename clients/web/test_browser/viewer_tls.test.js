// The viewer in a real headless Chromium through the TLS-terminating HAProxy of the README's
// "Behind HTTPS" (docs/haproxy.cfg, adapted as test/tls_proxy.test.js does: a self-signed
// certificate made with openssl, free loopback ports, no daemon, chroot or user): the page
// is loaded over https://, opens wss:// to its own origin (seen in Chromium's own network
// events, the handshake answered 101) and completes its view with triangles drawn.
// Chromium takes the self-signed certificate with --ignore-certificate-errors. Skipped when
// Chromium, puppeteer-core, voxeld, haproxy or openssl is missing. haproxy, voxeld and
// Chromium are killed at the end, also on failure; every wait has a deadline.
import assert from "node:assert/strict";
import { execFileSync, spawn } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { request } from "node:https";
import { createServer } from "node:net";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";
import { after, before, test } from "node:test";
import { findTool } from "../test/tools.js";

const here = dirname(fileURLToPath(import.meta.url));
const chromium = process.env.CHROMIUM || "/usr/bin/chromium";
const voxeld = findTool("VOXELD", "voxeld");
const haproxy = ["/usr/sbin/haproxy", "/usr/bin/haproxy"].find((p) => existsSync(p));
const openssl = ["/usr/bin/openssl"].find((p) => existsSync(p));
let puppeteer = null;
try {
  puppeteer = (await import("puppeteer-core")).default;
} catch {}
const skip = !existsSync(chromium) ? `no Chromium at ${chromium}`
  : !puppeteer ? "puppeteer-core not installed (npm ci)"
  : !voxeld ? "voxeld not built (VOXELD unset)"
  : !haproxy ? "haproxy not installed"
  : !openssl ? "openssl not installed" : false;

const SIZE = { width: 960, height: 540 };
const FLAGS = ["--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
  "--ignore-gpu-blocklist", `--window-size=${SIZE.width},${SIZE.height}`, "--ignore-certificate-errors"];
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

let dir;
const children = [];
let logs = "";
let browser;
let tlsPort;

function start(cmd, args) {
  const child = spawn(cmd, args, { cwd: dir, stdio: ["ignore", "pipe", "pipe"] });
  child.stdout.on("data", (d) => { logs += d; });
  child.stderr.on("data", (d) => { logs += d; });
  child.on("error", (e) => { logs += `${cmd}: ${e.message}\n`; });
  children.push(child);
  return child;
}

async function readPort(file, child, what) {
  const deadline = Date.now() + 20000;
  for (;;) {
    if (child.exitCode !== null) throw new Error(`${what} exited ${child.exitCode}: ${logs}`);
    if (Date.now() > deadline) throw new Error(`${what} wrote no port in 20 s: ${logs}`);
    try {
      const port = Number(readFileSync(file, "utf8").trim());
      if (port) return port;
    } catch {}
    await sleep(50);
  }
}

function freePort() {
  return new Promise((resolve, reject) => {
    const s = createServer();
    s.once("error", reject);
    s.listen(0, "127.0.0.1", () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
  });
}

/** Waits until the proxy answers GET / over TLS. */
async function waitTls(port, proxy) {
  const deadline = Date.now() + 20000;
  while (Date.now() < deadline) {
    if (proxy.exitCode !== null) throw new Error(`haproxy exited ${proxy.exitCode}: ${logs}`);
    const status = await new Promise((resolve) => {
      const req = request({ host: "127.0.0.1", port, path: "/", rejectUnauthorized: false, timeout: 3000 }, (res) => {
        res.resume();
        resolve(res.statusCode);
      });
      req.on("timeout", () => req.destroy(new Error("timeout")));
      req.on("error", () => resolve(0));
      req.end();
    });
    if (status === 200) return;
    await sleep(100);
  }
  throw new Error(`haproxy did not serve the page on ${port}: ${logs}`);
}

before(async () => {
  if (skip) return;
  dir = mkdtempSync(join(tmpdir(), "voxeld-viewer-tls-"));
  process.on("exit", () => {
    for (const c of children) c.kill("SIGKILL");
    browser?.process()?.kill("SIGKILL");
  });
  const web = join(dir, "web");
  execFileSync(process.execPath, [join(here, "..", "tools", "build_viewer.js"), web], { stdio: "pipe", timeout: 60000 });
  execFileSync(openssl, ["req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
    "-keyout", join(dir, "key.pem"), "-out", join(dir, "cert.pem")], { stdio: "ignore", timeout: 30000 });
  writeFileSync(join(dir, "site.pem"), readFileSync(join(dir, "cert.pem")) + readFileSync(join(dir, "key.pem")));
  const server = start(voxeld, ["--in-memory", "--seed", "1", "--threads", "2", "--port", "0", "--port-file", "port",
    "--http-port", "auto", "--http-port-file", "http-port", "--http-root", web, "--log-level", "warn"]);
  const httpPort = await readPort(join(dir, "http-port"), server, "voxeld");
  tlsPort = await freePort();
  // The README's configuration with these ports, as test/tls_proxy.test.js adapts it.
  const config = readFileSync(new URL("../../../docs/haproxy.cfg", import.meta.url), "utf8")
    .replace("/etc/haproxy/voxeld.pem", join(dir, "site.pem"))
    .replace("0.0.0.0:443", `127.0.0.1:${tlsPort}`)
    .replace("127.0.0.1:7780", `127.0.0.1:${httpPort}`)
    .replace(/^\s*(log|chroot|user|group|daemon|stats socket).*$/gm, "");
  writeFileSync(join(dir, "haproxy.cfg"), config);
  const proxy = start(haproxy, ["-db", "-f", join(dir, "haproxy.cfg")]);
  await waitTls(tlsPort, proxy);
  browser = await puppeteer.launch({ executablePath: chromium, headless: true, args: FLAGS, timeout: 30000, protocolTimeout: 60000 });
});

after(async () => {
  if (browser) {
    const proc = browser.process();
    await Promise.race([browser.close(), sleep(5000)]).catch(() => {});
    proc?.kill("SIGKILL");
  }
  for (const c of children) {
    if (c.exitCode === null && c.signalCode === null) {
      c.kill("SIGKILL");
      await new Promise((r) => c.once("exit", r));
    }
  }
  if (dir) rmSync(dir, { recursive: true, force: true });
});

test("over https:// the viewer opens wss:// through the proxy and completes its view", { skip, timeout: 90000 }, async (t) => {
  const page = await browser.newPage();
  const pageErrors = [];
  page.on("pageerror", (e) => pageErrors.push(e.message));
  try {
    await page.setViewport(SIZE);
    // Chromium's own record of the page's WebSockets: the URL asked for and the handshake's answer.
    const cdp = await page.createCDPSession();
    await cdp.send("Network.enable");
    const sockets = new Map();
    cdp.on("Network.webSocketCreated", (e) => sockets.set(e.requestId, { url: e.url, status: 0 }));
    cdp.on("Network.webSocketHandshakeResponseReceived", (e) => {
      const s = sockets.get(e.requestId);
      if (s) s.status = e.response.status;
    });
    const origin = `https://127.0.0.1:${tlsPort}`;
    const response = await page.goto(`${origin}/?radius=2&lod=0&pos=0,40,0&name=tls`, { timeout: 20000 });
    assert.equal(response.status(), 200);
    assert.equal(new URL(page.url()).protocol, "https:");
    await page.waitForFunction(() => window.voxelViewer?.stats().viewComplete, { timeout: 60000, polling: 100 })
      .catch(async (e) => assert.fail(`${e.message}; status: ${await page.$eval("#status", (s) => s.textContent).catch(() => "?")}; ${logs.slice(-1500)}`));
    const s = await page.evaluate(() => window.voxelViewer.stats());
    const url = await page.evaluate(() => window.voxelViewer.connection.url);
    t.diagnostic(`${url}: view complete ${s.firstViewMs} ms after navigation, ${s.chunks} chunks, ${s.triangles} triangles, ${s.bytesReceived} bytes`);
    assert.equal(url, `wss://127.0.0.1:${tlsPort}/ws`);
    assert.deepEqual([...sockets.values()], [{ url: `wss://127.0.0.1:${tlsPort}/ws`, status: 101 }]);
    assert.ok(s.connected);
    assert.ok(s.chunks > 0, `chunks held: ${s.chunks}`);
    assert.ok(s.triangles > 0, `triangles held: ${s.triangles}`);
    assert.match(await page.$eval("#status", (e) => e.textContent), /connected/);
    assert.deepEqual(pageErrors, []);
  } finally {
    await page.close().catch(() => {});
  }
});
