// The decoder against the C++ codec (clients/web/tools/mesh_fixtures.cpp): for terrain
// chunks in format 1, an empty and a full chunk, an odd-sized block, chunks with dropped
// triangles and level-of-detail chunks in format 2 with and without seams, the JS decoder
// gives the C++ decoder's positions and normals (float32 bits), materials and indices
// exactly. The server's zstd frames, full and delta, decompress to its encoding.
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { after, before, test } from "node:test";
import { ChunkCache } from "../src/chunks.js";
import { decompressDelta, decompressFull } from "../src/compression.js";
import { decodeMesh, MeshDecodeError } from "../src/mesh.js";
import { fixCrc, putU32 } from "./helpers.js";
import { findTool } from "./tools.js";

const tool = findTool("VOXEL_MESH_FIXTURES", "voxel_mesh_fixtures");
const skip = tool ? false : "voxel_mesh_fixtures not built (VOXEL_MESH_FIXTURES unset)";
let dir;
let names = [];
const fixture = (name) => ({
  bin: new Uint8Array(readFileSync(join(dir, `${name}.bin`))),
  want: JSON.parse(readFileSync(join(dir, `${name}.json`), "utf8")),
});

before(() => {
  if (!tool) return;
  dir = mkdtempSync(join(tmpdir(), "voxel-fixtures-"));
  execFileSync(tool, [dir], { timeout: 60000, stdio: ["ignore", "ignore", "inherit"] });
  names = JSON.parse(readFileSync(join(dir, "manifest.json"), "utf8")).fixtures;
});
after(() => {
  if (dir) rmSync(dir, { recursive: true, force: true });
});

test("the fixtures cover what they should", { skip }, () => {
  const all = names.map((n) => fixture(n).want);
  assert.ok(all.some((w) => w.format === 1 && w.triangle_count > 500), "a terrain chunk");
  assert.ok(all.some((w) => w.name === "empty_sky" && w.vertex_count === 0));
  assert.ok(all.some((w) => w.name === "full_rock" && w.vertex_count === 0));
  assert.ok(all.some((w) => w.cells.join() === "5,7,3"));
  assert.ok(all.some((w) => w.format === 1 && w.dropped > 0), "dropped triangles, format 1");
  assert.ok(all.filter((w) => w.format === 2 && /_f00_e000$/.test(w.name)).length >= 1, "format 2 without seams");
  assert.ok(all.filter((w) => w.format === 2 && !/_f00_e000$/.test(w.name)).length >= 3, "format 2 with seams");
});

test("every fixture decodes to the C++ decoder's mesh", { skip }, () => {
  for (const name of names) {
    const { bin, want } = fixture(name);
    const m = decodeMesh(bin);
    assert.equal(m.format, want.format, name);
    assert.deepEqual(m.cells, want.cells, name);
    assert.equal(m.vertexCount, want.vertex_count, name);
    assert.equal(m.triangleCount, want.triangle_count, name);
    assert.equal(m.droppedCount, want.dropped, name);
    assert.deepEqual([...new Uint32Array(m.positions.buffer)], want.positions, `${name}: positions, float32 bits`);
    assert.deepEqual([...m.materials], want.materials, `${name}: materials`);
    assert.deepEqual([...m.indices], want.indices, `${name}: indices`);
    assert.deepEqual([...new Uint32Array(m.normals.buffer)], want.normals, `${name}: normals, float32 bits`);
  }
});

test("all 65,536 octahedral normals are the C++ decode_normal's, bit for bit", { skip }, () => {
  const raw = readFileSync(join(dir, "normals.bin"));
  const want = new Float32Array(raw.buffer.slice(raw.byteOffset, raw.byteOffset + raw.length));
  // Decode each (u, v) through a one-vertex format-1 mesh: the worked example with its normal bytes replaced.
  const ex = Uint8Array.from(Buffer.from("01010101030000000100000000000000030101000000020202bf9f9f9fbf9f030000e42739aa", "hex"));
  const bits = new Uint32Array(want.buffer);
  for (let u = 0; u < 256; u++) {
    for (let v = 0; v < 256; v++) {
      ex[25] = u;
      ex[28] = v;
      const n = new Uint32Array(decodeMesh(fixCrc(ex)).normals.buffer);
      for (let j = 0; j < 3; j++) {
        const w = bits[3 * (256 * u + v) + j];
        if (n[j] !== w) assert.fail(`(${u}, ${v})[${j}]: bits ${n[j].toString(16)}, C++ ${w.toString(16)}`);
      }
    }
  }
});

test("every truncation of a seamed format-2 chunk is refused; so is a seam index past the end", { skip }, () => {
  const name = names.find((n) => n.startsWith("lod") && !n.endsWith("_f00_e000"));
  const { bin } = fixture(name);
  for (let n = 0; n < bin.length; n += 1 + (n >> 6)) {
    assert.throws(() => decodeMesh(bin.subarray(0, n)), MeshDecodeError, `${name}: length ${n}`);
  }
  const m = decodeMesh(bin);
  const ST = m.triangleCount - m.regularTriangleCount;
  assert.ok(ST > 0);
  const bad = bin.slice();
  putU32(bad, bad.length - 8, m.vertexCount);  // the last seam triangle's last index
  assert.throws(() => decodeMesh(fixCrc(bad)), /seam triangle \d+: vertex \d+ past/);
  // A regular triangle count one off.
  const off = bin.slice();
  putU32(off, 8, m.regularTriangleCount + 1);
  assert.throws(() => decodeMesh(fixCrc(off)), /triangle_count/);
});

test("the server's zstd frames: a full message and a delta against a raw prefix", { skip }, () => {
  const d = JSON.parse(readFileSync(join(dir, "delta.json"), "utf8"));
  const h = (s) => Uint8Array.from(Buffer.from(s, "hex"));
  const encoding = h(d.encoding);
  const base = h(d.base);
  assert.deepEqual(decompressFull(h(d.full_frame)), encoding);
  assert.deepEqual(decompressDelta(h(d.delta_frame), base), encoding);
  decodeMesh(encoding);
  // The same delta against the wrong base: garbage that the CRC refuses (or zstd itself).
  assert.throws(() => decodeMesh(decompressDelta(h(d.delta_frame), encoding)));
  assert.throws(() => decodeMesh(decompressFull(h(d.delta_frame))));
});

test("chunk cache: full copy, delta, a delta that does not apply drops the chunk until its full copy", { skip }, () => {
  const d = JSON.parse(readFileSync(join(dir, "delta.json"), "utf8"));
  const h = (s) => Uint8Array.from(Buffer.from(s, "hex"));
  const cache = new ChunkCache();
  const coord = { x: 1, y: -2, z: 3 };
  // Version 3 is the base (its full frame: the base is made a full copy by hand, raw block).
  const base = h(d.base);
  const rawFull = (content) => {
    const n = content.length;
    const blk = (n << 3) | 1;
    return Uint8Array.from([0x28, 0xb5, 0x2f, 0xfd, 0xa0, n & 255, (n >> 8) & 255, n >> 16, 0, blk & 255, (blk >> 8) & 255, blk >> 16, ...content]);
  };
  assert.equal(cache.apply({ coord, version: 3, base_version: 0, payload: rawFull(base) }).kind, "added");
  const up = cache.apply({ coord, version: 7, base_version: 3, payload: h(d.delta_frame) });
  assert.equal(up.kind, "updated");
  assert.equal(up.chunk.version, 7n);
  assert.deepEqual(up.chunk.encoding, h(d.encoding));
  // A delta against version 5, which is not held: dropped, to be resynced.
  const bad = cache.apply({ coord, version: 9, base_version: 5, payload: h(d.delta_frame) });
  assert.equal(bad.kind, "failed");
  assert.match(bad.error.message, /version 5, version 7 held/);
  assert.equal(cache.chunks.size, 0);
  assert.ok(cache.resyncing.has("0:1,-2,3"));
  assert.equal(cache.apply({ coord, version: 9, base_version: 7, payload: h(d.delta_frame) }).kind, "ignored");
  assert.equal(cache.apply({ coord, version: 9, base_version: 0, payload: h(d.full_frame) }).kind, "added");
  assert.equal(cache.resyncing.size, 0);
  // The same coordinate at level 2 is another chunk.
  assert.equal(cache.apply({ coord, level: 2, version: 1, base_version: 0, payload: h(d.full_frame) }).kind, "added");
  assert.equal(cache.chunks.get("2:1,-2,3").scale, 4);
  assert.deepEqual(cache.chunks.get("2:1,-2,3").origin, [128, -256, 384]);
  assert.equal(cache.unload(2, [coord]).length, 1);
  assert.equal(cache.chunks.size, 1);
});
