// Colours of materials (PROTOCOL §1: 1 grass, 2 dirt, 3 stone, 4 sand; edits may use any
// 1..255), as 8-bit sRGB triples. Pure: the node tests import it.

/** The materials the tool bar offers, with their names. */
export const MATERIALS = [
  { id: 1, name: "grass", rgb: [96, 142, 62] },
  { id: 2, name: "dirt", rgb: [124, 92, 62] },
  { id: 3, name: "stone", rgb: [128, 126, 122] },
  { id: 4, name: "sand", rgb: [212, 196, 140] },
  { id: 5, name: "snow", rgb: [236, 240, 244] },
  { id: 6, name: "clay", rgb: [178, 96, 64] },
  { id: 7, name: "slate", rgb: [70, 82, 104] },
  { id: 8, name: "gold", rgb: [224, 180, 48] },
];

/** An 8-bit sRGB value as linear light (IEC 61966-2-1), the space three.js shades in. */
export function srgbToLinear(c) {
  const x = c / 255;
  return x <= 0.04045 ? x / 12.92 : ((x + 0.055) / 1.055) ** 2.4;
}

/**
 * 256 × RGB: the known materials, then a stable hash colour for any other id.
 * @returns {Uint8Array}
 */
export function paletteBytes() {
  const out = new Uint8Array(256 * 3);
  for (let id = 0; id < 256; id++) {
    const h = Math.imul(id, 2654435761) >>> 0;
    out.set([80 + (h & 127), 80 + ((h >>> 8) & 127), 80 + ((h >>> 16) & 127)], id * 3);
  }
  for (const m of MATERIALS) out.set(m.rgb, m.id * 3);
  return out;
}
