// The edit each tool sends for a picked surface point (PROTOCOL §4.4), clamped to the
// server's limits from Welcome. Pure: no DOM, no three.js.

/** The tools, in the order of the tool bar. */
export const TOOLS = [
  { id: "explode", label: "Explode" },
  { id: "add", label: "Brush +" },
  { id: "remove", label: "Brush −" },
  { id: "smooth", label: "Smooth" },
  { id: "paint", label: "Paint" },
  { id: "box", label: "Stamp box" },
  { id: "sphere", label: "Stamp sphere" },
];

/**
 * @typedef {object} ToolSettings
 * @property {number} radius    voxels
 * @property {number} strength  density per edit (explosion power; smooth uses strength/limit)
 * @property {number} material  1..255 for paint, brush and stamps
 * @property {boolean} carve    stamps make air instead of solid
 */

/**
 * The Client.edit() arguments of a tool applied at a world point.
 * @param {string} tool a TOOLS id
 * @param {number[]} point world voxels [x, y, z]
 * @param {ToolSettings} s
 * @param {{maxEditRadius?: number, maxEditStrength?: number}} [limits] Welcome's (0: none known)
 * @returns {[string, object]} kind and parameters
 */
export function editFor(tool, point, s, limits = {}) {
  const maxR = limits.maxEditRadius || Infinity;
  const maxS = limits.maxEditStrength || Infinity;
  const radius = Math.min(Math.max(s.radius, 0.5), maxR);
  const strength = Math.min(Math.max(s.strength, 0.01), maxS);
  const center = [point[0], point[1], point[2]];
  const material = Math.min(255, Math.max(1, Math.round(s.material)));
  switch (tool) {
    case "explode": return ["explosion", { center, radius, power: strength }];
    case "add": return ["brush", { center, radius, strength, remove: false, material }];
    case "remove": return ["brush", { center, radius, strength, remove: true }];
    case "smooth": return ["smooth", { center, radius, strength: Math.min(1, strength / Math.min(maxS, 4)) }];
    case "paint": return ["paint", { center, radius, material }];
    case "box": return ["stamp", { shape: "box", min: center.map((c) => c - radius), max: center.map((c) => c + radius), solid: !s.carve, material }];
    case "sphere": return ["stamp", { shape: "sphere", center, radius, solid: !s.carve, material }];
    default: throw new Error(`unknown tool ${tool}`);
  }
}

/**
 * One line for an EditResult: accepted, clipped by regions, or refused with its reason and
 * when to retry.
 * @param {string} what e.g. "explosion"
 * @param {{statusName: string, reason?: string, changedChunks?: any[], retryAfterMs?: number, clippedBy?: bigint[]}} r
 */
export function describeResult(what, r) {
  if (r.statusName === "ACCEPTED") {
    const n = r.changedChunks?.length ?? 0;
    const clipped = r.clippedBy?.length ? `, clipped by region ${r.clippedBy.join(", ")}` : "";
    return `${what}: accepted (${n} chunk${n === 1 ? "" : "s"}${clipped})`;
  }
  const retry = r.retryAfterMs ? `, retry in ${r.retryAfterMs} ms` : "";
  return `${what}: refused ${r.statusName}${r.reason ? ` (${r.reason})` : ""}${retry}`;
}
