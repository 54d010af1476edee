// The mesh decoder on the page's own example and on broken encodings (PROTOCOL §2).
import assert from "node:assert/strict";
import { test } from "node:test";
import { crc32c } from "../src/crc32c.js";
import { decodeMesh, MeshDecodeError, seamCells } from "../src/mesh.js";
import { DEFAULT_TABLE, parseTable } from "../src/table.js";
import { fixCrc, format2, putU32, WORKED_EXAMPLE } from "./helpers.js";

const refuses = (bytes, pattern) => assert.throws(() => decodeMesh(bytes), (e) => e instanceof MeshDecodeError && (!pattern || pattern.test(e.message)), pattern?.toString());

test("CRC-32C check value of §2.1", () => {
  assert.equal(crc32c(new TextEncoder().encode("123456789")), 0xe3069283);
});

test("table: revision 2 and 256 cases, the masks agree with the corners", () => {
  assert.equal(DEFAULT_TABLE.revision, 2);
  assert.equal(DEFAULT_TABLE.edgeMask[1], 0x109);
  assert.deepEqual([...DEFAULT_TABLE.edges.subarray(DEFAULT_TABLE.offset[1], DEFAULT_TABLE.offset[2])], [0, 3, 8]);
  assert.throws(() => parseTable("0 0x000\n"), /case 1 missing/);
  const allEmpty = Array.from({ length: 256 }, (_, c) => `${c} 0x000`).join("\n");
  assert.throws(() => parseTable(allEmpty), /case 1 has mask 0x0, its corners cut 0x109/);
});

test("worked example of §2.6, bit for bit", () => {
  assert.equal(WORKED_EXAMPLE.length, 38);
  const m = decodeMesh(WORKED_EXAMPLE);
  assert.equal(m.format, 1);
  assert.deepEqual(m.cells, [1, 1, 1]);
  assert.equal(m.vertexCount, 3);
  assert.equal(m.triangleCount, 1);
  assert.deepEqual([...m.positions], [0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5]);
  assert.deepEqual([...m.materials], [3, 3, 3]);
  assert.deepEqual([...m.indices], [0, 1, 2]);
  // Vertex 0's normal, (0.81, 0.40, 0.42) to the page's two digits.
  assert.deepEqual([...m.normals.subarray(0, 3)].map((c) => c.toFixed(2)), ["0.81", "0.40", "0.42"]);
  for (let i = 0; i < 3; i++) {
    const [x, y, z] = m.normals.subarray(3 * i, 3 * i + 3);
    assert.ok(Math.abs(Math.hypot(x, y, z) - 1) < 1e-6);
  }
});

test("every truncation and every extension of the worked example is refused", () => {
  for (let n = 0; n < WORKED_EXAMPLE.length; n++) refuses(WORKED_EXAMPLE.subarray(0, n));
  const longer = new Uint8Array(39);
  longer.set(WORKED_EXAMPLE);
  refuses(longer, /39 bytes, but the header and bitmap make 38/);
  refuses(fixCrc(longer), /39 bytes/);
});

test("a flipped bit anywhere is refused by the CRC", () => {
  for (let i = 0; i < WORKED_EXAMPLE.length * 8; i++) {
    const b = WORKED_EXAMPLE.slice();
    b[i >> 3] ^= 1 << (i & 7);
    refuses(b);
  }
});

test("structural rules with the CRC fixed up", () => {
  const mutate = (f) => {
    const b = WORKED_EXAMPLE.slice();
    f(b);
    return fixCrc(b);
  };
  refuses(mutate((b) => { b[0] = 3; }), /unknown format 3/);
  refuses(mutate((b) => { b[1] = 0; }), /cells/);
  refuses(mutate((b) => { b[2] = 33; }), /cells/);
  refuses(mutate((b) => { putU32(b, 8, 2); }), /triangle_count 2/);
  refuses(mutate((b) => { putU32(b, 8, 0); }), /more table triangles/);
  refuses(mutate((b) => { b[22] = 5; }), /fraction 1280 over 1024/);
  refuses(mutate((b) => { b[17] = 0x04; }), /bits above cells_x/);   // bit 2 > cells_x = 1
  refuses(mutate((b) => { b[17] = 0x00; }), /difference is zero/);
  refuses(mutate((b) => { b[16] = 0x13; }), /past the last row|bytes, but/);
});

test("vertex_count that is not the number of cut edges", () => {
  // Same bytes, V = 2 and one vertex plane byte less each: the length rule holds, the count does not.
  const b = new Uint8Array(33);
  b.set(WORKED_EXAMPLE.subarray(0, 19));
  putU32(b, 4, 2);
  b.set([0, 0, 2, 2, 0xbf, 0x9f, 0x9f, 0xbf, 3, 0], 19);
  refuses(fixCrc(b), /vertex_count 2, but the rows cut 3 edges/);
});

test("dropped ordinals: past the table triangles, not increasing", () => {
  // D = 1 dropping ordinal 0: T must be 0.
  const withDrop = (T, ords) => {
    const b = new Uint8Array(38 + 4 * ords.length);
    b.set(WORKED_EXAMPLE.subarray(0, 34));
    putU32(b, 8, T);
    putU32(b, 12, ords.length);
    ords.forEach((o, i) => putU32(b, 34 + 4 * i, o));
    return fixCrc(b);
  };
  assert.equal(decodeMesh(withDrop(0, [0])).triangleCount, 0);
  refuses(withDrop(1, [1]), /dropped ordinal 1 is not a table triangle/);
  refuses(withDrop(0, [0, 0]), /strictly increasing/);
});

test("huge counts are refused by the length rule before any allocation", () => {
  const b = WORKED_EXAMPLE.slice();
  putU32(b, 4, 0xffffffff);
  refuses(fixCrc(b), /bytes, but the header/);
  const c = WORKED_EXAMPLE.slice();
  putU32(c, 12, 0xfffffff0);
  refuses(fixCrc(c), /bytes, but the header/);
  refuses(new Uint8Array(5 << 20), /over the limit/);
});

test("format 2: seam vertices, triangles and their checks (§2.7)", () => {
  const seam = [[0, 0, 0, 0, 512, 128, 128, 4], [0, 0, 0, 1, 1024, 128, 255, 0], [0, 0, 0, 2, 0, 128, 128, 1]];
  const m = decodeMesh(format2({ seam, tris: [[0, 1, 2]] }));
  assert.equal(m.format, 2);
  assert.equal(m.vertexCount, 3);
  assert.deepEqual([...m.positions], [0.25, 0, 0, 0, 0.5, 0, 0, 0, 0]);
  assert.deepEqual([...m.materials], [4, 4, 5]);
  assert.deepEqual([...m.indices], [0, 1, 2]);
  refuses(format2({ seam, tris: [[0, 1, 3]] }), /vertex 3 past 3/);
  refuses(format2({ seam: [[65, 0, 0, 1, 0, 0, 0, 1]] }), /past 64/);
  refuses(format2({ seam: [[64, 0, 0, 0, 0, 0, 0, 1]] }), /leaves the chunk/);
  refuses(format2({ seam: [[0, 0, 0, 3, 0, 0, 0, 1]] }), /axis 3/);
  refuses(format2({ seam: [[0, 0, 0, 0, 1025, 0, 0, 1]] }), /fraction 1025/);
  refuses(format2({ faces: 0x40 }), /bits 6-7/);
  refuses(format2({ edges: 0x1000 }), /bits 12-15/);
  refuses(format2({ faces: 1, edges: 0 }), /not normalized/);
  const big = format2();
  putU32(big, 19, 50689);
  refuses(fixCrc(big), /seam vertices, over 50688/);
  putU32(big, 19, 0);
  putU32(big, 23, 294913);
  refuses(fixCrc(big), /seam triangles, over 294912/);
  const cells = format2();
  cells[1] = 31;
  refuses(fixCrc(cells), /format 2 with cells/);
});

test("seam cells: a face marks its layer, an edge its line of cells", () => {
  const face = seamCells(1, 0b0000_0101_0101_0000 & 0);  // -x face alone (edges not needed here)
  assert.equal(face[0], 1);
  assert.equal(face[31 + 32 * 31], 1);
  const edge = seamCells(0, 1 << 0);  // x-edge at y = 0, z = 0
  assert.equal(edge[0], 0xffffffff);
  assert.equal(edge[1], 0);
  const zEdge = seamCells(0, 1 << 11);  // z-edge at x = 32, y = 32
  assert.equal(zEdge[31 + 32 * 5], 0x80000000);
  assert.equal(zEdge[30 + 32 * 5], 0);
});
