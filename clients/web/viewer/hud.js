// The HUD: connection state, ping, bytes per second received, chunks and triangles held,
// frames per second, whether the current view is complete, and the last edit results.

const RESULTS_SHOWN = 6;

export class Hud {
  /** @param {Document} doc */
  constructor(doc) {
    this.stats = doc.getElementById("stats");
    this.status = doc.getElementById("status");
    this.results = doc.getElementById("results");
  }

  /**
   * @param {{ping: number|null, bytesPerSecond: number, chunks: number, triangles: number,
   *   fps: number, viewComplete: boolean, position: number[], lod: number, radius: number}} s
   */
  show(s) {
    const kb = (s.bytesPerSecond / 1024).toFixed(s.bytesPerSecond < 10240 ? 1 : 0);
    const p = s.position.map((c) => Math.round(c)).join(", ");
    this.stats.textContent = [
      `ping ${s.ping === null ? "–" : `${s.ping} ms`} · ${kb} KiB/s`,
      `${s.chunks} chunks · ${(s.triangles / 1000).toFixed(0)}k triangles`,
      `${s.fps.toFixed(1)} fps · view ${s.viewComplete ? "complete" : "loading…"}`,
      `radius ${s.radius} · lod ${s.lod} · at ${p}`,
    ].join("\n");
  }

  /** @param {string} text @param {"info"|"ok"|"error"} kind */
  setStatus(text, kind) {
    this.status.textContent = text;
    this.status.className = kind;
  }

  /** @param {string} text @param {boolean} ok */
  addResult(text, ok) {
    const line = document.createElement("div");
    line.textContent = text;
    line.className = ok ? "ok" : "error";
    this.results.prepend(line);
    while (this.results.children.length > RESULTS_SHOWN) this.results.lastChild.remove();
  }
}
