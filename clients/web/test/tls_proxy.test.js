// voxeld behind a TLS-terminating HAProxy, as the README's "Behind HTTPS" deploys it: a page
// served over https:// can only open wss://, so the proxy terminates TLS and passes / and the
// /ws upgrade to voxeld's HTTP port. Started here on loopback (a self-signed certificate made
// with openssl in a temporary directory; voxeld in memory; both killed at the end, also on
// failure): the viewer's page loads over HTTPS, the client joins over wss:// from the page's
// own origin and gets its view and an edit's result, a page of another origin is refused
// (403), and each client is capped by its own address, which the proxy's X-Forwarded-For
// names (voxeld --http-trusted-proxy 127.0.0.1). Skipped when haproxy or openssl is missing.
import assert from "node:assert/strict";
import { writeFileSync } from "node:fs";
import { get } from "node:https";
import { join } from "node:path";
import { after, before, test } from "node:test";
import WebSocket from "ws";
import { Client, ServerError } from "../src/client.js";
import { connectWebSocket } from "../src/transport_ws.js";
import { Services, haproxy, openssl } from "./services.js";
import { findTool } from "./tools.js";

const voxeld = findTool("VOXELD", "voxeld");
const skip = !voxeld ? "voxeld not built" : !haproxy ? "haproxy not installed" : !openssl ? "openssl not installed" : false;

let services;
let tlsPort;

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
  services = new Services("voxeld-tls-");
  writeFileSync(join(services.dir, "index.html"), "<!doctype html><title>viewer</title>");
  // One player per address: behind the proxy, per client address, not the proxy's.
  const extra = ["--http-trusted-proxy", "127.0.0.1", "--max-per-address", "1"];
  tlsPort = await services.tlsProxy(await services.voxeld(voxeld, services.dir, extra));
});

after(async () => {
  await services?.stop();
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

test("behind the proxy each client is capped by its own address, not the proxy's", { skip, timeout: 60000 }, async () => {
  // Clients from two loopback addresses; the proxy connects to voxeld from 127.0.0.1 for all.
  const join = async (localAddress) => {
    const origin = `https://127.0.0.1:${tlsPort}`;
    class FromAddress extends WebSocket {
      constructor(url) {
        super(url, { rejectUnauthorized: false, origin, localAddress });
      }
    }
    const client = new Client(await connectWebSocket(`wss://127.0.0.1:${tlsPort}/ws`, { WebSocket: FromAddress }), { keepaliveMs: 0 });
    try {
      await client.hello({ playerName: localAddress });
      return { client, refused: null };
    } catch (e) {
      client.close();
      // The refusal comes at once, maybe before hello() was sent: then it is why the client closed.
      return { client: null, refused: client.closeError instanceof ServerError ? client.closeError : e };
    }
  };
  const a = await join("127.0.0.2");
  const b = await join("127.0.0.3");
  try {
    assert.equal(a.refused, null);
    assert.equal(b.refused, null);
    const again = await join("127.0.0.2");
    again.client?.close();
    // Refused: the Error, or (when it came before the client was listening) the close code
    // that follows it, 1013 "try again later".
    assert.ok(again.refused, "a second player from 127.0.0.2 was let in");
    if (again.refused instanceof ServerError) assert.equal(again.refused.codeName, "TOO_MANY_CONNECTIONS");
    else assert.match(String(again.refused), /1013/);
  } finally {
    a.client?.close();
    b.client?.close();
  }
});
