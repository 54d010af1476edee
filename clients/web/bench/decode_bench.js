// npm run bench: decode time per chunk in Node for the fixture chunks of
// voxel_mesh_fixtures (VOXEL_MESH_FIXTURES, or build/bin of this checkout): zstd full
// message (fzstd) then the mesh decoder with all its checks; and the delta of delta.json.
// When the zstddec package happens to be installed (it is not a dependency), its
// decompression of the same frames is timed too, for comparison.
import { execFileSync } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { decompressDelta, decompressFull } from "../src/compression.js";
import { decodeMesh } from "../src/mesh.js";
import { findTool } from "../test/tools.js";

const tool = findTool("VOXEL_MESH_FIXTURES", "voxel_mesh_fixtures");
if (!tool) {
  console.error("build voxel_mesh_fixtures first (cmake --build build --target voxel_mesh_fixtures)");
  process.exit(1);
}
const dir = mkdtempSync(join(tmpdir(), "voxel-bench-"));
execFileSync(tool, [dir], { stdio: "ignore" });
const names = JSON.parse(readFileSync(join(dir, "manifest.json"), "utf8")).fixtures;
const chunks = names.map((name) => ({
  name,
  frame: new Uint8Array(readFileSync(join(dir, `${name}.zst`))),
  encoding: new Uint8Array(readFileSync(join(dir, `${name}.bin`))),
}));
const delta = JSON.parse(readFileSync(join(dir, "delta.json"), "utf8"));
const h = (s) => Uint8Array.from(Buffer.from(s, "hex"));
rmSync(dir, { recursive: true, force: true });

function time(fn, minMs = 300) {
  for (let i = 0; i < 20; i++) fn();  // warm up
  const samples = [];
  const end = performance.now() + minMs;
  while (performance.now() < end || samples.length < 30) {
    const t = performance.now();
    fn();
    samples.push(performance.now() - t);
  }
  samples.sort((a, b) => a - b);
  return samples[samples.length >> 1] * 1000;  // median, µs
}

const fmt = (us) => `${us.toFixed(1).padStart(8)} µs`;
console.log("chunk                       format  bytes  zst  tris    zstd+decode   decode only");
let totalFull = 0;
let terrain = [];
for (const c of chunks) {
  const m = decodeMesh(c.encoding);
  const both = time(() => decodeMesh(decompressFull(c.frame)));
  const only = time(() => decodeMesh(c.encoding));
  totalFull += both;
  if (c.name.startsWith("terrain") || c.name.startsWith("lod")) terrain.push(both);
  console.log(`${c.name.padEnd(28)}${String(m.format).padStart(4)}${String(c.encoding.length).padStart(8)}${String(c.frame.length).padStart(6)}${String(m.triangleCount).padStart(6)}  ${fmt(both)}  ${fmt(only)}`);
}
const base = h(delta.base);
const dframe = h(delta.delta_frame);
const tDelta = time(() => decodeMesh(decompressDelta(dframe, base)));
console.log(`delta (${dframe.length} bytes against a ${base.length}-byte base): zstd+decode ${fmt(tDelta)}`);
terrain.sort((a, b) => a - b);
console.log(`mean over the ${chunks.length} fixtures: ${fmt(totalFull / chunks.length)}; median of terrain/LOD chunks: ${fmt(terrain[terrain.length >> 1])}`);

try {
  const { ZSTDDecoder } = await import("zstddec");
  const z = new ZSTDDecoder();
  await z.init();
  let f = 0;
  let zd = 0;
  for (const c of chunks) {
    f += time(() => decompressFull(c.frame), 100);
    zd += time(() => z.decode(c.frame, c.encoding.length), 100);
  }
  console.log(`zstd alone, mean per fixture frame: fzstd ${fmt(f / chunks.length)}, zstddec (WASM) ${fmt(zd / chunks.length)}`);
} catch (e) {
  if (e.code !== "ERR_MODULE_NOT_FOUND") throw e;
}
