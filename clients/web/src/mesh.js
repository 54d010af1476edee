// Chunk mesh decoding, formats 1 and 2 (PROTOCOL §2). Never trusts the bytes: the total
// length is checked against the header before anything is allocated from a count, the
// CRC-32C before anything is decoded, and every rule of §2 after; any failure throws a
// MeshDecodeError saying which.
import { crc32c } from "./crc32c.js";
import { DEFAULT_TABLE } from "./table.js";

/** An encoding that breaks a rule of PROTOCOL §2. */
export class MeshDecodeError extends Error {
  constructor(message) {
    super(`mesh: ${message}`);
    this.name = "MeshDecodeError";
  }
}

/** Largest encoding decoded by default (voxeld's own limit, §3). */
export const MAX_ENCODING_BYTES = 4 << 20;
/** Format-2 limits (§2.7). */
export const MAX_SEAM_VERTICES = 50688;
export const MAX_SEAM_TRIANGLES = 294912;

/**
 * A decoded chunk mesh. Positions are local to the chunk, in its cells (0..32): a level-k
 * chunk's world position is 32·2^k·coord + 2^k·position (§2.7, §4.10).
 * @typedef {object} DecodedMesh
 * @property {1|2} format
 * @property {[number, number, number]} cells
 * @property {number} vertexCount     all vertices (regular + seam)
 * @property {number} triangleCount   all triangles (regular + seam)
 * @property {number} regularVertexCount   V
 * @property {number} regularTriangleCount T
 * @property {number} droppedCount    D
 * @property {number} seamFaces       format 2: bit f = finer chunk across face f
 * @property {number} seamEdges       format 2: bit e = chunk edge e split
 * @property {Float32Array} positions xyz per vertex
 * @property {Float32Array} normals   xyz per vertex, unit length
 * @property {Uint8Array} materials   per vertex
 * @property {Uint32Array} indices    3 per triangle, counter-clockwise seen from the air
 */

const fail = (message) => {
  throw new MeshDecodeError(message);
};

// Per-row scratch of decodeMesh, for the largest grid (33 × 33 rows); axis a's rows at a · ROWS.
const ROWS = 33 * 33;
const SCRATCH = {
  rowLo: new Uint32Array(ROWS),
  rowHi: new Uint8Array(ROWS),
  cutLo: new Uint32Array(3 * ROWS),
  cutHi: new Uint8Array(3 * ROWS),
  first: new Uint32Array(3 * ROWS),
};

// Bit xx (0..32) of a 33-bit row kept as (low 32 bits, bit 32).
const bit = (l, h, xx) => (xx < 32 ? (l >>> xx) & 1 : h);

function popcount32(v) {
  v -= (v >>> 1) & 0x55555555;
  v = (v & 0x33333333) + ((v >>> 2) & 0x33333333);
  return (((v + (v >>> 4)) & 0x0f0f0f0f) * 0x01010101) >>> 24;
}

const u32 = (b, at) => (b[at] | (b[at + 1] << 8) | (b[at + 2] << 16) | (b[at + 3] << 24)) >>> 0;

// Octahedral normal (§2.4), in float32 arithmetic step by step as the server computes it.
const f = Math.fround;
const TWO_OVER_255 = f(2 / 255);
function decodeNormal(u, v, out, at) {
  const px = f(f(u * TWO_OVER_255) - 1);
  const py = f(f(v * TWO_OVER_255) - 1);
  const apx = Math.abs(px);
  const apy = Math.abs(py);
  const nz = f(f(1 - apx) - apy);
  let nx = px;
  let ny = py;
  if (nz < 0) {
    nx = f(1 - apy) * (px >= 0 ? 1 : -1);
    ny = f(1 - apx) * (py >= 0 ? 1 : -1);
  }
  const len = f(Math.sqrt(f(f(f(nx * nx) + f(ny * ny)) + f(nz * nz))));
  out[at] = f(nx / len);
  out[at + 1] = f(ny / len);
  out[at + 2] = f(nz / len);
}

// Cell edge e (Bourke numbering, §2.5): the lattice edge's axis and lower sample offset.
const EDGE_AXIS = [0, 1, 0, 1, 0, 1, 0, 1, 2, 2, 2, 2];
const EDGE_DX = [0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0];
const EDGE_DY = [0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1];
const EDGE_DZ = [0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 0, 0];

// The four chunk edges of face f (0 −x, 1 +x, 2 −y, 3 +y, 4 −z, 5 +z), as a seam_edges mask
// (§2.7: edge e runs along a = e>>2; bit 0 puts it at b = (a+1)%3 = 32, bit 1 at c = (a+2)%3 = 32).
const FACE_EDGES = (() => {
  const masks = [0, 0, 0, 0, 0, 0];
  for (let face = 0; face < 6; face++) {
    const fa = face >> 1;
    const side = face & 1;
    for (let e = 0; e < 12; e++) {
      const a = e >> 2;
      if (a === fa) continue;
      const b = (a + 1) % 3;
      const atSide = b === fa ? e & 1 : (e >> 1) & 1;
      if (atSide === side) masks[face] |= 1 << e;
    }
  }
  return masks;
})();

/**
 * The seam cells of a level-of-detail chunk (§2.7): bit x of entry y + 32·z set when cell
 * (x, y, z) has a split edge (on a face in seamFaces or a chunk edge in seamEdges).
 * @param {number} seamFaces
 * @param {number} seamEdges
 * @returns {Uint32Array} 32·32 rows of cells
 */
export function seamCells(seamFaces, seamEdges) {
  const rows = new Uint32Array(32 * 32);
  const mark = (x, y, z) => {  // -1: every value on that axis
    for (let zz = 0; zz < 32; zz++) {
      if (z >= 0 && zz !== z) continue;
      for (let yy = 0; yy < 32; yy++) {
        if (y >= 0 && yy !== y) continue;
        rows[yy + 32 * zz] |= x >= 0 ? 1 << x : 0xffffffff;
      }
    }
  };
  for (let face = 0; face < 6; face++) {
    if (!((seamFaces >> face) & 1)) continue;
    const at = face & 1 ? 31 : 0;
    const p = [-1, -1, -1];
    p[face >> 1] = at;
    mark(p[0], p[1], p[2]);
  }
  for (let e = 0; e < 12; e++) {
    if (!((seamEdges >> e) & 1)) continue;
    const a = e >> 2;
    const p = [-1, -1, -1];
    p[(a + 1) % 3] = e & 1 ? 31 : 0;
    p[(a + 2) % 3] = e & 2 ? 31 : 0;
    mark(p[0], p[1], p[2]);
  }
  return rows;
}

/**
 * Decodes one mesh encoding (format 1 or 2, PROTOCOL §2).
 * @param {Uint8Array} bytes the decompressed encoding
 * @param {{table?: import("./table.js").CaseTable, maxBytes?: number}} [options]
 * @returns {DecodedMesh}
 * @throws {MeshDecodeError} on any inconsistency
 */
export function decodeMesh(bytes, options = {}) {
  const table = options.table ?? DEFAULT_TABLE;
  const maxBytes = options.maxBytes ?? MAX_ENCODING_BYTES;
  const n = bytes.length;
  if (n > maxBytes) fail(`${n} bytes, over the limit of ${maxBytes}`);
  if (n < 1) fail("empty encoding");
  const format = bytes[0];
  if (format !== 1 && format !== 2) fail(`unknown format ${format}`);
  const headerBytes = format === 1 ? 16 : 27;
  if (n < headerBytes + 1 + 4) fail(`truncated: ${n} bytes, shorter than a header`);
  const cx = bytes[1];
  const cy = bytes[2];
  const cz = bytes[3];
  if (cx < 1 || cx > 32 || cy < 1 || cy > 32 || cz < 1 || cz > 32) fail(`cells ${cx}, ${cy}, ${cz} out of 1..32`);
  if (format === 2 && (cx !== 32 || cy !== 32 || cz !== 32)) fail(`format 2 with cells ${cx}, ${cy}, ${cz}`);
  const V = u32(bytes, 4);
  const T = u32(bytes, 8);
  const D = u32(bytes, 12);
  let seamFaces = 0;
  let seamEdges = 0;
  let S = 0;
  let ST = 0;
  if (format === 2) {
    seamFaces = bytes[16];
    seamEdges = bytes[17] | (bytes[18] << 8);
    S = u32(bytes, 19);
    ST = u32(bytes, 23);
    if (seamFaces & 0xc0) fail(`seam_faces 0x${seamFaces.toString(16)}: bits 6-7 set`);
    if (seamEdges & 0xf000) fail(`seam_edges 0x${seamEdges.toString(16)}: bits 12-15 set`);
    for (let face = 0; face < 6; face++) {
      if ((seamFaces >> face) & 1 && (seamEdges & FACE_EDGES[face]) !== FACE_EDGES[face]) {
        fail(`seams not normalized: face ${face} split but not all its edges`);
      }
    }
    if (S > MAX_SEAM_VERTICES) fail(`${S} seam vertices, over ${MAX_SEAM_VERTICES}`);
    if (ST > MAX_SEAM_TRIANGLES) fail(`${ST} seam triangles, over ${MAX_SEAM_TRIANGLES}`);
  }
  const R = (cy + 1) * (cz + 1);
  const bitmapBytes = (R + 7) >> 3;
  const B = (cx + 1 + 7) >> 3;
  if (n < headerBytes + bitmapBytes + 4) fail(`truncated: ${n} bytes, shorter than the row bitmap`);
  let N = 0;
  for (let i = 0; i < bitmapBytes; i++) N += popcount32(bytes[headerBytes + i]);
  if (R & 7 && bytes[headerBytes + bitmapBytes - 1] >> (R & 7)) fail("row bitmap has bits past the last row");
  const expected = headerBytes + bitmapBytes + N * B + 5 * V + 4 * D + 9 * S + 12 * ST + 4;
  if (expected !== n) fail(`${n} bytes, but the header and bitmap make ${expected}`);
  const crc = u32(bytes, n - 4);
  const actual = crc32c(bytes, 0, n - 4);
  if (crc !== actual) fail(`CRC-32C 0x${actual.toString(16)} differs from the sent 0x${crc.toString(16)}`);
  if (T > 5 * cx * cy * cz) fail(`triangle_count ${T} over 5 per cell`);

  // §2.2 solid rows: bits 0..31 in rowLo, bit 32 in rowHi.
  // Scratch reused across calls (decoding is synchronous; R is at most 33·33).
  const { rowLo, rowHi, cutLo, cutHi, first } = SCRATCH;
  const validLo = cx >= 31 ? 0xffffffff : ((1 << (cx + 1)) - 1) >>> 0;
  const validHi = cx === 32 ? 1 : 0;
  let p = headerBytes + bitmapBytes;
  let lo = 0;
  let hi = 0;
  for (let r = 0; r < R; r++) {
    if ((bytes[headerBytes + (r >> 3)] >> (r & 7)) & 1) {
      let dlo = 0;
      let dhi = 0;
      for (let k = 0; k < B; k++) {
        const byte = bytes[p + k];
        if (k < 4) dlo |= byte << (8 * k);
        else dhi |= byte;
      }
      dlo >>>= 0;
      p += B;
      if (dlo === 0 && dhi === 0) fail(`row ${r}: a sent difference is zero`);
      if ((dlo & ~validLo) !== 0 || (dhi & ~validHi) !== 0) fail(`row ${r}: a difference has bits above cells_x`);
      lo = (lo ^ dlo) >>> 0;
      hi ^= dhi;
    }
    rowLo[r] = lo;
    rowHi[r] = hi;
  }

  // §2.3 cut edges and vertex numbering, per (row, axis).
  const xMask = cx >= 32 ? 0xffffffff : ((1 << cx) - 1) >>> 0;
  let count = 0;
  for (let z = 0; z <= cz; z++) {
    for (let y = 0; y <= cy; y++) {
      const r = y + (cy + 1) * z;
      const l = rowLo[r];
      const h = rowHi[r];
      const xl = (l ^ ((l >>> 1) | (h << 31))) & xMask;
      cutLo[r] = xl >>> 0;
      cutHi[r] = 0;
      first[r] = count;
      count += popcount32(xl);
      if (y < cy) {
        const yl = (l ^ rowLo[r + 1]) >>> 0;
        const yh = h ^ rowHi[r + 1];
        cutLo[ROWS + r] = yl;
        cutHi[ROWS + r] = yh;
        first[ROWS + r] = count;
        count += popcount32(yl) + yh;
      } else {
        cutLo[ROWS + r] = 0;
        cutHi[ROWS + r] = 0;
        first[ROWS + r] = count;
      }
      if (z < cz) {
        const zl = (l ^ rowLo[r + cy + 1]) >>> 0;
        const zh = h ^ rowHi[r + cy + 1];
        cutLo[2 * ROWS + r] = zl;
        cutHi[2 * ROWS + r] = zh;
        first[2 * ROWS + r] = count;
        count += popcount32(zl) + zh;
      } else {
        cutLo[2 * ROWS + r] = 0;
        cutHi[2 * ROWS + r] = 0;
        first[2 * ROWS + r] = count;
      }
    }
  }
  if (count !== V) fail(`vertex_count ${V}, but the rows cut ${count} edges`);

  // §2.4 per-vertex planes.
  const total = V + S;
  const positions = new Float32Array(3 * total);
  const normals = new Float32Array(3 * total);
  const materials = new Uint8Array(total);
  const pLow = p;
  const pHigh = p + V;
  const pU = p + 2 * V;
  const pV = p + 3 * V;
  const pMat = p + 4 * V;
  let i = 0;
  let material = 0;
  for (let z = 0; z <= cz; z++) {
    for (let y = 0; y <= cy; y++) {
      const r = y + (cy + 1) * z;
      for (let axis = 0; axis < 3; axis++) {
        let m = cutLo[axis * ROWS + r];
        const last = cutHi[axis * ROWS + r];
        while (m !== 0 || last) {
          let x;
          if (m !== 0) {
            const low = m & -m;
            x = 31 - Math.clz32(low);
            m = (m ^ low) >>> 0;
          } else {
            x = 32;  // bit 32, the row's last sample
          }
          const q = bytes[pLow + i] | (bytes[pHigh + i] << 8);
          if (q > 1024) fail(`vertex ${i}: fraction ${q} over 1024`);
          const t = q / 1024;
          positions[3 * i] = axis === 0 ? x + t : x;
          positions[3 * i + 1] = axis === 1 ? y + t : y;
          positions[3 * i + 2] = axis === 2 ? z + t : z;
          decodeNormal(bytes[pU + i], bytes[pV + i], normals, 3 * i);
          material = (material + bytes[pMat + i]) & 255;
          materials[i] = material;
          i++;
          if (x === 32) break;
        }
      }
    }
  }
  p += 5 * V;

  // §2.5 dropped ordinals.
  const droppedAt = p;
  const dropped = (k) => u32(bytes, droppedAt + 4 * k);
  for (let k = 1; k < D; k++) {
    if (dropped(k) <= dropped(k - 1)) fail(`dropped ordinals not strictly increasing at ${k}`);
  }
  p += 4 * D;

  // §2.7 seam vertices.
  if (S > 0) {
    const plane = (k) => p + k * S;
    material = 0;
    for (let s = 0; s < S; s++) {
      const hx = bytes[plane(0) + s];
      const hy = bytes[plane(1) + s];
      const hz = bytes[plane(2) + s];
      const axis = bytes[plane(3) + s];
      const q = bytes[plane(4) + s] | (bytes[plane(5) + s] << 8);
      const at = V + s;
      if (hx > 64 || hy > 64 || hz > 64) fail(`seam vertex ${s}: half-cell point (${hx}, ${hy}, ${hz}) past 64`);
      if (axis > 2) fail(`seam vertex ${s}: axis ${axis}`);
      if ((axis === 0 ? hx : axis === 1 ? hy : hz) > 63) fail(`seam vertex ${s}: its half edge leaves the chunk`);
      if (q > 1024) fail(`seam vertex ${s}: fraction ${q} over 1024`);
      const t = q / 2048;
      positions[3 * at] = hx / 2 + (axis === 0 ? t : 0);
      positions[3 * at + 1] = hy / 2 + (axis === 1 ? t : 0);
      positions[3 * at + 2] = hz / 2 + (axis === 2 ? t : 0);
      decodeNormal(bytes[plane(6) + s], bytes[plane(7) + s], normals, 3 * at);
      material = (material + bytes[plane(8) + s]) & 255;
      materials[at] = material;
    }
    p += 9 * S;
  }

  // §2.5 triangles from the table, seam cells left out; then §2.7 seam triangles.
  const indices = new Uint32Array(3 * (T + ST));
  const skip = format === 2 && (seamFaces | seamEdges) ? seamCells(seamFaces, seamEdges) : null;
  const { offset, edges } = table;
  const cellMask = xMask;
  let ordinal = 0;
  let dp = 0;
  let nextDrop = D > 0 ? dropped(0) : -1;
  let out = 0;
  const rowStride = cy + 1;
  for (let z = 0; z < cz; z++) {
    for (let y = 0; y < cy; y++) {
      const r00 = y + rowStride * z;
      const r10 = r00 + 1;
      const r01 = r00 + rowStride;
      const r11 = r01 + 1;
      const a = rowLo[r00];
      const ah = rowHi[r00];
      const bl = rowLo[r10];
      const bh = rowHi[r10];
      const cl = rowLo[r01];
      const ch = rowHi[r01];
      const dl = rowLo[r11];
      const dh = rowHi[r11];
      // Cells whose eight corners are not all equal.
      const diffLo = (a ^ bl) | (a ^ cl) | (a ^ dl);
      const diffHi = (ah ^ bh) | (ah ^ ch) | (ah ^ dh);
      let mixed = (diffLo | (diffLo >>> 1) | (diffHi << 31) | (a ^ ((a >>> 1) | (ah << 31)))) & cellMask;
      if (skip) mixed &= ~skip[y + 32 * z];
      mixed >>>= 0;
      while (mixed !== 0) {
        const low = mixed & -mixed;
        const x = 31 - Math.clz32(low);
        mixed = (mixed ^ low) >>> 0;
        const x1 = x + 1;
        const cse =
          bit(a, ah, x) | (bit(a, ah, x1) << 1) | (bit(bl, bh, x1) << 2) | (bit(bl, bh, x) << 3) |
          (bit(cl, ch, x) << 4) | (bit(cl, ch, x1) << 5) | (bit(dl, dh, x1) << 6) | (bit(dl, dh, x) << 7);
        for (let k = offset[cse]; k < offset[cse + 1]; k += 3) {
          if (ordinal === nextDrop) {
            dp++;
            nextDrop = dp < D ? dropped(dp) : -1;
            ordinal++;
            continue;
          }
          ordinal++;
          if (out >= T) fail(`more table triangles than triangle_count ${T} + dropped ${D}`);
          for (let j = 0; j < 3; j++) {
            const e = edges[k + j];
            const axis = EDGE_AXIS[e];
            const xx = x + EDGE_DX[e];
            const rr = y + EDGE_DY[e] + rowStride * (z + EDGE_DZ[e]);
            const at = axis * ROWS + rr;
            const below = xx >= 32 ? cutLo[at] : cutLo[at] & ((1 << xx) - 1);
            indices[3 * out + j] = first[at] + popcount32(below);
          }
          out++;
        }
      }
    }
  }
  if (dp !== D) fail(`dropped ordinal ${dropped(dp)} is not a table triangle (there are ${ordinal})`);
  if (out !== T) fail(`triangle_count ${T}, but the table gives ${ordinal} triangles less ${D} dropped`);
  for (let k = 0; k < 3 * ST; k++) {
    const v = u32(bytes, p + 4 * k);
    if (v >= total) fail(`seam triangle ${Math.floor(k / 3)}: vertex ${v} past ${total}`);
    indices[3 * T + k] = v;
  }
  return {
    format,
    cells: [cx, cy, cz],
    vertexCount: total,
    triangleCount: T + ST,
    regularVertexCount: V,
    regularTriangleCount: T,
    droppedCount: D,
    seamFaces,
    seamEdges,
    positions,
    normals,
    materials,
    indices,
  };
}
