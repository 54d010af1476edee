// Shared by the tests: byte helpers and hand-made encodings.
import { crc32c } from "../src/crc32c.js";

export const hex = (s) => Uint8Array.from(Buffer.from(s.replace(/\s+/g, ""), "hex"));

/** PROTOCOL §2.6, byte for byte as the page prints it. */
export const WORKED_EXAMPLE = hex(`
  01 010101 03000000 01000000 00000000 03 01 01 000000 020202 bf9f9f 9fbf9f 030000 e42739aa`);

/** Rewrites the trailing CRC-32C after a mutation (so that the checks behind it run). */
export function fixCrc(bytes) {
  const n = bytes.length;
  const c = crc32c(bytes, 0, n - 4);
  bytes[n - 4] = c & 255;
  bytes[n - 3] = (c >>> 8) & 255;
  bytes[n - 2] = (c >>> 16) & 255;
  bytes[n - 1] = c >>> 24;
  return bytes;
}

export function putU32(bytes, at, v) {
  bytes[at] = v & 255;
  bytes[at + 1] = (v >>> 8) & 255;
  bytes[at + 2] = (v >>> 16) & 255;
  bytes[at + 3] = (v >>> 24) & 255;
}

/**
 * A format-2 encoding of an all-air 32³ chunk (no regular vertex) with the given seams and
 * seam vertices/triangles: §2.7 built by hand.
 * @param {{faces?: number, edges?: number, seam?: number[][], tris?: number[][]}} o
 *   seam: [hx, hy, hz, axis, q, u, v, materialDiff] per vertex
 */
export function format2(o = {}) {
  const seam = o.seam ?? [];
  const tris = o.tris ?? [];
  const R = 33 * 33;
  const bitmap = (R + 7) >> 3;
  const S = seam.length;
  const n = 27 + bitmap + 9 * S + 12 * tris.length + 4;
  const b = new Uint8Array(n);
  b[0] = 2;
  b[1] = b[2] = b[3] = 32;
  b[16] = o.faces ?? 0;
  b[17] = (o.edges ?? 0) & 255;
  b[18] = (o.edges ?? 0) >> 8;
  putU32(b, 19, S);
  putU32(b, 23, tris.length);
  let p = 27 + bitmap;
  seam.forEach(([hx, hy, hz, axis, q, u, v, md], i) => {
    const planes = [hx, hy, hz, axis, q & 255, q >> 8, u, v, md];
    planes.forEach((value, k) => {
      b[p + k * S + i] = value;
    });
  });
  p += 9 * S;
  for (const t of tris) for (const v of t) {
    putU32(b, p, v);
    p += 4;
  }
  return fixCrc(b);
}
