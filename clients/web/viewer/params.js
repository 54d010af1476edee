// The viewer's URL parameters (?server=&token=&pos=x,y,z&lod=&radius=&name=), read once
// at start. No DOM and no three.js: the node tests import it.

/**
 * @typedef {object} ViewerParams
 * @property {string} server   the WebSocket URL (ws(s)://<page host>/ws unless server= says)
 * @property {string} token    a player token (§4.8), "" for an open server
 * @property {[number, number, number]|null} position  pos=x,y,z, or null: above the origin
 * @property {number|null} lod  lod= level, or null: as far as Welcome allows (capped at 6)
 * @property {number} radius   radius= of the level-0 view in chunks
 * @property {string} name     name= of the player (1..32 bytes)
 */

/** The default level-0 radius: 4 chunks around the camera, coarser levels beyond. */
export const DEFAULT_RADIUS = 4;

/**
 * The WebSocket URL of the server that served the page: same host, /ws, wss: under https.
 * @param {{protocol: string, host: string}} location
 */
export function defaultServerUrl(location) {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  return `${scheme}//${location.host || "127.0.0.1:7780"}/ws`;
}

const finite = (s) => s !== null && s.trim() !== "" && Number.isFinite(Number(s));

/**
 * Reads the parameters; a value that does not parse is left at its default.
 * @param {string} search  location.search ("?pos=0,80,0&lod=3")
 * @param {{protocol: string, host: string}} location
 * @returns {ViewerParams}
 */
export function parseParams(search, location) {
  const q = new URLSearchParams(search);
  let position = null;
  const pos = (q.get("pos") ?? "").split(",");
  if (pos.length === 3 && pos.every(finite)) position = /** @type {[number, number, number]} */ (pos.map(Number));
  const lod = q.get("lod");
  const radius = q.get("radius");
  let name = (q.get("name") ?? "").trim();
  if (!name || new TextEncoder().encode(name).length > 32) name = "viewer";
  let server = q.get("server") ?? "";
  // A bare host:port takes the page's scheme: a page served over https may open only wss://.
  if (server && !/^wss?:\/\//.test(server)) server = `${location.protocol === "https:" ? "wss" : "ws"}://${server}`;
  if (server && !/\/ws$/.test(server) && new URL(server).pathname === "/") server = server.replace(/\/?$/, "/ws");
  return {
    server: server || defaultServerUrl(location),
    token: q.get("token") ?? "",
    position,
    lod: finite(lod) && Number(lod) >= 0 ? Math.floor(Number(lod)) : null,
    radius: finite(radius) && Number(radius) >= 1 ? Math.floor(Number(radius)) : DEFAULT_RADIUS,
    name,
  };
}
