// zstd frames (PROTOCOL §3): size and window limits checked from the header, before any
// output is allocated; deltas against a raw-content prefix.
import assert from "node:assert/strict";
import { test } from "node:test";
import { CompressionError, decompressDelta, decompressFull, inspectFrame } from "../src/compression.js";

// A frame with one raw block: magic, header (single segment, 1-byte content size), block.
function rawFrame(content, { fhd = 0x20, fcs = [content.length], blockType = 0, last = 1, extra = [] } = {}) {
  const h = (content.length << 3) | (blockType << 1) | last;
  return Uint8Array.from([0x28, 0xb5, 0x2f, 0xfd, fhd, ...fcs, h & 255, (h >> 8) & 255, h >> 16, ...content, ...extra]);
}
const refuses = (f, pattern, base) => assert.throws(() => (base ? decompressDelta(f, base) : decompressFull(f)), (e) => e instanceof CompressionError && pattern.test(e.message), pattern.toString());

test("a raw-block frame decompresses", () => {
  assert.deepEqual([...decompressFull(rawFrame([1, 2, 3]))], [1, 2, 3]);
});

test("content size: declared, within the limit, and exact", () => {
  refuses(rawFrame([1, 2, 3], { fhd: 0x00, fcs: [0x40] }), /does not declare its content size/);  // window byte, no size
  // 8-byte content size of 5 MiB: over the default 4 MiB.
  const big = 5 << 20;
  refuses(Uint8Array.from([0x28, 0xb5, 0x2f, 0xfd, 0xe0, big & 255, (big >> 8) & 255, big >> 16, 0, 0, 0, 0, 0, 1, 0, 0]), /declares 5242880 bytes, over the limit of 4194304/);
  assert.throws(() => decompressFull(rawFrame([1, 2, 3]), { maxBytes: 2 }), /over the limit of 2/);
  refuses(rawFrame([1, 2, 3], { fcs: [4] }), /decompresses to 3 bytes, it declares 4/);
  refuses(rawFrame([1, 2, 3], { fcs: [2] }), /block of 3 bytes over the maximum 2/);
  refuses(rawFrame([1, 2, 3], { fhd: 0x80, fcs: [0, 2, 0, 0, 0] }), /regenerate more than the declared size/);  // window 1 KiB, size 2
});

test("window over 2^23, dictionary ids, reserved bits and trailing bytes are refused", () => {
  // Not single segment, window descriptor exponent 14: log 24.
  refuses(Uint8Array.from([0x28, 0xb5, 0x2f, 0xfd, 0x40, 14 << 3, 3, 0, 0x19, 0, 0]), /window log 24 over 23/);
  refuses(rawFrame([1], { fhd: 0x21, fcs: [7, 1] }), /dictionary 7/);
  refuses(rawFrame([1], { fhd: 0x28 }), /reserved bit/);
  refuses(rawFrame([1], { extra: [0] }), /1 bytes after the frame/);
  refuses(rawFrame([1], { blockType: 3 }), /reserved block type/);
  refuses(Uint8Array.from([1, 2, 3, 4, 5, 6]), /not a zstd frame/);
});

test("every truncation is refused", () => {
  const f = rawFrame([5, 6, 7, 8]);
  for (let n = 0; n < f.length; n++) assert.throws(() => inspectFrame(f.subarray(0, n)), CompressionError, `length ${n}`);
});

test("an RLE block is checked against the declared size before it is expanded", () => {
  // RLE block of 2 MiB - 1 declared in a frame of content size 10.
  const size = (1 << 21) - 1;
  const h = (size << 3) | (1 << 1) | 1;
  refuses(Uint8Array.from([0x28, 0xb5, 0x2f, 0xfd, 0x20, 10, h & 255, (h >> 8) & 255, h >> 16, 0x41]), /block of 2097151 bytes over the maximum 10|regenerate more/);
});

test("a delta whose blocks are raw decodes against any base, to its own content", () => {
  assert.deepEqual([...decompressDelta(rawFrame([9, 9]), Uint8Array.from([1, 2, 3]))], [9, 9]);
  assert.deepEqual([...decompressDelta(rawFrame([9, 9]), new Uint8Array(300000).fill(7))], [9, 9]);
});
