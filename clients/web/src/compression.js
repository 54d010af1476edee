// zstd full messages and deltas (PROTOCOL §3), decompressed with fzstd.
//
// A frame is checked before any output is allocated: one zstd frame and nothing after it,
// its content size declared and within the limit, no dictionary id, a window of at most
// 2^23 bytes, every block header well-formed and the raw/RLE blocks not over the declared
// size. The output must be exactly the declared size.
//
// A delta's base is a raw-content prefix. fzstd has no dictionary call, but a raw-content
// prefix is exactly history the frame may refer back to, so the delta is decoded as a new
// single-segment frame whose content is [base as raw blocks] + [the delta's own blocks],
// and the base's bytes are cut off the front of the output. Only fzstd's public
// decompress() is used.
import { Decompress } from "fzstd";

/** A frame refused by the checks of §3, or one that does not decompress. */
export class CompressionError extends Error {
  constructor(message) {
    super(`zstd: ${message}`);
    this.name = "CompressionError";
  }
}

/** Default limit of a decompressed encoding (voxeld's own, §3). */
export const MAX_CONTENT_BYTES = 4 << 20;
/** voxeld's windowLogMax (§3). */
export const MAX_WINDOW_LOG = 23;

const MAGIC = 0xfd2fb528;
const MAX_BLOCK = 128 << 10;

const fail = (message) => {
  throw new CompressionError(message);
};

/**
 * Reads and checks a frame's header and block headers.
 * @param {Uint8Array} frame
 * @param {number} maxBytes
 * @returns {{contentSize: number, blocksAt: number, blocksEnd: number}}
 */
export function inspectFrame(frame, maxBytes = MAX_CONTENT_BYTES) {
  const n = frame.length;
  if (n < 6) fail(`truncated frame (${n} bytes)`);
  const magic = (frame[0] | (frame[1] << 8) | (frame[2] << 16) | (frame[3] << 24)) >>> 0;
  if (magic !== MAGIC) fail(`not a zstd frame (magic 0x${magic.toString(16)})`);
  const fhd = frame[4];
  const fcsFlag = fhd >> 6;
  const singleSegment = (fhd >> 5) & 1;
  const checksum = (fhd >> 2) & 1;
  const dictFlag = fhd & 3;
  if (fhd & 8) fail("reserved bit set in the frame header");
  let p = 5;
  let windowSize = 0;
  if (!singleSegment) {
    const wd = frame[p++];
    const windowLog = 10 + (wd >> 3);
    if (windowLog > MAX_WINDOW_LOG) fail(`window log ${windowLog} over ${MAX_WINDOW_LOG}`);
    const base = 2 ** windowLog;
    windowSize = base + (base / 8) * (wd & 7);
    if (windowSize > 2 ** MAX_WINDOW_LOG) fail(`window of ${windowSize} bytes over 2^${MAX_WINDOW_LOG}`);
  }
  const dictBytes = [0, 1, 2, 4][dictFlag];
  if (p + dictBytes > n) fail("truncated frame header");
  let dictId = 0;
  for (let i = 0; i < dictBytes; i++) dictId += frame[p + i] * 2 ** (8 * i);
  p += dictBytes;
  if (dictId !== 0) fail(`frame names dictionary ${dictId}`);
  const fcsBytes = [singleSegment ? 1 : 0, 2, 4, 8][fcsFlag];
  if (fcsBytes === 0) fail("frame does not declare its content size");
  if (p + fcsBytes > n) fail("truncated frame header");
  let contentSize = 0;
  for (let i = 0; i < fcsBytes; i++) contentSize += frame[p + i] * 2 ** (8 * i);
  if (fcsBytes === 2) contentSize += 256;
  p += fcsBytes;
  if (contentSize > maxBytes) fail(`frame declares ${contentSize} bytes, over the limit of ${maxBytes}`);
  if (singleSegment) windowSize = contentSize;
  const blockMax = Math.min(windowSize, MAX_BLOCK);
  const blocksAt = p;
  let regenerated = 0;
  for (;;) {
    if (p + 3 > n) fail("truncated: a block header is missing");
    const h = frame[p] | (frame[p + 1] << 8) | (frame[p + 2] << 16);
    p += 3;
    const last = h & 1;
    const type = (h >> 1) & 3;
    const size = h >>> 3;
    if (type === 3) fail("reserved block type");
    if (size > blockMax) fail(`block of ${size} bytes over the maximum ${blockMax}`);
    const stored = type === 1 ? 1 : size;
    if (p + stored > n) fail("truncated: a block is cut short");
    if (type !== 2) {
      regenerated += size;
      if (regenerated > contentSize) fail("blocks regenerate more than the declared size");
    }
    p += stored;
    if (last) break;
  }
  const blocksEnd = p;
  if (checksum) p += 4;
  if (p > n) fail("truncated: the checksum is cut short");
  if (p !== n) fail(`${n - p} bytes after the frame`);
  return { contentSize, blocksAt, blocksEnd };
}

function decompressFrame(frame, expected, skip) {
  const parts = [];
  let total = 0;
  const d = new Decompress((chunk) => {
    total += chunk.length;
    if (total > expected) throw new CompressionError(`frame decompresses past its declared ${expected - skip} bytes`);
    parts.push(chunk);
  });
  try {
    d.push(frame, true);
  } catch (e) {
    if (e instanceof CompressionError) throw e;
    fail(`corrupt frame (${e.message})`);
  }
  if (total !== expected) fail(`frame decompresses to ${total - skip} bytes, it declares ${expected - skip}`);
  const out = new Uint8Array(expected - skip);
  let at = -skip;
  for (const part of parts) {
    if (at + part.length > 0) {
      const from = Math.max(0, -at);
      out.set(from ? part.subarray(from) : part, at + from);
    }
    at += part.length;
  }
  return out;
}

/**
 * Decompresses a full message (§3: one zstd frame whose content is the encoding).
 * @param {Uint8Array} frame
 * @param {{maxBytes?: number}} [options]
 * @returns {Uint8Array}
 * @throws {CompressionError}
 */
export function decompressFull(frame, options = {}) {
  const { contentSize } = inspectFrame(frame, options.maxBytes ?? MAX_CONTENT_BYTES);
  return decompressFrame(frame, contentSize, 0);
}

/**
 * Decompresses a delta (§3): `frame` was compressed with `base` (the previous decompressed
 * encoding of the chunk) as a raw-content reference prefix.
 * @param {Uint8Array} frame
 * @param {Uint8Array} base
 * @param {{maxBytes?: number}} [options]
 * @returns {Uint8Array}
 * @throws {CompressionError}
 */
export function decompressDelta(frame, base, options = {}) {
  const maxBytes = options.maxBytes ?? MAX_CONTENT_BYTES;
  const { contentSize, blocksAt, blocksEnd } = inspectFrame(frame, maxBytes);
  if (base.length > maxBytes) fail(`delta base of ${base.length} bytes over the limit of ${maxBytes}`);
  const total = base.length + contentSize;
  const rawBlocks = Math.ceil(base.length / MAX_BLOCK);
  const own = frame.subarray(blocksAt, blocksEnd);
  const joined = new Uint8Array(5 + 4 + base.length + 3 * rawBlocks + own.length);
  // Magic, then a single-segment header (window = content) with a 4-byte content size,
  // no checksum, no dictionary.
  joined.set([0x28, 0xb5, 0x2f, 0xfd, 0xa0, total & 255, (total >>> 8) & 255, (total >>> 16) & 255, (total >>> 24) & 255]);
  let p = 9;
  for (let at = 0; at < base.length; at += MAX_BLOCK) {
    const size = Math.min(MAX_BLOCK, base.length - at);
    const h = size << 3;  // raw block, not last
    joined[p] = h & 255;
    joined[p + 1] = (h >>> 8) & 255;
    joined[p + 2] = (h >>> 16) & 255;
    joined.set(base.subarray(at, at + size), p + 3);
    p += 3 + size;
  }
  joined.set(own, p);
  return decompressFrame(joined, total, base.length);
}
