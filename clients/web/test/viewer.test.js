// The viewer's pure parts (no DOM, no three.js): URL parameters, when to send a view, the
// reconnection back-off and which errors stop it, the edit of each tool and its result line.
import assert from "node:assert/strict";
import { test } from "node:test";
import { Backoff, shouldRetry } from "../viewer/backoff.js";
import { describeResult, editFor, TOOLS } from "../viewer/edits.js";
import { MATERIALS, paletteBytes, srgbToLinear } from "../viewer/palette.js";
import { DEFAULT_RADIUS, defaultServerUrl, parseParams } from "../viewer/params.js";
import { ViewPolicy } from "../viewer/view_policy.js";

const http = { protocol: "http:", host: "127.0.0.1:7780" };

test("the WebSocket is the page's own host, wss under https", () => {
  assert.equal(defaultServerUrl(http), "ws://127.0.0.1:7780/ws");
  assert.equal(defaultServerUrl({ protocol: "https:", host: "game.example" }), "wss://game.example/ws");
});

test("URL parameters are read, and a value that does not parse keeps its default", () => {
  const p = parseParams("?pos=1,2.5,-3&lod=4&radius=6&name=ann&token=abc", http);
  assert.deepEqual(p, { server: "ws://127.0.0.1:7780/ws", token: "abc", position: [1, 2.5, -3], lod: 4, radius: 6, name: "ann" });
  const d = parseParams("?pos=1,2&lod=x&radius=0&name=" + "é".repeat(17), http);
  assert.deepEqual([d.position, d.lod, d.radius, d.name], [null, null, DEFAULT_RADIUS, "viewer"]);
  assert.equal(parseParams("?lod=0", http).lod, 0);
  assert.equal(parseParams("?server=10.0.0.1:7780", http).server, "ws://10.0.0.1:7780/ws");
  assert.equal(parseParams("?server=wss://h/x/ws", http).server, "wss://h/x/ws");
  assert.equal(parseParams("?server=10.0.0.1:7780", { protocol: "https:", host: "game.example" }).server, "wss://10.0.0.1:7780/ws",
    "an https page may open only wss://");
});

test("a view goes out at once, then after 16 voxels of movement and never twice in 500 ms", () => {
  const v = new ViewPolicy();
  assert.equal(v.shouldSend([0, 0, 0], 0), true);
  assert.equal(v.shouldSend([100, 0, 0], 499), false, "too soon");
  assert.equal(v.shouldSend([10, 0, 0], 1000), false, "too close");
  assert.equal(v.shouldSend([100, 0, 0], 1000), true);
  assert.equal(v.shouldSend([200, 0, 0], 1200), false);
  v.reset();
  assert.equal(v.shouldSend([200, 0, 0], 1200), true, "a new connection sends at once");
});

test("back-off doubles to its cap with jitter below, and starts again after a Welcome", () => {
  const b = new Backoff({ firstMs: 1000, maxMs: 8000, random: () => 0 });
  assert.deepEqual([b.next(), b.next(), b.next(), b.next(), b.next()], [1000, 2000, 4000, 8000, 8000]);
  b.reset();
  assert.equal(b.next(), 1000);
  assert.equal(new Backoff({ random: () => 1 }).next(), 800, "at most 20 % earlier");
});

test("no automatic reconnection after REPLACED or a token refusal", () => {
  for (const codeName of ["REPLACED", "AUTH_REQUIRED", "BAD_TOKEN", "TOKEN_EXPIRED", "BAD_VERSION"]) assert.equal(shouldRetry({ codeName }), false, codeName);
  for (const e of [undefined, new Error("WebSocket closed (1006)"), { codeName: "SERVER_FULL" }, { codeName: "SHUTTING_DOWN" }]) assert.equal(shouldRetry(e), true);
});

test("each tool sends its edit, within the server's limits", () => {
  const s = { radius: 40, strength: 9, material: 7, carve: false };
  const limits = { maxEditRadius: 16, maxEditStrength: 4 };
  const at = [1, 2, 3];
  const kinds = Object.fromEntries(TOOLS.map((t) => [t.id, editFor(t.id, at, s, limits)]));
  assert.deepEqual(kinds.explode, ["explosion", { center: at, radius: 16, power: 4 }]);
  assert.deepEqual(kinds.add, ["brush", { center: at, radius: 16, strength: 4, remove: false, material: 7 }]);
  assert.equal(kinds.remove[1].remove, true);
  assert.ok(kinds.smooth[1].strength > 0 && kinds.smooth[1].strength <= 1, "smooth strength in (0, 1]");
  assert.deepEqual(kinds.paint, ["paint", { center: at, radius: 16, material: 7 }]);
  assert.deepEqual(kinds.box[1].min, [-15, -14, -13]);
  assert.deepEqual(kinds.box[1].max, [17, 18, 19], "a side of 2·radius: the largest the server takes");
  assert.deepEqual(kinds.sphere, ["stamp", { shape: "sphere", center: at, radius: 16, solid: true, material: 7 }]);
  assert.equal(editFor("sphere", at, { ...s, carve: true }).at(1).solid, false);
  assert.throws(() => editFor("nope", at, s));
});

test("a result line says accepted, clipped, or refused with reason and retry time", () => {
  assert.equal(describeResult("explosion", { statusName: "ACCEPTED", changedChunks: [{}, {}] }), "explosion: accepted (2 chunks)");
  assert.equal(describeResult("brush", { statusName: "ACCEPTED", changedChunks: [{}], clippedBy: [4n] }), "brush: accepted (1 chunk, clipped by region 4)");
  assert.equal(describeResult("brush", { statusName: "RATE_LIMITED", reason: "over budget", retryAfterMs: 120 }), "brush: refused RATE_LIMITED (over budget), retry in 120 ms");
});

test("the palette has the protocol's four terrain materials and a colour for every id", () => {
  const p = paletteBytes();
  assert.equal(p.length, 768);
  assert.deepEqual(MATERIALS.slice(0, 4).map((m) => m.name), ["grass", "dirt", "stone", "sand"]);
  assert.deepEqual([...p.subarray(3, 6)], MATERIALS[0].rgb);
  assert.equal(srgbToLinear(255), 1);
  assert.ok(Math.abs(srgbToLinear(188) - 0.5) < 0.01);
});
