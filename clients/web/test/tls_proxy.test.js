// voxeld behind a TLS-terminating HAProxy, as the README's "Behind HTTPS" deploys it: a page
// served over https:// can only open wss://, so the proxy terminates TLS and passes / and the
// /ws upgrade to voxeld's HTTP port. Started here on loopback (a self-signed certificate made
// with openssl in a temporary directory; voxeld in memory; both killed at the end, also on
// failure): the viewer's page loads over HTTPS, the client joins over wss:// from the page's
// own origin and gets its view and an edit's result, and a page of another origin is refused
// (403). Skipped when haproxy or openssl is missing.
import assert from "node:assert/strict";
import { execFileSync, spawn } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { get } from "node:https";
import { createServer } from "node:net";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { after, before, test } from "node:test";
import WebSocket from "ws";
import { Client } from "../src/client.js";
import { connectWebSocket } from "../src/transport_ws.js";
import { findTool } from "./tools.js";

const voxeld = findTool("VOXELD", "voxeld");
const haproxy = ["/usr/sbin/haproxy", "/usr/bin/haproxy"].find((p) => existsSync(p));
const openssl = ["/usr/bin/openssl"].find((p) => existsSync(p));
const skip = !voxeld ? "voxeld not built" : !haproxy ? "haproxy not installed" : !openssl ? "openssl not installed" : false;

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
let dir;
const children = [];
let tlsPort;
let logs = "";

function start(cmd, args) {
  const child = spawn(cmd, args, { cwd: dir, stdio: ["ignore", "pipe", "pipe"] });
  child.stdout.on("data", (d) => { logs += d; });
  child.stderr.on("data", (d) => { logs += d; });
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

// Waits until the proxy accepts TLS connections.
async function waitTls(port) {
  const deadline = Date.now() + 20000;
  while (Date.now() < deadline) {
    try {
      await httpsGet(port, "/");
      return;
    } catch {
      await sleep(100);
    }
  }
  throw new Error(`haproxy did not answer on ${port}: ${logs}`);
}

function httpsGet(port, path) {
  return new Promise((resolve, reject) => {
    const req = get({ host: "127.0.0.1", port, path, rejectUnauthorized: false, timeout: 5000 }, (res) => {
      let body = "";
      res.on("data", (d) => { body += d; });
      res.on("end", () => resolve({ status: res.statusCode, body, type: res.headers["content-type"] }));
    });
    req.on("timeout", () => req.destroy(new Error("timeout")));
    req.on("error", reject);
  });
}

before(async () => {
  if (skip) return;
  dir = mkdtempSync(join(tmpdir(), "voxeld-tls-"));
  writeFileSync(join(dir, "index.html"), "<!doctype html><title>viewer</title>");
  execFileSync(openssl, ["req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=127.0.0.1",
    "-keyout", join(dir, "key.pem"), "-out", join(dir, "cert.pem")], { stdio: "ignore" });
  writeFileSync(join(dir, "site.pem"), readFileSync(join(dir, "cert.pem")) + readFileSync(join(dir, "key.pem")));
  const server = start(voxeld, ["--port", "0", "--port-file", "port", "--http-port", "auto", "--http-port-file", "http_port",
    "--http-root", dir, "--in-memory", "--threads", "2", "--log-level", "warn"]);
  const httpPort = await readPort(join(dir, "http_port"), server, "voxeld");
  tlsPort = await freePort();
  // The README's configuration, with these ports.
  const config = readFileSync(new URL("../../../docs/haproxy.cfg", import.meta.url), "utf8")
    .replace("/etc/haproxy/voxeld.pem", join(dir, "site.pem"))
    .replace("0.0.0.0:443", `127.0.0.1:${tlsPort}`)
    .replace("127.0.0.1:7780", `127.0.0.1:${httpPort}`)
    .replace(/^\s*(log|chroot|user|group|daemon|stats socket).*$/gm, "");
  writeFileSync(join(dir, "haproxy.cfg"), config);
  start(haproxy, ["-db", "-f", join(dir, "haproxy.cfg")]);
  await waitTls(tlsPort);
});

after(async () => {
  for (const c of children) {
    if (c.exitCode === null) {
      c.kill("SIGKILL");
      await new Promise((r) => c.once("exit", r));
    }
  }
  if (dir) rmSync(dir, { recursive: true, force: true });
});

test("the page loads over HTTPS through the proxy", { skip, timeout: 30000 }, async () => {
  const page = await httpsGet(tlsPort, "/");
  assert.equal(page.status, 200);
  assert.match(page.body, /viewer/);
  assert.match(page.type, /text\/html/);
});

test("a client of the page's own origin joins over wss:// and plays", { skip, timeout: 60000 }, async () => {
  const origin = `https://127.0.0.1:${tlsPort}`;
  class PageWebSocket extends WebSocket {
    constructor(url) {
      super(url, { rejectUnauthorized: false, origin });
    }
  }
  const client = new Client(await connectWebSocket(`wss://127.0.0.1:${tlsPort}/ws`, { WebSocket: PageWebSocket }), { keepaliveMs: 0 });
  try {
    const welcome = await client.hello({ playerName: "tls" });
    assert.equal(welcome.protocolVersion, 1);
    const id = client.setView({ position: [16, 40, 16], radius: 1 });
    await client.waitViewReady(id, { timeoutMs: 30000 });
    assert.ok(client.chunks.size > 0);
    const result = await client.edit("explosion", { center: [16, 40, 16], radius: 5, power: 2 });
    assert.equal(result.status, 0); // ACCEPTED
  } finally {
    client.close();
  }
});

test("a page of another origin is refused through the proxy", { skip, timeout: 30000 }, async () => {
  const status = await new Promise((resolve) => {
    const ws = new WebSocket(`wss://127.0.0.1:${tlsPort}/ws`, { rejectUnauthorized: false, origin: "https://evil.example" });
    ws.on("unexpected-response", (_req, res) => resolve(res.statusCode));
    ws.on("open", () => { ws.close(); resolve(101); });
    ws.on("error", () => {});
  });
  assert.equal(status, 403);
});
