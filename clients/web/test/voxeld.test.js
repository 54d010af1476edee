// End to end against a real voxeld over TCP (started here on port 0, in memory, in a
// temporary directory; killed at the end, also on failure): Hello, a radius-2 view up to
// ViewReady, an explosion ACCEPTED whose deltas change held chunks, a second client that
// sees the first one's edit, every other edit kind, Ping, and a level-of-detail view whose
// format-2 chunks decode.
import assert from "node:assert/strict";
import { spawn } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { after, before, test } from "node:test";
import { Client } from "../src/client.js";
import { connectTcp } from "../src/transport_tcp.js";
import { findTool } from "./tools.js";

const voxeld = findTool("VOXELD", "voxeld");
const skip = voxeld ? false : "voxeld not built (VOXELD unset)";
let server;
let dir;
let port;
let serverLog = "";
const clients = [];

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

before(async () => {
  if (!voxeld) return;
  dir = mkdtempSync(join(tmpdir(), "voxeld-web-"));
  const portFile = join(dir, "port");
  server = spawn(voxeld, ["--port", "0", "--port-file", portFile, "--in-memory", "--seed", "1", "--threads", "2"], {
    cwd: dir, stdio: ["ignore", "pipe", "pipe"],
  });
  server.stdout.on("data", (d) => { serverLog += d; });
  server.stderr.on("data", (d) => { serverLog += d; });
  process.on("exit", () => server?.kill("SIGKILL"));
  const deadline = Date.now() + 20000;
  while (!port) {
    if (server.exitCode !== null) throw new Error(`voxeld exited ${server.exitCode}: ${serverLog}`);
    if (Date.now() > deadline) throw new Error(`voxeld wrote no port file in 20 s: ${serverLog}`);
    try {
      port = Number(readFileSync(portFile, "utf8").trim()) || undefined;
    } catch {}
    if (!port) await sleep(50);
  }
});

after(async () => {
  for (const c of clients) c.close();
  if (server && server.exitCode === null) {
    server.kill("SIGKILL");
    await new Promise((r) => server.once("exit", r));
  }
  if (dir) rmSync(dir, { recursive: true, force: true });
});

async function connect(name) {
  const client = new Client(await connectTcp("127.0.0.1", port), { keepaliveMs: 0 });
  clients.push(client);
  client.failures = [];
  client.deltas = 0;
  client.on("chunkfailed", (key, error) => client.failures.push(`${key}: ${error.message}`));
  client.on("message", (kind, m) => {
    if (kind === "chunk_mesh" && Number(m.base_version) !== 0) client.deltas++;
  });
  const welcome = await client.hello({ playerName: name });
  return { client, welcome };
}

// A point on the surface: a vertex of the held chunk with the most triangles, in world voxels.
function surfacePoint(client) {
  let best;
  for (const c of client.chunks.values()) if (c.level === 0 && (!best || c.mesh.triangleCount > best.mesh.triangleCount)) best = c;
  const p = best.mesh.positions;
  return [best.origin[0] + p[0], best.origin[1] + p[1], best.origin[2] + p[2]];
}

// Resolves when `pred(chunk)` holds for an added or updated chunk, or rejects after ms.
function waitChunk(client, pred, ms, what) {
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => { off1(); off2(); reject(new Error(`no ${what} in ${ms} ms`)); }, ms);
    const check = (chunk, previous) => {
      if (!pred(chunk, previous)) return;
      clearTimeout(timer); off1(); off2(); resolve(chunk);
    };
    const off1 = client.on("chunkupdated", check);
    const off2 = client.on("chunkadded", (c) => check(c, undefined));
  });
}

test("two clients: view, explosion, deltas on both, every edit kind, ping", { skip, timeout: 90000 }, async () => {
  const { client: a, welcome } = await connect("web-a");
  assert.equal(welcome.protocolVersion, 1);
  assert.equal(welcome.meshTableRevision, 2);
  assert.equal(welcome.chunkSize, 32);
  assert.ok(welcome.maxResyncChunks > 0);
  const position = [16, 16, 16];
  const view = a.setView({ position, radius: 2 });
  const ready = await a.waitViewReady(view, { timeoutMs: 60000 });
  assert.equal(ready.radius, 2);
  assert.equal(ready.chunksSent + ready.chunksEmpty, 33, "a radius-2 ball holds 33 chunks");
  const held = [...a.chunks.values()].filter((c) => c.level === 0);
  assert.equal(held.length, ready.chunksSent);
  assert.ok(held.length > 0, "chunks held");
  assert.ok(held.some((c) => c.mesh.triangleCount > 0), "chunks with triangles");
  assert.deepEqual(a.failures, []);

  const { client: b } = await connect("web-b");
  await b.waitViewReady(b.setView({ position, radius: 2 }), { timeoutMs: 60000 });
  assert.equal(b.chunks.size, a.chunks.size);

  const center = surfacePoint(a);
  const versionsA = new Map([...a.chunks].map(([k, c]) => [k, c.version]));
  const versionsB = new Map([...b.chunks].map(([k, c]) => [k, c.version]));
  const changedA = waitChunk(a, (c) => versionsA.has(c.key) && c.version > versionsA.get(c.key), 20000, "changed chunk on A");
  const changedB = waitChunk(b, (c) => versionsB.has(c.key) && c.version > versionsB.get(c.key), 20000, "changed chunk on B");
  const result = await a.edit("explosion", { center, radius: 4, power: 2 }, { timeoutMs: 20000 });
  assert.equal(result.statusName, "ACCEPTED", result.reason);
  assert.ok(result.changedChunks.length > 0);
  const chunkA = await changedA;
  const chunkB = await changedB;
  assert.ok(chunkA.version > versionsA.get(chunkA.key));
  assert.ok(chunkB.version > versionsB.get(chunkB.key), "B sees A's edit");
  assert.ok(a.deltas > 0 && b.deltas > 0, "the changes came as deltas");

  // Every edit kind of the proto, each answered; then a refused one.
  const [x, y, z] = center;
  const kinds = [
    ["brush", { center: [x, y, z], radius: 3, strength: 1, material: 4 }],
    ["brush", { center: [x, y, z], radius: 2, strength: 1, remove: true }],
    ["smooth", { center: [x, y, z], radius: 3, strength: 0.5 }],
    ["paint", { center: [x, y, z], radius: 3, material: 2 }],
    ["stamp", { shape: "box", min: [x - 2, y - 2, z - 2], max: [x + 2, y + 2, z + 2], solid: true, material: 3 }],
    ["stamp", { shape: "sphere", center: [x, y + 3, z], radius: 2, solid: false }],
  ];
  for (const [kind, params] of kinds) {
    const r = await a.edit(kind, params, { timeoutMs: 20000 });
    assert.equal(r.statusName, "ACCEPTED", `${kind}: ${r.reason}`);
  }
  const refused = await a.edit("explosion", { center: [x, y, z], radius: 0, power: 1 }, { timeoutMs: 20000 });
  assert.equal(refused.statusName, "BAD_RADIUS");
  assert.ok((await a.ping({ timeoutMs: 10000 })) >= 0);

  // After the edits settle, both clients hold the same versions' meshes, and nothing failed.
  await a.waitViewReady(a.setView({ position, radius: 2 }), { timeoutMs: 30000 });
  await b.waitViewReady(b.setView({ position, radius: 2 }), { timeoutMs: 30000 });
  await sleep(300);
  assert.deepEqual(a.failures, []);
  assert.deepEqual(b.failures, []);
  for (const [key, chunk] of a.chunks) {
    const other = b.chunk(chunk.level, chunk.coord.x, chunk.coord.y, chunk.coord.z);
    assert.ok(other, key);
    assert.deepEqual(other.encoding, chunk.encoding, `${key}: same encoding on both clients`);
  }
});

test("a level-of-detail view: format-2 chunks keyed by level", { skip, timeout: 90000 }, async () => {
  const { client, welcome } = await connect("web-lod");
  assert.ok(welcome.maxLodLevel >= 2);
  const view = client.setView({ position: [16, 16, 16], radius: 1, lodLevel: 2 });
  const ready = await client.waitViewReady(view, { timeoutMs: 60000 });
  const coarse = [...client.chunks.values()].filter((c) => c.level > 0);
  assert.equal(coarse.length, ready.lodChunksSent);
  assert.ok(coarse.length > 0);
  assert.ok(coarse.every((c) => c.mesh.format === 2));
  assert.ok(coarse.some((c) => c.mesh.seamFaces || c.mesh.seamEdges), "some chunk has seams");
  assert.ok(coarse.some((c) => c.level === 2));
  // Back to level 0: the coarse chunks are unloaded.
  const unloaded = [];
  client.on("chunkunloaded", (c) => unloaded.push(c));
  await client.waitViewReady(client.setView({ position: [16, 16, 16], radius: 1 }), { timeoutMs: 60000 });
  await sleep(200);
  assert.equal([...client.chunks.values()].filter((c) => c.level > 0).length, 0);
  assert.ok(unloaded.some((c) => c.level > 0));
  assert.deepEqual(client.failures, []);
});

test("the server's Error closes the connection and rejects what waits", { skip, timeout: 30000 }, async () => {
  const client = new Client(await connectTcp("127.0.0.1", port), { keepaliveMs: 0 });
  clients.push(client);
  await assert.rejects(client.hello({ playerName: "" }), /BAD_VALUE/);
  await new Promise((r) => (client.closed ? r() : client.on("close", r)));
  assert.ok(client.closed);
});
