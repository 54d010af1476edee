// The chunks held, as three.js meshes: one BufferGeometry per (level, coord), reused when
// the chunk changes; vertices chunk-local, so a level-k chunk is placed at its origin and
// scaled by 2^k (PROTOCOL §2.7, §4.10). An unloaded chunk stays drawn until the next
// ViewReady or a few seconds, so that no hole opens while the chunks replacing it arrive.
import * as THREE from "three";
import { paletteBytes, srgbToLinear } from "./palette.js";

// three.js takes vertex colours as linear values; the palette is sRGB.
const PALETTE = paletteBytes().map((c) => Math.round(255 * srgbToLinear(c)));
// Every chunk's vertices lie in its [0, 32]³ cells: a fixed bound, no per-update compute.
const BOX = new THREE.Box3(new THREE.Vector3(0, 0, 0), new THREE.Vector3(32, 32, 32));
const SPHERE = new THREE.Sphere(new THREE.Vector3(16, 16, 16), 16 * Math.sqrt(3));
/** How long an unloaded chunk may stay drawn without a ViewReady. */
const RETIRE_MS = 4000;

export class ChunkMeshes {
  /** @param {THREE.Object3D} parent where the meshes go */
  constructor(parent) {
    this.group = new THREE.Group();
    this.group.name = "chunks";
    parent.add(this.group);
    this.material = new THREE.MeshLambertMaterial({ vertexColors: true });
    /** @type {Map<string, THREE.Mesh>} */
    this.meshes = new Map();
    /** Unloaded but still drawn: key → time unloaded. @type {Map<string, number>} */
    this.retiring = new Map();
    this.triangles = 0;
    /** Per key: version and triangle count of what is drawn (for the HUD and the tests). */
    this.info = new Map();
  }

  /**
   * Draws a chunk's newest mesh (chunkadded / chunkupdated).
   * @param {import("../src/chunks.js").Chunk} chunk
   */
  upsert(chunk) {
    const m = chunk.mesh;
    let mesh = this.meshes.get(chunk.key);
    if (!mesh) {
      const geometry = new THREE.BufferGeometry();
      geometry.boundingBox = BOX.clone();
      geometry.boundingSphere = SPHERE.clone();
      mesh = new THREE.Mesh(geometry, this.material);
      mesh.matrixAutoUpdate = false;
      mesh.position.set(chunk.origin[0], chunk.origin[1], chunk.origin[2]);
      mesh.scale.setScalar(chunk.scale);
      mesh.updateMatrix();
      mesh.name = chunk.key;
      mesh.userData.level = chunk.level;
      this.meshes.set(chunk.key, mesh);
      this.group.add(mesh);
    } else {
      this.triangles -= this.info.get(chunk.key)?.triangles ?? 0;
    }
    this.retiring.delete(chunk.key);
    fill(mesh.geometry, m);
    mesh.visible = m.triangleCount > 0;
    this.triangles += m.triangleCount;
    this.info.set(chunk.key, { version: chunk.version, triangles: m.triangleCount, level: chunk.level });
  }

  /**
   * A chunk left the view: keep drawing it until flushRetired() (ViewReady) or RETIRE_MS.
   * @param {{key: string}} chunk
   * @param {number} now
   */
  retire(chunk, now) {
    if (this.meshes.has(chunk.key)) this.retiring.set(chunk.key, now);
  }

  /**
   * Removes retired chunks: all of them (a ViewReady: the view's chunks are all in), or
   * those retired before `olderThan`.
   * @param {number} [olderThan]
   */
  flushRetired(olderThan = Infinity) {
    for (const [key, t] of this.retiring) if (t < olderThan) this.remove(key);
  }

  /** Per frame: drops chunks retired more than RETIRE_MS ago. @param {number} now */
  tick(now) {
    if (this.retiring.size) this.flushRetired(now - RETIRE_MS);
  }

  /** @param {string} key */
  remove(key) {
    const mesh = this.meshes.get(key);
    this.retiring.delete(key);
    if (!mesh) return;
    this.group.remove(mesh);
    mesh.geometry.dispose();
    this.meshes.delete(key);
    this.triangles -= this.info.get(key)?.triangles ?? 0;
    this.info.delete(key);
  }

  /** Removes everything (a new connection). */
  clear() {
    for (const key of [...this.meshes.keys()]) this.remove(key);
  }

  /** Chunks drawn, not counting the retiring ones. */
  get count() {
    return this.meshes.size - this.retiring.size;
  }
}

/**
 * Puts a decoded mesh into a geometry, reusing its buffers when the mesh fits and growing
 * them by a quarter when it does not.
 * @param {THREE.BufferGeometry} g
 * @param {import("../src/mesh.js").DecodedMesh} m
 */
function fill(g, m) {
  const v = m.vertexCount;
  const n = m.triangleCount * 3;
  const pos = /** @type {THREE.BufferAttribute|undefined} */ (g.getAttribute("position"));
  if (!pos || pos.count < v || g.index.count < n) {
    g.dispose();  // new buffer sizes: three.js uploads new GPU buffers on the next draw
    const cap = Math.ceil(v * 1.25);
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(cap * 3), 3));
    g.setAttribute("normal", new THREE.BufferAttribute(new Float32Array(cap * 3), 3));
    g.setAttribute("color", new THREE.BufferAttribute(new Uint8Array(cap * 3), 3, true));
    g.setIndex(new THREE.BufferAttribute(new Uint32Array(Math.ceil(n * 1.25)), 1));
  }
  const position = g.getAttribute("position");
  const normal = g.getAttribute("normal");
  const color = g.getAttribute("color");
  position.array.set(m.positions.subarray(0, v * 3));
  normal.array.set(m.normals.subarray(0, v * 3));
  const c = color.array;
  for (let i = 0; i < v; i++) {
    const p = m.materials[i] * 3;
    c[i * 3] = PALETTE[p];
    c[i * 3 + 1] = PALETTE[p + 1];
    c[i * 3 + 2] = PALETTE[p + 2];
  }
  g.index.array.set(m.indices.subarray(0, n));
  for (const [a, count] of [[position, v * 3], [normal, v * 3], [color, v * 3], [g.index, n]]) {
    a.clearUpdateRanges?.();
    a.addUpdateRange?.(0, count);
    a.needsUpdate = true;
  }
  g.setDrawRange(0, n);
}
