// When the viewer sends a new SetView: after the camera has moved far enough from the last
// view's position, and never more often than the server's SetView rate (§4.6: 2 per second)
// so that no view is coalesced away before it completes. A pure class, no I/O.

export class ViewPolicy {
  /**
   * @param {{minIntervalMs?: number, minMove?: number}} [options]
   *   minIntervalMs: at least this long between SetViews (default 500 ms: 2 per second);
   *   minMove: voxels the camera moves before a new view is worth it (default 16)
   */
  constructor(options = {}) {
    this.minIntervalMs = options.minIntervalMs ?? 500;
    this.minMove = options.minMove ?? 16;
    /** @type {number[]|null} the position of the last view sent */
    this.sentAt = null;
    this.sentTime = -Infinity;
  }

  /** Forgets the last view (a new connection must send one at once). */
  reset() {
    this.sentAt = null;
    this.sentTime = -Infinity;
  }

  /**
   * Whether to send a view for this position now; records it when yes.
   * @param {number[]} position world voxels [x, y, z]
   * @param {number} now milliseconds
   * @returns {boolean}
   */
  shouldSend(position, now) {
    if (now - this.sentTime < this.minIntervalMs) return false;
    if (this.sentAt) {
      const d = Math.hypot(position[0] - this.sentAt[0], position[1] - this.sentAt[1], position[2] - this.sentAt[2]);
      if (d < this.minMove) return false;
    }
    this.sentAt = [...position];
    this.sentTime = now;
    return true;
  }
}
