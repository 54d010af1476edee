// The session logic over a fake server speaking through the WebSocket transport (the `ws`
// package in Node; one binary message = one Envelope): Welcome and the table revision, a
// delta that does not apply is dropped and asked for with one Resync, edits resolve by
// request id, queries resolve by request id (samples decoded), Error codes that close
// reject what waits. Also: the browser entry point imports nothing of Node's.
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

test("queries: each QueryResult goes to its request by request_id, samples decoded, close rejects", async () => {
  const held = [];
  const server = await fakeServer((kind, m, send, socket) => {
    if (kind === "hello") send(welcome({ max_query_distance: 512, max_query_samples: 32768, max_queries_in_flight: 8, queries_per_second: 20 }));
    if (kind !== "query") return;
    held.push(m);
    if (held.length === 3) {
      // Answered last first: each result must reach the promise of its own request.
      const [ray, ground, samples] = held;
      // Densities 1, -2, 300, -32767 as int16 little-endian; materials 3, 0, 4, 0.
      send({
        query_result: {
          request_id: samples.request_id, status: 0, box: samples.samples.box,
          densities: Uint8Array.from([1, 0, 0xfe, 0xff, 0x2c, 0x01, 0x01, 0x80]), materials: Uint8Array.from([3, 0, 4, 0]),
        },
      });
      send({ query_result: { request_id: ground.request_id, status: 0, hit: true, point: { x: 5, y: 7.5, z: 6 }, normal: { x: 0, y: 1, z: 0 }, material: 2, distance: 92.5 } });
      send({ query_result: { request_id: ray.request_id, status: 1, reason: "the raycast's direction has no length" } });
    }
    if (held.length === 4) socket.close();
  });
  const client = new Client(await connectWebSocket(server.url, { WebSocket }), { keepaliveMs: 0 });
  try {
    await assert.rejects(client.ground(0, 0, 1, 1), /before hello/);
    const w = await client.hello();
    assert.equal(w.maxQuerySamples, 32768);
    assert.equal(w.queriesPerSecond, 20);
    const seen = [];
    client.on("queryresult", (r) => seen.push(r.requestId));
    const ray = client.raycast([1, 2, 3], [0, 0, 0], 10);
    const ground = client.ground(5, 6, 100);
    const samples = client.samples([10, -1, 4], [11, 0, 4]);
    const [r, g, s] = await Promise.all([ray, ground, samples]);
    assert.equal(r.statusName, "BAD_VALUE");
    assert.match(r.reason, /no length/);
    assert.equal(r.hit, false);
    assert.equal(g.statusName, "OK");
    assert.deepEqual([g.hit, g.point, g.material, g.distance], [true, { x: 5, y: 7.5, z: 6 }, 2, 92.5]);
    assert.equal(s.statusName, "OK");
    assert.deepEqual(s.size, [2, 2, 1]);
    assert.deepEqual([...s.densities], [1, -2, 300, -32767]);
    assert.deepEqual([...s.materials], [3, 0, 4, 0]);
    assert.equal(s.index(11, 0, 4), 3);
    assert.equal(seen.length, 3);
    assert.deepEqual([r.requestId, g.requestId, s.requestId], [1n, 2n, 3n]);
    // What went out: the fields of proto/voxel.proto, the ground's depth defaulted to Welcome's.
    const sent = server.received.filter((x) => x.kind === "query").map((x) => x.message);
    assert.deepEqual(sent.map((q) => q.kind), ["raycast", "ground", "samples"]);
    const d = sent[0].raycast.direction;
    assert.deepEqual([d.x, d.y, d.z], [0, 0, 0]);
    assert.equal(sent[0].raycast.max_distance, 10);
    assert.equal(sent[1].ground.from_y, 100);
    assert.equal(sent[1].ground.max_depth, 512);
    const box = sent[2].samples.box;
    assert.deepEqual([box.min_x, box.min_y, box.min_z, box.max_x, box.max_y, box.max_z], [10, -1, 4, 11, 0, 4]);
    assert.throws(() => client.query("dig", {}), /unknown query kind "dig"/);
    await assert.rejects(client.samples([0, 0, 0], [1.5, 0, 0]), /integer/);
    // The connection ends with a query waiting: it is rejected.
    await assert.rejects(client.raycast([0, 0, 0], [0, -1, 0], 1), /connection closed|closed/);
  } finally {
    client.close();
    await server.close();
  }
});

test("a server without queries (no max_query_distance in Welcome): queries refused at once", async () => {
  const server = await fakeServer((kind, m, send) => {
    if (kind === "hello") send(welcome());
  });
  const client = new Client(await connectWebSocket(server.url, { WebSocket }), { keepaliveMs: 0 });
  try {
    await client.hello();
    await assert.rejects(client.raycast([0, 0, 0], [0, -1, 0], 1), /answers no queries/);
    assert.equal(server.received.filter((x) => x.kind === "query").length, 0);
  } finally {
    client.close();
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
