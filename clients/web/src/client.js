// The session (PROTOCOL §4.2–§4.10) over any transport: Hello/Welcome, SetView and
// ViewReady, held chunks with their deltas and Resync, edits and their results, Ping.
import { ChunkCache, chunkKey } from "./chunks.js";
import { Emitter } from "./emitter.js";
import {
  decodeEnvelope, editStatusName, encodeEnvelope, Envelope, errorCodeName, StampShape, toBigInt, toUint64,
} from "./messages.js";
import { DEFAULT_TABLE } from "./table.js";

/**
 * What a Client needs of a transport: send one serialized Envelope, close, and call
 * onmessage with each Envelope received and onclose once when the connection ends.
 * @typedef {object} Transport
 * @property {(envelope: Uint8Array) => void} send
 * @property {() => void} close
 * @property {(envelope: Uint8Array) => void} onmessage
 * @property {(error?: Error) => void} onclose
 * @property {number} [maxSendBytes]
 */

/** An Error message of the server (§4.5) turned into an exception. */
export class ServerError extends Error {
  constructor(code, message) {
    super(`server: ${errorCodeName(code)}${message ? `: ${message}` : ""}`);
    this.name = "ServerError";
    this.code = code;
    this.codeName = errorCodeName(code);
  }
}

const camel = (s) => s.replace(/_([a-z])/g, (_, c) => c.toUpperCase());
const LONGS = new Set(["uint64", "int64", "sint64", "fixed64", "sfixed64"]);

/**
 * A protobufjs message as a plain object: camelCase keys, every field present (defaults
 * filled), 64-bit integers as BigInt.
 * @param {any} msg
 * @param {any} type a protobufjs Type
 */
export function plain(msg, type) {
  const out = {};
  for (const field of type.fieldsArray) {
    const value = msg?.[field.name];
    const one = (v) => {
      if (field.resolvedType && field.resolvedType.fieldsArray) return plain(v, field.resolvedType);
      if (LONGS.has(field.type)) return toBigInt(v ?? 0);
      if (v === undefined || v === null) return field.typeDefault;
      return v;
    };
    out[camel(field.name)] = field.repeated ? (value ?? []).map(one) : one(value);
  }
  return out;
}

const typeOf = (kind) => Envelope.fields[kind].resolvedType;

const vec = (v, what) => {
  if (v === undefined) return undefined;
  const [x, y, z] = Array.isArray(v) ? v : [v.x, v.y, v.z];
  if (![x, y, z].every((c) => typeof c === "number")) throw new TypeError(`${what}: expected [x, y, z] numbers`);
  return { x, y, z };
};

/**
 * The Edit message of an edit kind and its parameters (§4.4).
 * @param {"brush"|"explosion"|"smooth"|"paint"|"stamp"} kind
 * @param {object} p
 */
export function editBody(kind, p) {
  switch (kind) {
    case "brush":
      return { brush: { center: vec(p.center, "center"), radius: p.radius, strength: p.strength, remove: !!p.remove, material: p.material ?? 0 } };
    case "explosion":
      return { explosion: { center: vec(p.center, "center"), radius: p.radius, power: p.power } };
    case "smooth":
      return { smooth: { center: vec(p.center, "center"), radius: p.radius, strength: p.strength } };
    case "paint":
      return { paint: { center: vec(p.center, "center"), radius: p.radius, material: p.material } };
    case "stamp": {
      const shape = typeof p.shape === "string" ? StampShape[p.shape.toUpperCase()] : (p.shape ?? 0);
      if (shape === undefined) throw new TypeError(`stamp shape "${p.shape}": box or sphere`);
      return {
        stamp: {
          shape, min: vec(p.min, "min"), max: vec(p.max, "max"), center: vec(p.center, "center"),
          radius: p.radius ?? 0, solid: p.solid ?? true, material: p.material ?? 0,
        },
      };
    }
    default:
      throw new TypeError(`unknown edit kind "${kind}": brush, explosion, smooth, paint or stamp`);
  }
}

/**
 * A voxeld client.
 *
 * Events (client.on(name, fn)):
 *  - "chunkadded" (chunk), "chunkupdated" (chunk, previousVersion): a mesh decoded and held
 *  - "chunkunloaded" (chunk): the server said to forget it (ChunkUnload)
 *  - "chunkfailed" (key, error): a payload did not apply; the chunk was dropped and asked
 *    for again with Resync
 *  - "viewready" (viewReady), "editresult" (result), "welcome" (welcome)
 *  - "servererror" (ServerError): an Error message of the server
 *  - "message" (kind, message): every Envelope received (protobufjs objects), unknown ones too
 *  - "close" (error?): the connection ended
 */
export class Client extends Emitter {
  /**
   * @param {Transport} transport a connected transport (connectTcp, connectWebSocket)
   * @param {{table?: import("./table.js").CaseTable, maxEncodingBytes?: number, keepaliveMs?: number}} [options]
   *   keepaliveMs: send a Ping after this long without sending (default 15000, 0: never)
   */
  constructor(transport, options = {}) {
    super();
    this.transport = transport;
    this.table = options.table ?? DEFAULT_TABLE;
    this.cache = new ChunkCache({ table: this.table, maxEncodingBytes: options.maxEncodingBytes });
    /** The server's Welcome, once hello() resolved. */
    this.welcome = null;
    this.closed = false;
    /** Why the connection ended (the server's Error or the transport's), once closed. */
    this.closeError = null;
    this.nextRequestId = 1;
    this.nextViewId = 1;
    this.nextNonce = 1;
    /** @type {Map<bigint, object>} the ViewReady of each view id received */
    this.viewReady = new Map();
    this.pending = { hello: null, edits: new Map(), views: new Map(), pings: new Map() };
    this.resyncQueue = new Map();  // level -> Set of "x,y,z"
    this.resyncScheduled = false;
    this.lastSend = Date.now();
    transport.onmessage = (bytes) => this.#receive(bytes);
    transport.onclose = (error) => this.#closed(error);
    const keepalive = options.keepaliveMs ?? 15000;
    if (keepalive > 0) {
      this.keepaliveTimer = setInterval(() => {
        if (this.welcome && !this.closed && Date.now() - this.lastSend >= keepalive) this.ping().catch(() => {});
      }, Math.max(100, keepalive / 3));
      this.keepaliveTimer.unref?.();
    }
  }

  /** The chunks held, keyed chunkKey(level, x, y, z) ("level:x,y,z"). @returns {Map<string, import("./chunks.js").Chunk>} */
  get chunks() {
    return this.cache.chunks;
  }

  /** @param {number} level @param {number} x @param {number} y @param {number} z */
  chunk(level, x, y, z) {
    return this.cache.chunks.get(chunkKey(level, x, y, z));
  }

  #send(body) {
    if (this.closed) throw this.closeError ?? new Error("connection closed");
    this.transport.send(encodeEnvelope(body));
    this.lastSend = Date.now();
  }

  /**
   * Sends Hello and waits for Welcome (§4.2). Refuses a server whose mesh table revision
   * is not this client's (§2.7).
   * @param {{playerName?: string, token?: string, timeoutMs?: number}} [options]
   * @returns {Promise<object>} the Welcome (camelCase fields)
   */
  hello(options = {}) {
    if (this.pending.hello || this.welcome) return Promise.reject(new Error("hello() already sent"));
    const promise = new Promise((resolve, reject) => {
      this.pending.hello = { resolve, reject };
    });
    const timeout = options.timeoutMs ?? 10000;
    const timer = setTimeout(() => this.pending.hello?.reject(new Error("no Welcome in time")), timeout);
    this.#send({ hello: { protocol_version: 1, player_name: options.playerName ?? "web", token: options.token ?? "" } });
    return promise.finally(() => {
      clearTimeout(timer);
      this.pending.hello = null;
    });
  }

  /**
   * Sets the view (§4.2, §4.10). Returns the view id to wait for with waitViewReady().
   * @param {{position: number[]|{x:number,y:number,z:number}, radius: number, lodLevel?: number, lodDistance?: number, viewId?: number}} view
   * @returns {number}
   */
  setView(view) {
    if (!this.welcome) throw new Error("setView before hello()");
    const viewId = view.viewId ?? this.nextViewId++;
    const body = { position: vec(view.position, "position"), radius: view.radius };
    // A server that does not send ViewReady (max_resync_chunks 0) refuses view_id (§4.1).
    if (this.welcome.maxResyncChunks > 0) body.view_id = toUint64(viewId);
    if (view.lodLevel) body.lod_level = view.lodLevel;
    if (view.lodDistance) body.lod_distance = view.lodDistance;
    this.#send({ set_view: body });
    return viewId;
  }

  /**
   * Resolves with the ViewReady of that view (§4.2 item 5): every chunk of the view is
   * held then. A SetView replaced or coalesced before it completed gets none: use a timeout.
   * @param {number} viewId
   * @param {{timeoutMs?: number}} [options]
   * @returns {Promise<object>}
   */
  waitViewReady(viewId, options = {}) {
    const id = BigInt(viewId);
    if (this.viewReady.has(id)) return Promise.resolve(this.viewReady.get(id));
    if (this.welcome && this.welcome.maxResyncChunks === 0) return Promise.reject(new Error("this server sends no ViewReady"));
    return this.#waitFor(this.pending.views, id, options.timeoutMs, `ViewReady of view ${viewId}`);
  }

  /**
   * Sends an edit (§4.4) and resolves with its EditResult, whatever its status (check
   * result.status === 0, "ACCEPTED" in result.statusName). Rejects only if the connection
   * ends first.
   * @param {"brush"|"explosion"|"smooth"|"paint"|"stamp"} kind
   * @param {object} params center [x, y, z], radius, strength, power, remove, material,
   *   and for a stamp shape ("box"|"sphere"), min, max, solid
   * @param {{timeoutMs?: number}} [options]
   * @returns {Promise<{requestId: bigint, status: number, statusName: string, reason: string, changedChunks: {x:number,y:number,z:number}[], retryAfterMs: number, clippedBy: bigint[]}>}
   */
  edit(kind, params, options = {}) {
    const requestId = BigInt(this.nextRequestId++);
    const body = editBody(kind, params);
    const promise = this.#waitFor(this.pending.edits, requestId, options.timeoutMs, `EditResult of edit ${requestId}`);
    this.#send({ edit: { request_id: toUint64(requestId), ...body } });
    return promise;
  }

  /**
   * Sends a Ping and resolves with the round trip in milliseconds.
   * @param {{timeoutMs?: number}} [options]
   * @returns {Promise<number>}
   */
  ping(options = {}) {
    const nonce = BigInt(this.nextNonce++);
    const start = Date.now();
    const promise = this.#waitFor(this.pending.pings, nonce, options.timeoutMs ?? 30000, "Pong");
    this.#send({ ping: { nonce: toUint64(nonce) } });
    return promise.then(() => Date.now() - start);
  }

  /**
   * Asks for full copies of chunks (§4.3); done by the client itself when a payload does
   * not apply.
   * @param {number} level
   * @param {{x:number,y:number,z:number}[]} coords
   */
  resync(level, coords) {
    const max = this.welcome?.maxResyncChunks || 64;
    for (let i = 0; i < coords.length; i += max) {
      this.#send({ resync: { level, coords: coords.slice(i, i + max) } });
    }
  }

  /** Closes the connection. */
  close() {
    this.transport.close();
  }

  #waitFor(map, id, timeoutMs, what) {
    if (this.closed) return Promise.reject(this.closeError ?? new Error("connection closed"));
    return new Promise((resolve, reject) => {
      const entry = { resolve, reject, timer: null };
      if (timeoutMs) {
        entry.timer = setTimeout(() => {
          map.delete(id);
          reject(new Error(`no ${what} within ${timeoutMs} ms`));
        }, timeoutMs);
      }
      map.set(id, entry);
    });
  }

  #settle(map, id, value) {
    const entry = map.get(id);
    if (!entry) return;
    map.delete(id);
    clearTimeout(entry.timer);
    entry.resolve(value);
  }

  #receive(bytes) {
    let kind;
    let message;
    try {
      ({ kind, message } = decodeEnvelope(bytes));
    } catch (e) {
      this.closeError = new Error(`an Envelope that does not parse: ${e.message}`);
      this.transport.close();
      return;
    }
    this.emit("message", kind, message);
    switch (kind) {
      case "welcome": {
        const welcome = plain(message, typeOf("welcome"));
        const revision = welcome.meshTableRevision || 1;
        if (revision !== this.table.revision) {
          this.closeError = new Error(`the server derives triangles with table revision ${revision}, this client has ${this.table.revision}`);
          this.pending.hello?.reject(this.closeError);
          this.transport.close();
          return;
        }
        this.welcome = welcome;
        if (welcome.maxFrameBytes) this.transport.maxSendBytes = welcome.maxFrameBytes;
        this.emit("welcome", welcome);
        this.pending.hello?.resolve(welcome);
        break;
      }
      case "chunk_mesh":
        this.#chunkMesh(message);
        break;
      case "chunk_unload":
        for (const chunk of this.cache.unload(message.level ?? 0, message.coords ?? [])) this.emit("chunkunloaded", chunk);
        break;
      case "edit_result": {
        const result = plain(message, typeOf("edit_result"));
        result.statusName = editStatusName(result.status);
        this.emit("editresult", result);
        this.#settle(this.pending.edits, result.requestId, result);
        break;
      }
      case "view_ready": {
        const ready = plain(message, typeOf("view_ready"));
        this.viewReady.set(ready.viewId, ready);
        if (this.viewReady.size > 64) this.viewReady.delete(this.viewReady.keys().next().value);
        this.emit("viewready", ready);
        this.#settle(this.pending.views, ready.viewId, ready);
        break;
      }
      case "pong":
        this.#settle(this.pending.pings, toBigInt(message.nonce), undefined);
        break;
      case "error": {
        const error = new ServerError(message.code ?? 0, message.message ?? "");
        // The codes after which the connection stays open (§4.5); the others close it.
        if (![5, 6, 12, 13].includes(error.code)) this.closeError = error;
        this.emit("servererror", error);
        if (this.pending.hello && !this.welcome) this.pending.hello.reject(error);
        break;
      }
      default:
        break;  // region_result and bodies this schema does not know: "message" only
    }
  }

  #chunkMesh(message) {
    const held = this.cache.chunks.get(chunkKey(message.level ?? 0, message.coord?.x ?? 0, message.coord?.y ?? 0, message.coord?.z ?? 0));
    const previous = held?.version;
    const outcome = this.cache.apply(message);
    if (outcome.kind === "added") this.emit("chunkadded", outcome.chunk);
    else if (outcome.kind === "updated") this.emit("chunkupdated", outcome.chunk, previous);
    else if (outcome.kind === "failed") {
      this.emit("chunkfailed", outcome.key, outcome.error);
      if (held) this.emit("chunkunloaded", held);
      const level = message.level ?? 0;
      if (!this.resyncQueue.has(level)) this.resyncQueue.set(level, new Map());
      const c = message.coord ?? {};
      this.resyncQueue.get(level).set(outcome.key, { x: c.x ?? 0, y: c.y ?? 0, z: c.z ?? 0 });
      if (!this.resyncScheduled) {
        this.resyncScheduled = true;
        queueMicrotask(() => this.#flushResync());
      }
    }
  }

  #flushResync() {
    this.resyncScheduled = false;
    const queue = this.resyncQueue;
    this.resyncQueue = new Map();
    if (this.closed) return;
    if (this.welcome && this.welcome.maxResyncChunks === 0) {
      this.emit("servererror", new Error("a chunk did not apply and this server has no Resync: set the view again"));
      return;
    }
    for (const [level, coords] of queue) this.resync(level, [...coords.values()]);
  }

  #closed(error) {
    if (this.closed) return;
    this.closed = true;
    clearInterval(this.keepaliveTimer);
    if (error && !this.closeError) this.closeError = error;
    const reason = this.closeError ?? new Error("connection closed");
    this.pending.hello?.reject(reason);
    for (const map of [this.pending.edits, this.pending.views, this.pending.pings]) {
      for (const entry of map.values()) {
        clearTimeout(entry.timer);
        entry.reject(reason);
      }
      map.clear();
    }
    this.emit("close", this.closeError ?? undefined);
  }
}
