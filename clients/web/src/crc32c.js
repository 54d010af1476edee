// CRC-32C (Castagnoli): reflected polynomial 0x82F63B78, initial value and final xor
// 0xFFFFFFFF (PROTOCOL §2.1). Slicing-by-4 tables.

const T = new Uint32Array(4 * 256);
for (let i = 0; i < 256; i++) {
  let c = i;
  for (let k = 0; k < 8; k++) c = c & 1 ? (c >>> 1) ^ 0x82f63b78 : c >>> 1;
  T[i] = c >>> 0;
}
for (let i = 0; i < 256; i++) {
  for (let t = 1; t < 4; t++) {
    const p = T[(t - 1) * 256 + i];
    T[t * 256 + i] = (p >>> 8) ^ T[p & 0xff];
  }
}

/**
 * CRC-32C of `bytes[begin, end)`.
 * @param {Uint8Array} bytes
 * @param {number} [begin]
 * @param {number} [end]
 * @returns {number} the CRC as an unsigned 32-bit integer
 */
export function crc32c(bytes, begin = 0, end = bytes.length) {
  let c = 0xffffffff;
  let i = begin;
  for (; i + 4 <= end; i += 4) {
    c ^= bytes[i] | (bytes[i + 1] << 8) | (bytes[i + 2] << 16) | (bytes[i + 3] << 24);
    c = T[768 + (c & 0xff)] ^ T[512 + ((c >>> 8) & 0xff)] ^ T[256 + ((c >>> 16) & 0xff)] ^ T[c >>> 24];
  }
  for (; i < end; i++) c = (c >>> 8) ^ T[(c ^ bytes[i]) & 0xff];
  return (c ^ 0xffffffff) >>> 0;
}
