// End to end against a real voxeld over TCP (started here on port 0, in memory, in a
// temporary directory; killed at the end, also on failure): Hello, a radius-2 view up to
// ViewReady, an explosion ACCEPTED whose deltas change held chunks, a second client that
// sees the first one's edit, every other edit kind, Ping, a level-of-detail view whose
// format-2 chunks decode, and queries (§4.13: ground, raycast, samples) with an edit's
// material yield (§4.4 volumes).
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

// Asks again while the server says to (terrain loaded over several tries, or the rate).
async function ask(fn) {
  for (let i = 0; ; i++) {
    const r = await fn();
    if (!["SERVER_BUSY", "RATE_LIMITED"].includes(r.statusName) || i === 20) return r;
    await sleep(Math.max(r.retryAfterMs, 10));
  }
}

const near = (a, b, eps, what) => assert.ok(Math.abs(a - b) <= eps, `${what}: ${a} vs ${b}`);

// First, on terrain no other test has edited yet.
test("queries: ground, raycast, samples, an explosion's volumes, BAD_VALUE", { skip, timeout: 90000 }, async () => {
  const { client, welcome } = await connect("web-query");
  assert.ok(welcome.maxQueryDistance >= 400, `max_query_distance ${welcome.maxQueryDistance}`);
  assert.ok(welcome.maxQuerySamples >= 120);
  assert.ok(welcome.maxQueriesInFlight > 0);
  assert.ok(welcome.queriesPerSecond >= 0);
  const t = { timeoutMs: 20000 };

  // Ground under (0, 0), from high above.
  const g = await ask(() => client.ground(0, 0, 200, 400, t));
  assert.equal(g.statusName, "OK", g.reason);
  assert.equal(g.hit, true);
  assert.equal(g.point.x, 0);
  assert.equal(g.point.z, 0);
  assert.ok(g.point.y < 200 && g.point.y > -200);
  assert.ok(g.normal.y > 0, `normal ${JSON.stringify(g.normal)}`);
  near(Math.hypot(g.normal.x, g.normal.y, g.normal.z), 1, 1e-4, "|normal|");
  near(g.distance, 200 - g.point.y, 1e-3, "distance");
  assert.ok(g.material >= 1 && g.material <= 255);

  // A ray straight down agrees (also with a direction not of unit length); one upward misses.
  for (const dir of [[0, -1, 0], [0, -5, 0]]) {
    const r = await ask(() => client.raycast([0, 200, 0], dir, 400, t));
    assert.equal(r.statusName, "OK", r.reason);
    assert.equal(r.hit, true);
    for (const k of ["x", "y", "z"]) near(r.point[k], g.point[k], 1e-3, `ray point ${k}`);
    near(r.distance, g.distance, 1e-3, "ray distance");
    assert.equal(r.material, g.material);
  }
  const up = await ask(() => client.raycast([0, g.point.y + 1, 0], [0, 1, 0], 400, t));
  assert.equal(up.statusName, "OK", up.reason);
  assert.equal(up.hit, false);

  // Samples of a 4×5×6 box around the ground point: sizes, the box echoed, and the column
  // (0, y, 0) solid below the ground point and air above, crossing where ground says.
  const y0 = Math.floor(g.point.y);
  const s = await ask(() => client.samples([-2, y0 - 2, -3], [1, y0 + 2, 2], t));
  assert.equal(s.statusName, "OK", s.reason);
  assert.deepEqual(s.box, { minX: -2, minY: y0 - 2, minZ: -3, maxX: 1, maxY: y0 + 2, maxZ: 2 });
  assert.deepEqual(s.size, [4, 5, 6]);
  assert.ok(s.densities instanceof Int16Array);
  assert.ok(s.materials instanceof Uint8Array);
  assert.equal(s.densities.length, 120);
  assert.equal(s.materials.length, 120);
  for (let y = y0 - 2; y <= y0 + 2; y++) {
    const i = s.index(0, y, 0);
    const solid = s.densities[i] > 0;
    assert.equal(solid, y <= y0, `sample (0, ${y}, 0): density ${s.densities[i]}`);
    assert.equal(s.materials[i] !== 0, solid, `sample (0, ${y}, 0): material ${s.materials[i]}`);
  }
  const d0 = s.densities[s.index(0, y0, 0)];
  const d1 = s.densities[s.index(0, y0 + 1, 0)];
  near(g.point.y, y0 + d0 / (d0 - d1), 1 / 1024, "the crossing between the two samples");

  // The surface is the drawn one: the held level-0 meshes have a vertex at the ground point.
  await client.waitViewReady(client.setView({ position: [0, g.point.y, 0], radius: 1 }), { timeoutMs: 60000 });
  let vertex;
  for (const c of client.chunks.values()) {
    const p = c.mesh.positions;
    for (let i = 0; i < p.length && !vertex; i += 3) {
      if (c.origin[0] + p[i] === 0 && c.origin[2] + p[i + 2] === 0 && Math.abs(c.origin[1] + p[i + 1] - g.point.y) < 1e-6) {
        vertex = { normal: c.mesh.normals.subarray(i, i + 3), material: c.mesh.materials[i / 3] };
      }
    }
  }
  assert.ok(vertex, "a mesh vertex at the ground point");
  assert.equal(vertex.material, g.material);
  const dot = vertex.normal[0] * g.normal.x + vertex.normal[1] * g.normal.y + vertex.normal[2] * g.normal.z;
  assert.ok(dot > 0.999, `the vertex's normal within 2.5° of the query's (cos ${dot})`);

  // An explosion at the ground point: its volumes are what the samples say (§4.4).
  const c = [g.point.x, g.point.y, g.point.z];
  const lo = [-6, y0 - 6, -6];
  const hi = [6, y0 + 6, 6];
  const before = await ask(() => client.samples(lo, hi, t));
  const e = await client.edit("explosion", { center: c, radius: 4, power: 2 }, t);
  assert.equal(e.statusName, "ACCEPTED", e.reason);
  const after = await ask(() => client.samples(lo, hi, t));
  assert.equal(before.statusName, "OK");
  assert.equal(after.statusName, "OK");
  assert.ok(e.volumes.length > 0, "volumes listed");
  assert.ok(e.volumes.some((v) => v.removed > 0), "an explosion removes some material");
  for (const [i, v] of e.volumes.entries()) {
    assert.ok(v.material >= 1 && v.material <= 255);
    assert.ok(v.removed >= 0 && v.added >= 0);
    if (i) assert.ok(v.material > e.volumes[i - 1].material, "in material order");
  }
  const expected = new Map();
  const put = (m, key, amount) => {
    if (!m || !amount) return;
    const v = expected.get(m) ?? { material: m, removed: 0n, added: 0n };
    v[key] += amount;
    expected.set(m, v);
  };
  for (let i = 0; i < before.densities.length; i++) {
    const ob = BigInt(before.densities[i] + 32767);
    const oa = BigInt(after.densities[i] + 32767);
    const mb = before.materials[i];
    const ma = after.materials[i];
    if (mb === ma) put(ma, oa > ob ? "added" : "removed", oa > ob ? oa - ob : ob - oa);
    else {
      put(mb, "removed", ob);
      put(ma, "added", oa);
    }
  }
  const mine = [...expected.values()].sort((a, b) => a.material - b.material);
  assert.deepEqual(e.volumes.map((v) => v.material), mine.map((v) => v.material));
  for (const [i, v] of e.volumes.entries()) {
    near(v.removed, Number(mine[i].removed) / 65534, 1e-9, `material ${v.material} removed`);
    near(v.added, Number(mine[i].added) / 65534, 1e-9, `material ${v.material} added`);
  }
  // A query sent after the edit sees it.
  const g2 = await ask(() => client.ground(0, 0, 200, 400, t));
  assert.equal(g2.hit, true);
  assert.ok(g2.point.y < g.point.y, `ground went down: ${g.point.y} -> ${g2.point.y}`);

  // Refused: a direction of no length, a box over the sample cap (its fields empty).
  const zero = await client.raycast([0, 200, 0], [0, 0, 0], 100, t);
  assert.equal(zero.statusName, "BAD_VALUE");
  assert.ok(zero.reason.length > 0);
  assert.equal(zero.hit, false);
  const side = Math.ceil(Math.cbrt(welcome.maxQuerySamples)) + 1;
  const big = await client.samples([0, 0, 0], [side - 1, side - 1, side - 1], t);
  assert.equal(big.statusName, "BAD_VALUE");
  assert.ok(big.reason.length > 0);
  assert.deepEqual(big.size, [0, 0, 0]);
  assert.equal(big.densities.length, 0);
  assert.equal(big.materials.length, 0);
  const far = await client.raycast([0, 200, 0], [0, -1, 0], welcome.maxQueryDistance * 2, t);
  assert.equal(far.statusName, "BAD_VALUE");
  assert.deepEqual(client.failures, []);
});

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
