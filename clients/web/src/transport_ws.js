// The WebSocket transport: one binary message is exactly one Envelope, no length prefix
// (ws://HOST:7780/ws). Works with the browser's WebSocket and with the `ws` package in
// Node: pass its constructor as options.WebSocket, or leave it out to use
// globalThis.WebSocket.
import { MAX_SERVER_FRAME_BYTES } from "./framing.js";

export class WebSocketTransport {
  /** @param {any} socket an open WebSocket @param {{maxFrameBytes?: number}} [options] */
  constructor(socket, options = {}) {
    this.socket = socket;
    this.maxBytes = options.maxFrameBytes ?? MAX_SERVER_FRAME_BYTES;
    this.maxSendBytes = 0xffffffff;
    /** @type {(bytes: Uint8Array) => void} */
    this.onmessage = () => {};
    /** @type {(error?: Error) => void} */
    this.onclose = () => {};
    this.closed = false;
    let error;
    socket.binaryType = "arraybuffer";
    socket.onmessage = (event) => {
      if (this.closed) return;
      const data = event.data;
      let bytes;
      if (data instanceof ArrayBuffer) bytes = new Uint8Array(data);
      else if (ArrayBuffer.isView(data)) bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
      else {
        error = new Error("a text WebSocket message: the protocol sends binary messages only");
        socket.close(1003);
        return;
      }
      if (bytes.length > this.maxBytes) {
        error = new Error(`a message of ${bytes.length} bytes is over the limit of ${this.maxBytes}`);
        socket.close(1009);
        return;
      }
      this.onmessage(bytes);
    };
    socket.onerror = (event) => {
      error = error ?? new Error(`WebSocket error${event?.message ? `: ${event.message}` : ""}`);
    };
    socket.onclose = (event) => {
      if (this.closed) return;
      this.closed = true;
      if (!error && event && event.code !== 1000 && event.code !== 1005) error = new Error(`WebSocket closed (${event.code}${event.reason ? ` ${event.reason}` : ""})`);
      this.onclose(error);
    };
  }

  /** @param {Uint8Array} envelope one serialized Envelope */
  send(envelope) {
    if (this.closed) throw new Error("transport closed");
    if (envelope.length > this.maxSendBytes) throw new Error(`a message of ${envelope.length} bytes is over the server's limit of ${this.maxSendBytes}`);
    this.socket.send(envelope);
  }

  close() {
    this.socket.close(1000);
  }
}

/**
 * Opens a WebSocket to voxeld, e.g. connectWebSocket("ws://host:7780/ws").
 * @param {string} url
 * @param {{WebSocket?: any, maxFrameBytes?: number, timeoutMs?: number}} [options]
 * @returns {Promise<WebSocketTransport>}
 */
export function connectWebSocket(url, options = {}) {
  const Ctor = options.WebSocket ?? globalThis.WebSocket;
  if (!Ctor) throw new Error("no WebSocket: pass options.WebSocket (e.g. the ws package's)");
  return new Promise((resolve, reject) => {
    const socket = new Ctor(url);
    socket.binaryType = "arraybuffer";
    const timer = setTimeout(() => {
      socket.close();
      reject(new Error(`WebSocket ${url} did not open in time`));
    }, options.timeoutMs ?? 10000);
    socket.onerror = (event) => {
      clearTimeout(timer);
      reject(new Error(`WebSocket ${url}: ${event?.message ?? "error"}`));
    };
    socket.onopen = () => {
      clearTimeout(timer);
      resolve(new WebSocketTransport(socket, options));
    };
  });
}
