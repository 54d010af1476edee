// The session (PROTOCOL §4.2–§4.13) over any transport: Hello/Welcome, SetView and
// ViewReady, held chunks with their deltas and Resync, edits and their results, queries
// (raycast, ground, samples) and theirs, Ping.
import { ChunkCache, chunkKey } from "./chunks.js";
import { Emitter } from "./emitter.js";
import {
  decodeEnvelope, editStatusName, encodeEnvelope, Envelope, errorCodeName, queryStatusName, StampShape, toBigInt, toUint64,
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

const voxelBox = (min, max) => {
  const lo = vec(min, "min");
  const hi = vec(max, "max");
  if (!lo || !hi) throw new TypeError("samples: min and max [x, y, z] are required");
  for (const c of [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z]) {
    if (!Number.isInteger(c)) throw new TypeError("samples: min and max are integer sample coordinates");
  }
  return { min_x: lo.x, min_y: lo.y, min_z: lo.z, max_x: hi.x, max_y: hi.y, max_z: hi.z };
};

/**
 * The samples of a SampleQuery's answer (§4.13): densities as int16 read little-endian
 * (solid above 0), materials one byte each, both x fastest, then y, then z; size is the
 * echoed box's samples per axis ([0, 0, 0] for a refused query, whose box is empty).
 * @param {{box: {minX:number,minY:number,minZ:number,maxX:number,maxY:number,maxZ:number}, densities: Uint8Array, materials: Uint8Array}} result
 * @returns {{size: number[], densities: Int16Array, materials: Uint8Array}}
 */
export function decodeSamples(result) {
  const bytes = result.densities instanceof Uint8Array ? result.densities : Uint8Array.from(result.densities ?? []);
  const b = result.box;
  const size = bytes.length === 0 || !b ? [0, 0, 0] : [b.maxX - b.minX + 1, b.maxY - b.minY + 1, b.maxZ - b.minZ + 1];
  const n = size[0] * size[1] * size[2];
  if (bytes.length !== 2 * n || (result.materials?.length ?? 0) !== n) {
    throw new Error(`QueryResult: ${bytes.length} density bytes and ${result.materials?.length ?? 0} materials for a box of ${n} samples`);
  }
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const densities = new Int16Array(n);
  for (let i = 0; i < n; i++) densities[i] = view.getInt16(2 * i, true);
  const materials = new Uint8Array(n);
  materials.set(result.materials ?? []);
  return { size, densities, materials };
}

/**
 * The Query message of a query kind and its parameters (§4.13).
 * @param {"raycast"|"ground"|"samples"} kind
 * @param {object} p
 * @param {number} [defaultDistance] maxDistance / maxDepth when not given
 */
export function queryBody(kind, p, defaultDistance = 512) {
  switch (kind) {
    case "raycast":
      return { raycast: { origin: vec(p.origin, "origin"), direction: vec(p.direction, "direction"), max_distance: p.maxDistance ?? defaultDistance } };
    case "ground":
      return { ground: { x: p.x, z: p.z, from_y: p.fromY, max_depth: p.maxDepth ?? defaultDistance } };
    case "samples":
      return { samples: { box: voxelBox(p.min, p.max) } };
    default:
      throw new TypeError(`unknown query kind "${kind}": raycast, ground or samples`);
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
 *  - "viewready" (viewReady), "editresult" (result), "queryresult" (result), "welcome" (welcome)
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
    this.pending = { hello: null, edits: new Map(), views: new Map(), pings: new Map(), queries: new Map() };
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
   * @returns {Promise<{requestId: bigint, status: number, statusName: string, reason: string, changedChunks: {x:number,y:number,z:number}[], retryAfterMs: number, clippedBy: bigint[], alreadyApplied: boolean, volumes: {material: number, removed: number, added: number}[]}>}
   *   volumes (ACCEPTED, not a resend): voxels of each material the edit took away and put in
   */
  edit(kind, params, options = {}) {
    const requestId = BigInt(this.nextRequestId++);
    const body = editBody(kind, params);
    const promise = this.#waitFor(this.pending.edits, requestId, options.timeoutMs, `EditResult of edit ${requestId}`);
    this.#send({ edit: { request_id: toUint64(requestId), ...body } });
    return promise;
  }

  /**
   * Sends a Query (§4.13) and resolves with its QueryResult, whatever its status (check
   * result.status === 0, "OK" in result.statusName; RATE_LIMITED, TOO_MANY, SERVER_BUSY and
   * STORAGE_UNAVAILABLE are worth retrying after result.retryAfterMs). Rejects if the
   * connection ends first (or after timeoutMs), before hello(), or when the server's
   * Welcome has no max_query_distance (a server without queries).
   * @param {"raycast"|"ground"|"samples"} kind
   * @param {object} params raycast: origin, direction, maxDistance; ground: x, z, fromY,
   *   maxDepth; samples: min, max (inclusive integer sample coordinates)
   * @param {{timeoutMs?: number}} [options]
   * @returns {Promise<{requestId: bigint, status: number, statusName: string, reason: string, retryAfterMs: number, hit: boolean, point: {x:number,y:number,z:number}, normal: {x:number,y:number,z:number}, material: number, distance: number, box: object, densities: Uint8Array, materials: Uint8Array}>}
   */
  query(kind, params, options = {}) {
    const body = queryBody(kind, params, this.welcome?.maxQueryDistance || 512);
    if (!this.welcome) return Promise.reject(new Error("query before hello()"));
    // A server before queries sends no query limits (and would answer UNKNOWN_MESSAGE,
    // with no request id to match): every server that answers them has a ray length.
    if (!(this.welcome.maxQueryDistance > 0)) return Promise.reject(new Error("this server answers no queries (Welcome.max_query_distance is 0)"));
    const requestId = BigInt(this.nextRequestId++);
    const promise = this.#waitFor(this.pending.queries, requestId, options.timeoutMs, `QueryResult of query ${requestId}`);
    try {
      this.#send({ query: { request_id: toUint64(requestId), ...body } });
    } catch (e) {
      const entry = this.pending.queries.get(requestId);
      this.pending.queries.delete(requestId);
      clearTimeout(entry?.timer);
      throw e;
    }
    return promise;
  }

  /**
   * Where a ray first meets the surface (§4.13): result.hit, point, normal (unit, towards
   * the air), material, distance.
   * @param {number[]|{x:number,y:number,z:number}} origin world voxels
   * @param {number[]|{x:number,y:number,z:number}} direction any length but zero
   * @param {number} [maxDistance] voxels (default Welcome.max_query_distance)
   * @param {{timeoutMs?: number}} [options]
   */
  raycast(origin, direction, maxDistance, options) {
    return this.query("raycast", { origin, direction, maxDistance }, options);
  }

  /**
   * The first surface straight down from (x, fromY, z) within maxDepth voxels (§4.13),
   * answered as a raycast. Start in the air above the ground.
   * @param {number} x
   * @param {number} z
   * @param {number} fromY
   * @param {number} [maxDepth] voxels (default Welcome.max_query_distance)
   * @param {{timeoutMs?: number}} [options]
   */
  ground(x, z, fromY, maxDepth, options) {
    return this.query("ground", { x, z, fromY, maxDepth }, options);
  }

  /**
   * The samples of the inclusive box min..max (§4.13), at most Welcome.max_query_samples.
   * Resolves with the QueryResult, its densities replaced by an Int16Array (decoded
   * little-endian; solid above 0) and materials a Uint8Array, x fastest, then y, then z;
   * size is [nx, ny, nz] and index(x, y, z) the position of a world sample in both arrays.
   * @param {number[]|{x:number,y:number,z:number}} min
   * @param {number[]|{x:number,y:number,z:number}} max
   * @param {{timeoutMs?: number}} [options]
   */
  async samples(min, max, options) {
    const result = await this.query("samples", { min, max }, options);
    const { size, densities, materials } = decodeSamples(result);
    const b = result.box;
    const index = (x, y, z) => (x - b.minX) + size[0] * ((y - b.minY) + size[1] * (z - b.minZ));
    return { ...result, size, densities, materials, index };
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
      case "query_result": {
        const result = plain(message, typeOf("query_result"));
        // bytes fields: a Uint8Array always (protobufjs' default for a missing one is []).
        result.densities = Uint8Array.from(result.densities);
        result.materials = Uint8Array.from(result.materials);
        result.statusName = queryStatusName(result.status);
        this.emit("queryresult", result);
        this.#settle(this.pending.queries, result.requestId, result);
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
    for (const map of [this.pending.edits, this.pending.views, this.pending.pings, this.pending.queries]) {
      for (const entry of map.values()) {
        clearTimeout(entry.timer);
        entry.reject(reason);
      }
      map.clear();
    }
    this.emit("close", this.closeError ?? undefined);
  }
}
