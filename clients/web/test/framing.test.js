// TCP framing (PROTOCOL §4.1): any split of the stream gives the same frames; a truncated
// frame waits; a length over the limit is refused before anything is allocated.
import assert from "node:assert/strict";
import { test } from "node:test";
import { encodeFrame, FrameDecoder, FrameError } from "../src/framing.js";
import { decodeEnvelope, encodeEnvelope } from "../src/messages.js";

const bodies = [new Uint8Array(0), Uint8Array.from([1, 2, 3]), Uint8Array.from({ length: 300 }, (_, i) => i & 255)];
const stream = () => {
  const frames = bodies.map((b) => encodeFrame(b));
  const out = new Uint8Array(frames.reduce((n, f) => n + f.length, 0));
  let p = 0;
  for (const f of frames) {
    out.set(f, p);
    p += f.length;
  }
  return out;
};

test("a frame is the u32 LE length then the body", () => {
  assert.deepEqual([...encodeFrame(Uint8Array.from([9, 8]))], [2, 0, 0, 0, 9, 8]);
  assert.throws(() => encodeFrame(new Uint8Array(10), 9), FrameError);
});

test("every truncation waits for the rest, every split point gives the same frames", () => {
  const s = stream();
  for (let cut = 0; cut <= s.length; cut++) {
    const d = new FrameDecoder();
    const first = d.push(s.subarray(0, cut));
    // Only complete frames come out of the first part.
    let complete = 0;
    let p = 0;
    for (const b of bodies) {
      if (p + 4 + b.length <= cut) complete++;
      p += 4 + b.length;
    }
    assert.equal(first.length, complete, `cut ${cut}`);
    const rest = d.push(s.subarray(cut));
    assert.deepEqual([...first, ...rest].map((f) => [...f]), bodies.map((b) => [...b]));
    assert.equal(d.pending, 0);
  }
});

test("byte by byte", () => {
  const s = stream();
  const d = new FrameDecoder();
  const got = [];
  for (let i = 0; i < s.length; i++) got.push(...d.push(s.subarray(i, i + 1)));
  assert.equal(got.length, bodies.length);
});

test("a length over the limit is refused from its four bytes, before allocating", () => {
  const d = new FrameDecoder({ maxBytes: 1000 });
  assert.deepEqual(d.push(Uint8Array.from([0xe9, 0x03, 0])), []);  // 1001, three bytes: waits
  assert.throws(() => d.push(Uint8Array.from([0])), /frame of 1001 bytes is over the limit of 1000/);
  assert.throws(() => d.push(Uint8Array.from([1])), FrameError, "stays refused");
  // 4 GiB declared with the default limit: refused at once.
  assert.throws(() => new FrameDecoder().push(Uint8Array.from([0xff, 0xff, 0xff, 0xff])), /over the limit of 16777216/);
  // Exactly the limit is accepted.
  const ok = new FrameDecoder({ maxBytes: 3 });
  assert.equal(ok.push(encodeFrame(Uint8Array.from([1, 2, 3]))).length, 1);
});

test("Envelopes round-trip; an unknown body decodes as kind null", () => {
  const bytes = encodeEnvelope({ ping: { nonce: 7 } });
  const { kind, message } = decodeEnvelope(bytes);
  assert.equal(kind, "ping");
  assert.equal(Number(message.nonce), 7);
  // Field 99 (length-delimited, empty): a newer server's message.
  assert.deepEqual(decodeEnvelope(Uint8Array.from([0x9a, 0x06, 0x00])), { kind: null, message: null });
  assert.deepEqual(decodeEnvelope(new Uint8Array(0)), { kind: null, message: null });
});
