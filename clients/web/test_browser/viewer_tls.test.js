// The viewer in a real headless Chromium through the TLS-terminating HAProxy of the README's
// "Behind HTTPS" (docs/haproxy.cfg, adapted as test/tls_proxy.test.js does: a self-signed
// certificate made with openssl, free loopback ports, no daemon, chroot or user): the page
// is loaded over https://, opens wss:// to its own origin (seen in Chromium's own network
// events, the handshake answered 101) and completes its view with triangles drawn.
// Chromium takes the self-signed certificate with --ignore-certificate-errors. Skipped when
// Chromium, puppeteer-core, voxeld, haproxy or openssl is missing. haproxy, voxeld and
// Chromium are killed at the end, also on failure; every wait has a deadline.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { existsSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";
import { after, before, test } from "node:test";
import { Services, haproxy, openssl } from "../test/services.js";
import { findTool } from "../test/tools.js";
import { SIZE, launch, missing } from "./chromium.js";

const here = dirname(fileURLToPath(import.meta.url));
const voxeld = findTool("VOXELD", "voxeld");
const skip = missing ? missing
  : !voxeld ? "voxeld not built (VOXELD unset)"
  : !haproxy ? "haproxy not installed"
  : !openssl ? "openssl not installed" : false;

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

let services;
let browser;
let tlsPort;

before(async () => {
  if (skip) return;
  services = new Services("voxeld-viewer-tls-");
  process.on("exit", () => browser?.process()?.kill("SIGKILL"));
  const web = join(services.dir, "web");
  execFileSync(process.execPath, [join(here, "..", "tools", "build_viewer.js"), web], { stdio: "pipe", timeout: 60000 });
  tlsPort = await services.tlsProxy(await services.voxeld(voxeld, web));
  browser = await launch(["--ignore-certificate-errors"]);
});

after(async () => {
  if (browser) {
    const proc = browser.process();
    await Promise.race([browser.close(), sleep(5000)]).catch(() => {});
    proc?.kill("SIGKILL");
  }
  await services?.stop();
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
      .catch(async (e) => assert.fail(`${e.message}; status: ${await page.$eval("#status", (s) => s.textContent).catch(() => "?")}; ${services.logs.slice(-1500)}`));
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
