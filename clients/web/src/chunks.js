// The chunks a client holds (PROTOCOL §4.3, §4.10): per (level, x, y, z) the version, the
// decompressed encoding (the base of the next delta) and the decoded mesh. A payload that
// does not apply drops the chunk; the caller then asks for it with Resync, and deltas for
// it are ignored until its full copy comes.
import { decompressDelta, decompressFull, MAX_CONTENT_BYTES } from "./compression.js";
import { decodeMesh } from "./mesh.js";
import { toBigInt } from "./messages.js";

/**
 * The key of a chunk: "level:x,y,z".
 * @param {number} level
 * @param {number} x
 * @param {number} y
 * @param {number} z
 */
export const chunkKey = (level, x, y, z) => `${level}:${x},${y},${z}`;

/**
 * @typedef {object} Chunk
 * @property {string} key        chunkKey(level, x, y, z)
 * @property {number} level      0, or k ≥ 1 for a level-of-detail chunk
 * @property {{x: number, y: number, z: number}} coord  in level-k chunks
 * @property {bigint} version
 * @property {Uint8Array} encoding  the decompressed encoding (§2), base of the next delta
 * @property {import("./mesh.js").DecodedMesh} mesh
 * @property {[number, number, number]} origin  world position of local (0, 0, 0): 32·2^k·coord
 * @property {number} scale      2^k: world = origin + scale · position
 */

/**
 * @typedef {object} ApplyOutcome
 * @property {"added"|"updated"|"failed"|"ignored"} kind  failed: dropped, ask for it again;
 *   ignored: a delta for a chunk being resynced (no base held)
 * @property {string} key
 * @property {Chunk} [chunk]
 * @property {Error} [error]
 */

export class ChunkCache {
  /** @param {{table?: any, maxEncodingBytes?: number}} [options] */
  constructor(options = {}) {
    this.table = options.table;
    this.maxBytes = options.maxEncodingBytes ?? MAX_CONTENT_BYTES;
    /** @type {Map<string, Chunk>} */
    this.chunks = new Map();
    /** Keys asked for with Resync whose full copy has not come yet. @type {Set<string>} */
    this.resyncing = new Set();
  }

  /**
   * Applies one ChunkMesh message (as decoded by protobufjs).
   * @param {any} msg
   * @returns {ApplyOutcome}
   */
  apply(msg) {
    const level = msg.level ?? 0;
    const c = msg.coord ?? {};
    const coord = { x: c.x ?? 0, y: c.y ?? 0, z: c.z ?? 0 };
    const key = chunkKey(level, coord.x, coord.y, coord.z);
    const version = toBigInt(msg.version);
    const base = toBigInt(msg.base_version);
    const payload = msg.payload ?? new Uint8Array(0);
    const held = this.chunks.get(key);
    const limits = { maxBytes: this.maxBytes };
    let encoding;
    try {
      if (base === 0n) {
        encoding = decompressFull(payload, limits);
      } else {
        if (!held) {
          if (this.resyncing.has(key)) return { kind: "ignored", key };
          throw new Error(`delta against version ${base} of a chunk not held`);
        }
        if (held.version !== base) throw new Error(`delta against version ${base}, version ${held.version} held`);
        encoding = decompressDelta(payload, held.encoding, limits);
      }
      const mesh = decodeMesh(encoding, { table: this.table, maxBytes: this.maxBytes });
      const scale = 2 ** level;
      const side = 32 * scale;
      /** @type {Chunk} */
      const chunk = { key, level, coord, version, encoding, mesh, origin: [side * coord.x, side * coord.y, side * coord.z], scale };
      this.chunks.set(key, chunk);
      this.resyncing.delete(key);
      return { kind: held ? "updated" : "added", key, chunk };
    } catch (error) {
      this.chunks.delete(key);
      this.resyncing.add(key);
      return { kind: "failed", key, error };
    }
  }

  /**
   * Forgets chunks (ChunkUnload). Returns the chunks that were held.
   * @param {number} level
   * @param {{x?: number, y?: number, z?: number}[]} coords
   * @returns {Chunk[]}
   */
  unload(level, coords) {
    const gone = [];
    for (const c of coords) {
      const key = chunkKey(level, c.x ?? 0, c.y ?? 0, c.z ?? 0);
      const held = this.chunks.get(key);
      if (held) gone.push(held);
      this.chunks.delete(key);
      this.resyncing.delete(key);
    }
    return gone;
  }

  /** Forgets everything (a new connection: versions are per connection, §4.3). */
  clear() {
    this.chunks.clear();
    this.resyncing.clear();
  }
}
