// Reconnection after the server went away: exponential back-off with jitter, reset once a
// session got its Welcome; and which server errors mean "do not retry by yourself".

/** Errors after which retrying cannot help until the person acts (PROTOCOL §4.5, §4.8). */
const NO_RETRY = new Set(["REPLACED", "AUTH_REQUIRED", "BAD_TOKEN", "TOKEN_EXPIRED", "BAD_VERSION"]);

/**
 * Whether the viewer should reconnect by itself after a connection ended with this error.
 * REPLACED: the same player joined elsewhere (§4.8 says not to fight it); token errors
 * wait for a new token in the token box.
 * @param {{codeName?: string}|undefined|null} error
 */
export const shouldRetry = (error) => !NO_RETRY.has(error?.codeName ?? "");

export class Backoff {
  /**
   * @param {{firstMs?: number, maxMs?: number, random?: () => number}} [options]
   */
  constructor(options = {}) {
    this.firstMs = options.firstMs ?? 1000;
    this.maxMs = options.maxMs ?? 30000;
    this.random = options.random ?? Math.random;
    this.attempt = 0;
  }

  /** The wait before the next attempt: firstMs·2^n, at most maxMs, minus up to 20 % jitter. */
  next() {
    const base = Math.min(this.maxMs, this.firstMs * 2 ** this.attempt);
    this.attempt++;
    return Math.round(base * (1 - 0.2 * this.random()));
  }

  /** After a session that got its Welcome: the next failure waits firstMs again. */
  reset() {
    this.attempt = 0;
  }
}
