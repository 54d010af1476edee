// The session logic over a fake server speaking through the WebSocket transport (the `ws`
// package in Node; one binary message = one Envelope): Welcome and the table revision, a
// delta that does not apply is dropped and asked for with one Resync, edits resolve by
// request id, Error codes that close reject what waits. Also: the browser entry point
// imports nothing of Node's.
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { test } from "node:test";
import { WebSocket, WebSocketServer } from "ws";
import { Client } from "../src/client.js";
import { decodeEnvelope, encodeEnvelope } from "../src/messages.js";
import { connectWebSocket } from "../src/transport_ws.js";
import { WORKED_EXAMPLE } from "./helpers.js";

// A zstd frame holding `content` as one raw block.
const rawFull = (content) => {
  const n = content.length;
  const blk = (n << 3) | 1;
  return Uint8Array.from([0x28, 0xb5, 0x2f, 0xfd, 0xa0, n & 255, (n >> 8) & 255, n >> 16, 0, blk & 255, (blk >> 8) & 255, blk >> 16, ...content]);
};

async function fakeServer(onMessage) {
  const wss = new WebSocketServer({ port: 0, host: "127.0.0.1" });
  await new Promise((r) => wss.once("listening", r));
  const received = [];
  wss.on("connection", (socket) => {
    socket.on("message", (data, isBinary) => {
      assert.ok(isBinary);
      const { kind, message } = decodeEnvelope(new Uint8Array(data));
      received.push({ kind, message });
      onMessage(kind, message, (body) => socket.send(encodeEnvelope(body)), socket);
    });
  });
  return { url: `ws://127.0.0.1:${wss.address().port}/ws`, received, close: () => new Promise((r) => wss.close(r)) };
}

const welcome = (extra = {}) => ({
  welcome: { protocol_version: 1, chunk_size: 32, mesh_format: 1, max_resync_chunks: 64, mesh_table_revision: 2, max_frame_bytes: 65536, ...extra },
});

test("over WebSocket: hello, a chunk, a bad delta resynced once, an edit result, a ping", async () => {
  const server = await fakeServer((kind, m, send) => {
    if (kind === "hello") send(welcome());
    if (kind === "set_view") {
      send({ chunk_mesh: { coord: { x: 1, y: 2, z: 3 }, version: 4, payload: rawFull(WORKED_EXAMPLE) } });
      send({ chunk_mesh: { coord: { x: 1, y: 2, z: 3 }, version: 6, base_version: 5, payload: rawFull(WORKED_EXAMPLE) } });
      send({ chunk_mesh: { coord: { x: 1, y: 2, z: 3 }, version: 7, base_version: 6, payload: rawFull(WORKED_EXAMPLE) } });
      send({ view_ready: { view_id: m.view_id, radius: m.radius, chunks_sent: 1 } });
    }
    if (kind === "resync") send({ chunk_mesh: { coord: m.coords[0], version: 7, payload: rawFull(WORKED_EXAMPLE) } });
    if (kind === "edit") send({ edit_result: { request_id: m.request_id, status: 3, reason: "radius" } });
    if (kind === "ping") send({ pong: { nonce: m.nonce } });
  });
  const client = new Client(await connectWebSocket(server.url, { WebSocket }), { keepaliveMs: 0 });
  try {
    const w = await client.hello({ playerName: "ws" });
    assert.equal(w.maxResyncChunks, 64);
    const events = [];
    for (const e of ["chunkadded", "chunkupdated", "chunkfailed", "chunkunloaded"]) client.on(e, (x) => events.push(`${e} ${x.key ?? x}`));
    const ready = await client.waitViewReady(client.setView({ position: [0, 0, 0], radius: 1 }), { timeoutMs: 5000 });
    assert.equal(ready.chunksSent, 1);
    const r = await client.edit("smooth", { center: [1, 2, 3], radius: 9, strength: 0.5 }, { timeoutMs: 5000 });
    assert.equal(r.statusName, "BAD_RADIUS");
    assert.equal(r.requestId, 1n);
    await client.ping({ timeoutMs: 5000 });
    assert.deepEqual(events, ["chunkadded 0:1,2,3", "chunkfailed 0:1,2,3", "chunkunloaded 0:1,2,3", "chunkadded 0:1,2,3"]);
    const resyncs = server.received.filter((x) => x.kind === "resync");
    assert.equal(resyncs.length, 1, "one Resync; the next delta was ignored");
    assert.deepEqual(resyncs[0].message.coords.map((c) => [c.x, c.y, c.z]), [[1, 2, 3]]);
    assert.equal(client.chunk(0, 1, 2, 3).version, 7n);
    const edit = server.received.find((x) => x.kind === "edit").message;
    assert.equal(edit.kind, "smooth");
    assert.equal(edit.smooth.strength, 0.5);
  } finally {
    client.close();
    await server.close();
  }
});

test("a server with another table revision is refused", async () => {
  const server = await fakeServer((kind, m, send) => {
    if (kind === "hello") send(welcome({ mesh_table_revision: 0 }));
  });
  const client = new Client(await connectWebSocket(server.url, { WebSocket }), { keepaliveMs: 0 });
  try {
    await assert.rejects(client.hello(), /table revision 1, this client has 2/);
  } finally {
    client.close();
    await server.close();
  }
});

test("an Error that closes rejects the edits waiting, with the server's reason", async () => {
  const server = await fakeServer((kind, m, send, socket) => {
    if (kind === "hello") send(welcome());
    if (kind === "edit") {
      send({ error: { code: 11, message: "stopping" } });
      socket.close();
    }
  });
  const client = new Client(await connectWebSocket(server.url, { WebSocket }), { keepaliveMs: 0 });
  try {
    await client.hello();
    await assert.rejects(client.edit("explosion", { center: [0, 0, 0], radius: 1, power: 1 }), /SHUTTING_DOWN: stopping/);
    assert.throws(() => client.setView({ position: [0, 0, 0], radius: 1 }), /SHUTTING_DOWN/);
  } finally {
    await server.close();
  }
});

test("edit parameters: every kind, and unknown kinds refused", () => {
  assert.throws(() => new Client({ send() {}, close() {} }, { keepaliveMs: 0 }).edit("dig", {}), /unknown edit kind "dig"/);
});

test("the browser entry point imports nothing of Node's", () => {
  const src = join(dirname(fileURLToPath(import.meta.url)), "..", "src");
  const seen = new Set();
  const visit = (file) => {
    if (seen.has(file)) return;
    seen.add(file);
    const text = readFileSync(file, "utf8");
    for (const [, spec] of text.matchAll(/^\s*(?:import|export)[^;]*?from\s+"([^"]+)"/gm)) {
      assert.ok(!spec.startsWith("node:") && !["net", "fs", "path", "os", "ws"].includes(spec), `${file} imports ${spec}`);
      if (spec.startsWith(".")) visit(resolve(dirname(file), spec));
    }
  };
  visit(join(src, "index.js"));
  assert.ok(seen.size >= 10);
  assert.ok(![...seen].some((f) => f.endsWith("transport_tcp.js")));
});
