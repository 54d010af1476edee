// The marching-cubes case table (docs/marching_cubes_tables.txt, PROTOCOL §2.5): one line
// per case 0..255, "case mask e0 e1 e2 ...", with a "# revision N" comment line (none: 1).
import TABLE_TEXT from "./generated/mc_table.js";

/**
 * @typedef {object} CaseTable
 * @property {number} revision   the table's "# revision" (1 when the file has none)
 * @property {Uint16Array} edgeMask  per case: bit e set when cell edge e is cut
 * @property {Uint16Array} offset  per case (257 entries): where its edges begin in `edges`
 * @property {Uint8Array} edges    cell edges, three per triangle, case after case
 */

// Bourke's edge numbering: the corners each cell edge joins (PROTOCOL §2.5).
const EDGE_CORNERS = [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]];

/**
 * Parses the table's text; refuses anything that is not 256 well-formed cases.
 * @param {string} text
 * @returns {CaseTable}
 */
export function parseTable(text) {
  let revision = 1;
  const lines = new Array(256);
  for (const raw of text.split("\n")) {
    const line = raw.trim();
    if (line === "") continue;
    if (line.startsWith("#")) {
      const m = /^#\s*revision\s+(\d+)\s*$/.exec(line);
      if (m) revision = Number(m[1]);
      continue;
    }
    const f = line.split(/\s+/);
    const c = Number(f[0]);
    if (!Number.isInteger(c) || c < 0 || c > 255 || lines[c]) throw new Error(`mc table: bad case line "${line}"`);
    const mask = Number.parseInt(f[1], 16);
    const edges = f.slice(2).map(Number);
    if (!Number.isInteger(mask) || edges.length % 3 !== 0 ||
        edges.some((e) => !Number.isInteger(e) || e < 0 || e > 11 || !((mask >> e) & 1))) {
      throw new Error(`mc table: bad case line "${line}"`);
    }
    lines[c] = { mask, edges };
  }
  const edgeMask = new Uint16Array(256);
  const offset = new Uint16Array(257);
  let total = 0;
  for (let c = 0; c < 256; c++) {
    if (!lines[c]) throw new Error(`mc table: case ${c} missing`);
    total += lines[c].edges.length;
  }
  const edges = new Uint8Array(total);
  let at = 0;
  for (let c = 0; c < 256; c++) {
    edgeMask[c] = lines[c].mask;
    offset[c] = at;
    edges.set(lines[c].edges, at);
    at += lines[c].edges.length;
  }
  offset[256] = at;
  // Each case's mask must be the edges whose two corners differ (so that a triangle's
  // edges are always cut and its vertices exist).
  for (let c = 0; c < 256; c++) {
    let mask = 0;
    for (let e = 0; e < 12; e++) mask |= (((c >> EDGE_CORNERS[e][0]) ^ (c >> EDGE_CORNERS[e][1])) & 1) << e;
    if (mask !== edgeMask[c]) throw new Error(`mc table: case ${c} has mask 0x${edgeMask[c].toString(16)}, its corners cut 0x${mask.toString(16)}`);
  }
  return { revision, edgeMask, offset, edges };
}

/** The table this package was built with (docs/marching_cubes_tables.txt). @type {CaseTable} */
export const DEFAULT_TABLE = parseTable(TABLE_TEXT);
