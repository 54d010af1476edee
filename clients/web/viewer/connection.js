// The viewer's connection: connect, Hello, and after the server goes away (or refuses)
// a new Client with back-off. Counts the bytes received. Every new session starts empty
// (versions belong to one connection, PROTOCOL §4.3): listeners get "session" with the
// fresh Client and drop what the old one held on "ended".
import { Client, connectWebSocket } from "../src/index.js";
import { Emitter } from "../src/emitter.js";
import { Backoff, shouldRetry } from "./backoff.js";

/**
 * Events: "status" (text, kind: "info"|"ok"|"error"), "session" (client, welcome),
 * "ended" (error?, retryInMs|null: null when the viewer waits for the person).
 */
export class Connection extends Emitter {
  /**
   * @param {{url: string, name: string, token?: string, backoff?: Backoff}} options
   */
  constructor(options) {
    super();
    this.url = options.url;
    this.name = options.name;
    this.token = options.token ?? "";
    this.backoff = options.backoff ?? new Backoff();
    /** @type {Client|null} the current session's client, once welcomed */
    this.client = null;
    /** Bytes of every Envelope received, all sessions. */
    this.bytesReceived = 0;
    this.retryTimer = null;
    this.generation = 0;
    this.endedGeneration = 0;
  }

  /** Connects now (again, with the current token), dropping any session or pending retry. */
  start() {
    clearTimeout(this.retryTimer);
    const generation = ++this.generation;
    const old = this.client;
    this.client = null;
    if (old) old.close();
    this.#attempt(generation);
  }

  /** @param {string} token a player token for servers that check them (§4.8) */
  setToken(token) {
    this.token = token.trim();
    this.start();
  }

  async #attempt(generation) {
    this.emit("status", `connecting to ${this.url}…`, "info");
    let client;
    try {
      const transport = await connectWebSocket(this.url, { timeoutMs: 10000 });
      if (generation !== this.generation) return transport.close();
      client = new Client(transport);
      const deliver = transport.onmessage;
      transport.onmessage = (bytes) => {
        this.bytesReceived += bytes.length;
        deliver(bytes);
      };
      client.on("close", (error) => {
        this.#ended(generation, error ?? new Error("the server closed the connection"));
      });
      const welcome = await client.hello({ playerName: this.name, token: this.token || undefined });
      if (generation !== this.generation) return client.close();
      this.client = client;
      this.backoff.reset();
      this.emit("status", `connected to voxeld ${welcome.serverVersion || ""} (${welcome.players} player${welcome.players === 1 ? "" : "s"})`, "ok");
      this.emit("session", client, welcome);
    } catch (error) {
      client?.close();
      this.#ended(generation, client?.closeError ?? error);
    }
  }

  #ended(generation, error) {
    // A session's end is reported once: its close and a failed hello() may both get here.
    if (generation !== this.generation || this.endedGeneration === generation) return;
    this.endedGeneration = generation;
    this.client = null;
    // A server's Error says why itself; anything else is the connection going away.
    const why = error?.codeName ? error.message : `no connection to the server (${error?.message ?? "closed"})`;
    if (!shouldRetry(error)) {
      const hint = error.codeName === "REPLACED" ? "reload the page to take over" : "enter a token and press Connect";
      this.emit("status", `${why} — ${hint}`, "error");
      this.emit("ended", error, null);
      return;
    }
    const wait = this.backoff.next();
    this.emit("status", `${why} — reconnecting in ${(wait / 1000).toFixed(1)} s`, "error");
    this.emit("ended", error, wait);
    this.retryTimer = setTimeout(() => {
      if (generation === this.generation) this.start();
    }, wait);
  }
}
