// The viewer page: wires the connection, the scene, the controls, the tools and the HUD.
// window.voxelViewer exposes the figures the HUD shows (for people and the browser tests).
import { ChunkMeshes } from "./chunk_meshes.js";
import { Connection } from "./connection.js";
import { FlyControls } from "./controls.js";
import { describeResult, editFor } from "./edits.js";
import { Hud } from "./hud.js";
import { parseParams } from "./params.js";
import { createStage } from "./scene.js";
import { pick, ToolBar } from "./tools.js";
import { ViewPolicy } from "./view_policy.js";

const START = [0, 64, 0];    // above the default terrain (sea level 0, hills about ±40)
const START_PITCH = -0.5;    // looking down at the ground ahead and the horizon beyond
const MAX_LOD = 6;

const params = parseParams(location.search, location);
const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById("view"));
const stage = createStage(canvas);
const { camera } = stage;
const meshes = new ChunkMeshes(stage.scene);
const hud = new Hud(document);
const toolbar = new ToolBar(document.getElementById("tools"));
const policy = new ViewPolicy();
const connection = new Connection({ url: params.server, name: params.name, token: params.token });
const controls = new FlyControls(camera, canvas, { onClick: (x, y) => applyTool(x, y) });
camera.position.set(...(params.position ?? START));
controls.setAngles(0, START_PITCH);

/** The current session: its client, limits, view and figures. */
let session = null;
const counters = { fps: 0, bytesPerSecond: 0, ping: null, firstViewMs: null, edits: [] };

connection.on("status", (text, kind) => hud.setStatus(text, kind));
connection.on("ended", () => {
  session = null;
  counters.ping = null;
});
connection.on("session", (client, welcome) => {
  meshes.clear();
  policy.reset();
  toolbar.setLimits(welcome);
  const lod = Math.min(params.lod ?? MAX_LOD, welcome.maxLodLevel || 0);
  const radius = Math.min(params.radius, welcome.maxViewRadius || params.radius);
  stage.setFar(lod > 0 ? 64 * 2 ** lod : (radius + 1) * 32);
  session = { client, welcome, lod, radius, viewId: 0, complete: false };
  const s = session;
  client.on("chunkadded", (chunk) => meshes.upsert(chunk));
  client.on("chunkupdated", (chunk) => meshes.upsert(chunk));
  client.on("chunkunloaded", (chunk) => meshes.retire(chunk, performance.now()));
  client.on("viewready", (ready) => {
    if (Number(ready.viewId) !== s.viewId) return;
    s.complete = true;
    meshes.flushRetired();
    counters.firstViewMs ??= Math.round(performance.now());
  });
  client.on("servererror", (e) => hud.setStatus(e.message, "error"));
});
connection.start();

/** Sends the view around the camera (the policy says when). */
function updateView(now) {
  const s = session;
  if (!s || s.client.closed) return;
  const p = camera.position;
  if (!policy.shouldSend([p.x, p.y, p.z], now)) return;
  s.viewId = s.client.setView({ position: [p.x, p.y, p.z], radius: s.radius, lodLevel: s.lod });
  s.complete = s.client.viewReady.has(BigInt(s.viewId));
}

/** Applies the selected tool where the pixel's ray meets the terrain. */
function applyTool(x, y) {
  const s = session;
  if (!s) return;
  const point = pick(camera, canvas, x, y, meshes.group);
  if (!point) return hud.addResult("no terrain under the pointer", false);
  const [kind, p] = editFor(toolbar.tool, point, toolbar.settings, s.welcome);
  const sent = performance.now();
  s.client.edit(kind, p, { timeoutMs: 30000 }).then(
    (r) => {
      counters.edits.push({ kind, point, status: r.statusName, ms: Math.round(performance.now() - sent), changed: r.changedChunks.length });
      hud.addResult(describeResult(kind, r), r.statusName === "ACCEPTED");
    },
    (e) => hud.addResult(`${kind}: ${e.message}`, false));
}

// Ping every 2 s; bytes per second and frames per second over the last second.
setInterval(() => {
  session?.client.ping({ timeoutMs: 10000 }).then((ms) => { counters.ping = ms; }, () => {});
}, 2000);
let frames = 0;
let bytesBefore = 0;
let windowStart = performance.now();
let last = windowStart;
let hudShown = 0;

function frame(now) {
  requestAnimationFrame(frame);
  controls.update((now - last) / 1000);
  last = now;
  updateView(now);
  meshes.tick(now);
  stage.renderer.render(stage.scene, camera);
  frames++;
  if (now - windowStart >= 1000) {
    counters.fps = (frames * 1000) / (now - windowStart);
    counters.bytesPerSecond = ((connection.bytesReceived - bytesBefore) * 1000) / (now - windowStart);
    bytesBefore = connection.bytesReceived;
    frames = 0;
    windowStart = now;
  }
  if (now - hudShown >= 250) {
    hudShown = now;
    hud.show(stats());
  }
}
requestAnimationFrame(frame);
window.addEventListener("resize", stage.resize);

const tokenBox = /** @type {HTMLInputElement} */ (document.getElementById("token"));
tokenBox.value = params.token;
document.getElementById("token-form").addEventListener("submit", (e) => {
  e.preventDefault();
  connection.setToken(tokenBox.value);
});

/** What the HUD shows, as numbers. */
function stats() {
  const p = camera.position;
  return {
    ping: counters.ping,
    bytesPerSecond: counters.bytesPerSecond,
    bytesReceived: connection.bytesReceived,
    chunks: meshes.count,
    triangles: meshes.triangles,
    fps: counters.fps,
    viewComplete: !!session?.complete,
    viewId: session?.viewId ?? 0,
    connected: !!session,
    position: [p.x, p.y, p.z],
    lod: session?.lod ?? 0,
    radius: session?.radius ?? params.radius,
    firstViewMs: counters.firstViewMs,
  };
}

/** For people (the console) and the browser tests. */
window.voxelViewer = {
  stats,
  /** Version (as a string), triangles and level of every chunk drawn, by key. */
  chunks: () => Object.fromEntries([...meshes.info].map(([k, v]) => [k, { ...v, version: String(v.version) }])),
  /** The edits sent and their results. */
  edits: counters.edits,
  /** The tool bar: tool, settings {radius, strength, material, carve}, select(id). */
  toolbar,
  camera,
  controls,
  connection,
};
