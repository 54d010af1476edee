// TCP framing (PROTOCOL §4.1): every message is a u32 little-endian length, then that many
// bytes of a serialized Envelope. Over WebSocket there is no length: one binary message is
// one Envelope.

/** Default largest frame accepted from the server (§4.1: "accept at least 16 MiB"). */
export const MAX_SERVER_FRAME_BYTES = 16 << 20;

/** A frame refused by the framing rules. */
export class FrameError extends Error {
  constructor(message) {
    super(`framing: ${message}`);
    this.name = "FrameError";
  }
}

/**
 * Prefixes one serialized Envelope with its length.
 * @param {Uint8Array} body
 * @param {number} [maxBytes] refuse bodies longer than this (the server's Welcome.max_frame_bytes)
 * @returns {Uint8Array}
 */
export function encodeFrame(body, maxBytes = 0xffffffff) {
  if (body.length > maxBytes) throw new FrameError(`a frame of ${body.length} bytes is over the limit of ${maxBytes}`);
  const out = new Uint8Array(4 + body.length);
  const n = body.length;
  out[0] = n & 255;
  out[1] = (n >>> 8) & 255;
  out[2] = (n >>> 16) & 255;
  out[3] = (n >>> 24) & 255;
  out.set(body, 4);
  return out;
}

/**
 * Splits a byte stream into frames. push() takes any slice of the stream and returns the
 * frames it completed; the rest waits for more bytes. A declared length over the limit
 * throws before anything is allocated for it, and the decoder refuses further input.
 */
export class FrameDecoder {
  /** @param {{maxBytes?: number}} [options] */
  constructor(options = {}) {
    this.maxBytes = options.maxBytes ?? MAX_SERVER_FRAME_BYTES;
    this.header = new Uint8Array(4);
    this.headerFill = 0;
    /** @type {Uint8Array|null} */
    this.body = null;
    this.bodyFill = 0;
    this.failed = null;
  }

  /** Bytes held of a frame not yet complete (0 between frames). */
  get pending() {
    return this.body ? 4 + this.bodyFill : this.headerFill;
  }

  /**
   * @param {Uint8Array} chunk
   * @returns {Uint8Array[]} the frames completed by this chunk, in order
   * @throws {FrameError}
   */
  push(chunk) {
    if (this.failed) throw this.failed;
    const frames = [];
    let p = 0;
    while (p < chunk.length || (this.body && this.bodyFill === this.body.length)) {
      if (!this.body) {
        const take = Math.min(4 - this.headerFill, chunk.length - p);
        this.header.set(chunk.subarray(p, p + take), this.headerFill);
        this.headerFill += take;
        p += take;
        if (this.headerFill < 4) break;
        const h = this.header;
        const n = (h[0] | (h[1] << 8) | (h[2] << 16) | (h[3] << 24)) >>> 0;
        if (n > this.maxBytes) {
          this.failed = new FrameError(`a frame of ${n} bytes is over the limit of ${this.maxBytes}`);
          throw this.failed;
        }
        this.body = new Uint8Array(n);
        this.bodyFill = 0;
      }
      const take = Math.min(this.body.length - this.bodyFill, chunk.length - p);
      this.body.set(chunk.subarray(p, p + take), this.bodyFill);
      this.bodyFill += take;
      p += take;
      if (this.bodyFill === this.body.length) {
        frames.push(this.body);
        this.body = null;
        this.headerFill = 0;
      }
    }
    return frames;
  }
}
