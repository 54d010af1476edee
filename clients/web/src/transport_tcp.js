// Node only: the TCP transport (PROTOCOL §4.1), u32 little-endian length-prefixed frames
// over a net.Socket. Not imported by the browser entry point (src/index.js).
import net from "node:net";
import { encodeFrame, FrameDecoder, MAX_SERVER_FRAME_BYTES } from "./framing.js";

/**
 * A connected TCP transport. The client sets onmessage (one Envelope's bytes) and
 * onclose (an Error, or undefined for an orderly close).
 */
export class TcpTransport {
  /** @param {net.Socket} socket @param {{maxFrameBytes?: number}} [options] */
  constructor(socket, options = {}) {
    this.socket = socket;
    this.decoder = new FrameDecoder({ maxBytes: options.maxFrameBytes ?? MAX_SERVER_FRAME_BYTES });
    /** Largest frame to send (set from Welcome.max_frame_bytes by the client). */
    this.maxSendBytes = 0xffffffff;
    /** @type {(bytes: Uint8Array) => void} */
    this.onmessage = () => {};
    /** @type {(error?: Error) => void} */
    this.onclose = () => {};
    this.closed = false;
    let error;
    socket.setNoDelay(true);
    socket.on("data", (data) => {
      if (this.closed) return;
      let frames;
      try {
        frames = this.decoder.push(data);
      } catch (e) {
        error = e;
        socket.destroy();
        return;
      }
      for (const f of frames) this.onmessage(f);
    });
    socket.on("error", (e) => {
      error = error ?? e;
    });
    socket.on("close", () => {
      if (this.closed) return;
      this.closed = true;
      if (!error && this.decoder.pending > 0) error = new Error(`connection closed inside a frame (${this.decoder.pending} bytes held)`);
      this.onclose(error);
    });
  }

  /** @param {Uint8Array} envelope one serialized Envelope */
  send(envelope) {
    if (this.closed) throw new Error("transport closed");
    this.socket.write(encodeFrame(envelope, this.maxSendBytes));
  }

  close() {
    this.socket.end();
    this.socket.destroySoon?.();
  }
}

/**
 * Connects to voxeld over TCP.
 * @param {string} host
 * @param {number} port
 * @param {{maxFrameBytes?: number, timeoutMs?: number}} [options]
 * @returns {Promise<TcpTransport>}
 */
export function connectTcp(host, port, options = {}) {
  return new Promise((resolve, reject) => {
    const socket = net.connect({ host, port });
    const timer = setTimeout(() => {
      socket.destroy();
      reject(new Error(`connect to ${host}:${port} timed out`));
    }, options.timeoutMs ?? 10000);
    socket.once("error", (e) => {
      clearTimeout(timer);
      reject(e);
    });
    socket.once("connect", () => {
      clearTimeout(timer);
      socket.removeAllListeners("error");
      resolve(new TcpTransport(socket, options));
    });
  });
}
