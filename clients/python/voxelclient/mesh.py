"""Mesh encoding formats 1 and 2 (PROTOCOL.md section 2): decoding and every check it lists."""
import math
import struct
from array import array

FORMAT = 1
LOD_FORMAT = 2  # a level-of-detail chunk with its seams (section 2.7)
HEADER = 16
LOD_HEADER = 27
SEAM_VERTEX_BYTES = 9
MAX_SEAM_VERTICES = 6 * 2 * 64 * 65 + 12 * 64  # half edges on the faces and chunk edges
MAX_SEAM_TRIANGLES = 6 * 32 * 32 * 48           # 48 per seam cell
FRACTION_ONE = 1024
AXIS_X, AXIS_Y, AXIS_Z = 0, 1, 2


class MeshError(ValueError):
    """The encoding breaks a rule of section 2."""


# ---- CRC-32C (Castagnoli, reflected 0x82F63B78) ----------------------------------------

def _crc_table():
    table = []
    for n in range(256):
        c = n
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        table.append(c)
    return table


_CRC_TABLE = _crc_table()


def crc32c(data):
    crc, table = 0xFFFFFFFF, _CRC_TABLE
    for b in data:
        crc = table[(crc ^ b) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFF


def check_crc(enc):
    """Only the CRC-32C of section 2.1 (what a client that does not decode must check)."""
    if len(enc) < HEADER + 4:
        raise MeshError("encoding of %d bytes is too short" % len(enc))
    if crc32c(enc[:-4]) != struct.unpack_from("<I", enc, len(enc) - 4)[0]:
        raise MeshError("CRC-32C mismatch")


# ---- the case table --------------------------------------------------------------------

# Cell edge e -> (axis, lower sample minus cell), section 2.5.
CELL_EDGES = [
    (AXIS_X, (0, 0, 0)), (AXIS_Y, (1, 0, 0)), (AXIS_X, (0, 1, 0)), (AXIS_Y, (0, 0, 0)),
    (AXIS_X, (0, 0, 1)), (AXIS_Y, (1, 0, 1)), (AXIS_X, (0, 1, 1)), (AXIS_Y, (0, 0, 1)),
    (AXIS_Z, (0, 0, 0)), (AXIS_Z, (1, 0, 0)), (AXIS_Z, (1, 1, 0)), (AXIS_Z, (0, 1, 0)),
]
CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
EDGE_CORNERS = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                (0, 4), (1, 5), (2, 6), (3, 7)]


class Table(list):
    """The 256 cases' triangles, and the file's revision (its "# revision N" line; 1 when
    it has none)."""
    revision = 1


def load_table(path):
    """Parses docs/marching_cubes_tables.txt: a list of 256 tuples of triangles (edge triples)."""
    cases, revision = {}, 1
    with open(path, encoding="ascii") as f:
        for line in f:
            if line.startswith("# revision "):
                revision = int(line.split()[2])
            fields = line.split("#", 1)[0].split()
            if not fields:
                continue
            case, mask, edges = int(fields[0]), int(fields[1], 16), [int(e) for e in fields[2:]]
            _check_case(case, mask, edges)
            cases[case] = tuple(tuple(edges[i:i + 3]) for i in range(0, len(edges), 3))
    if sorted(cases) != list(range(256)):
        raise MeshError("table does not have exactly the cases 0..255")
    table = Table(cases[c] for c in range(256))
    table.revision = revision
    return table


def _check_case(case, mask, edges):
    cut = 0
    for e, (a, b) in enumerate(EDGE_CORNERS):
        if ((case >> a) ^ (case >> b)) & 1:
            cut |= 1 << e
    if cut != mask or len(edges) % 3 or any(not (mask >> e) & 1 for e in edges):
        raise MeshError("table line %d is inconsistent" % case)


# ---- decoding ---------------------------------------------------------------------------

class Mesh:
    """A decoded chunk mesh. Flat arrays: positions/normals are xyz per vertex (float32),
    triangles three vertex indices each. Regular vertex i lies on the lattice edge of axis
    `axis[i]` whose lower sample is `samples[3i:3i+3]`; in format 2 the seam vertices follow
    (`seam_faces`, `seam_edges`: the chunk's seams)."""

    def __init__(self, cells, rows):
        self.cells = cells
        self.rows = rows
        self.positions = array("f")
        self.normals = array("f")
        self.axis = bytearray()
        self.samples = bytearray()
        self.materials = b""
        self.triangles = array("I")
        self.table_triangles = 0
        self.dropped = ()
        self.seam_faces = 0
        self.seam_edges = 0

    @property
    def vertex_count(self):
        return len(self.positions) // 3

    @property
    def regular_vertex_count(self):
        return len(self.axis)

    @property
    def triangle_count(self):
        return len(self.triangles) // 3


class _Reader:
    def __init__(self, data, offset):
        self.data, self.offset = data, offset

    def take(self, n):
        chunk = self.data[self.offset:self.offset + n]
        self.offset += n
        return chunk


def decode(enc, table):
    """Decodes one encoding; raises MeshError on any violation of section 2."""
    enc = bytes(enc)
    cells, counts, seams = _header(enc)
    header = LOD_HEADER if seams else HEADER
    cx, cy, cz = cells
    V, T, D = counts
    faces, edges, S, ST = seams or (0, 0, 0, 0)
    R = (cy + 1) * (cz + 1)
    bitmap_len = (R + 7) // 8
    bitmap = int.from_bytes(enc[header:header + bitmap_len], "little")
    if bitmap >> R:
        raise MeshError("row bitmap has bits at or past R")
    B = (cx + 1 + 7) // 8
    expected = (header + bitmap_len + bitmap.bit_count() * B + 5 * V + 4 * D
                + SEAM_VERTEX_BYTES * S + 12 * ST + 4)
    if len(enc) != expected:
        raise MeshError("length %d, the header says %d" % (len(enc), expected))
    reader = _Reader(enc, header + bitmap_len)
    mesh = Mesh(cells, _rows(reader, bitmap, R, cx, B))
    mesh.seam_faces, mesh.seam_edges = faces, edges
    groups = _groups(mesh.rows, cells)
    cut = groups[-1][0] + groups[-1][1].bit_count()
    if cut != V:
        raise MeshError("V = %d but there are %d cut edges" % (V, cut))
    planes = [reader.take(V) for _ in range(5)]
    _positions(mesh, groups, planes[0], planes[1], cells)
    _normals(mesh, planes[2], planes[3])
    _materials(mesh, planes[4])
    dropped = struct.unpack_from("<%dI" % D, enc, reader.offset)
    reader.take(4 * D)
    _triangles(mesh, groups, table, dropped, seam_cells(faces, edges) if seams else None)
    if mesh.triangle_count != T:
        raise MeshError("T = %d but %d triangles remain" % (T, mesh.triangle_count))
    if seams:
        _seam_section(mesh, reader, S, ST)
    return mesh


def _header(enc):
    check_crc(enc)  # first: a delta applied to a wrong base is reported as what it is
    if enc[0] not in (FORMAT, LOD_FORMAT):
        raise MeshError("format %d is not 1 or 2" % enc[0])
    cells = tuple(enc[1:4])
    if any(c < 1 or c > 32 for c in cells):
        raise MeshError("cells %s out of 1..32" % (cells,))
    if enc[0] == FORMAT:
        return cells, struct.unpack_from("<III", enc, 4), None
    if len(enc) < LOD_HEADER + 4:
        raise MeshError("encoding of %d bytes is too short" % len(enc))
    if cells != (32, 32, 32):
        raise MeshError("a level-of-detail chunk has 32 cells per axis, not %s" % (cells,))
    faces, edges, S, ST = struct.unpack_from("<BHII", enc, 16)
    if faces > 63 or edges > 0xFFF or normalized(faces, edges) != edges:
        raise MeshError("seam faces %#x and edges %#x are not a normalized set" % (faces, edges))
    if S > MAX_SEAM_VERTICES or ST > MAX_SEAM_TRIANGLES:
        raise MeshError("seam counts %d, %d are impossible" % (S, ST))
    return cells, struct.unpack_from("<III", enc, 4), (faces, edges, S, ST)


# ---- seams (section 2.7) ----------------------------------------------------------------

def face_edges(f):
    """The chunk edges lying on face f (0 -x, 1 +x, 2 -y, 3 +y, 4 -z, 5 +z)."""
    axis, side, mask = f // 2, f % 2, 0
    for e in range(12):
        a = e // 4
        if a == axis:
            continue
        bit = e & 1 if (a + 1) % 3 == axis else (e >> 1) & 1
        if bit == side:
            mask |= 1 << e
    return mask


def normalized(faces, edges):
    for f in range(6):
        if (faces >> f) & 1:
            edges |= face_edges(f)
    return edges


def seam_cells(faces, edges):
    """The cells (x, y, z) with a split edge: they contribute no table triangles. A cell
    has one when it is in the layer of a split face (x, y or z is 0 or 31 on that face's
    side) or in the column along a split chunk edge."""
    out = set()
    ends = (0, 31)
    for f in range(6):
        if (faces >> f) & 1:
            axis, at = f // 2, ends[f % 2]
            for u in range(32):
                for v in range(32):
                    p = [u, v]
                    p.insert(axis, at)
                    out.add(tuple(p))
    for e in range(12):
        if (edges >> e) & 1:
            axis, b, c = e // 4, (e // 4 + 1) % 3, (e // 4 + 2) % 3
            for t in range(32):
                p = [0, 0, 0]
                p[axis], p[b], p[c] = t, ends[e & 1], ends[(e >> 1) & 1]
                out.add(tuple(p))
    return out


def _seam_section(mesh, reader, S, ST):
    planes = [reader.take(S) for _ in range(SEAM_VERTEX_BYTES)]
    hx, hy, hz, axes, low, high, us, vs, mats = planes
    material, materials = 0, bytearray(S)
    for i in range(S):
        h, axis = [hx[i], hy[i], hz[i]], axes[i]
        q = low[i] | high[i] << 8
        if axis > 2 or max(h) > 64 or h[axis] >= 64:
            raise MeshError("seam vertex %d lies outside the chunk" % i)
        if q > FRACTION_ONE:
            raise MeshError("seam vertex %d has fraction %d > 1024" % (i, q))
        p = [c / 2 for c in h]
        p[axis] += q / (2 * FRACTION_ONE)
        mesh.positions.extend(p)
        mesh.normals.extend(octahedral(us[i], vs[i]))
        material = (material + mats[i]) & 0xFF
        if material == 0:
            raise MeshError("seam vertex %d has material 0 (air)" % i)
        materials[i] = material
    mesh.materials += bytes(materials)
    total = mesh.vertex_count
    indices = struct.unpack("<%dI" % (3 * ST), reader.take(12 * ST))
    if any(v >= total for v in indices):
        raise MeshError("a seam triangle names a vertex that does not exist")
    mesh.triangles.extend(indices)


def _rows(reader, bitmap, R, cx, B):
    rows, row = [], 0
    for r in range(R):
        if (bitmap >> r) & 1:
            diff = int.from_bytes(reader.take(B), "little")
            if diff == 0 or diff >> (cx + 1):
                raise MeshError("row difference %d is zero or has bits above cells_x" % r)
            row ^= diff
        rows.append(row)
    return rows


def _groups(rows, cells):
    """Per (row, axis) group, in vertex order: (index of its first vertex, cut mask)."""
    cx, cy, cz = cells
    xmask = (1 << cx) - 1
    groups, first = [], 0
    for z in range(cz + 1):
        for y in range(cy + 1):
            r = z * (cy + 1) + y
            row = rows[r]
            masks = ((row ^ (row >> 1)) & xmask,
                     row ^ rows[r + 1] if y < cy else 0,
                     row ^ rows[r + cy + 1] if z < cz else 0)
            for m in masks:
                groups.append((first, m))
                first += m.bit_count()
    return groups


def _bits(mask):
    while mask:
        low = mask & -mask
        yield low.bit_length() - 1
        mask ^= low


def _positions(mesh, groups, low, high, cells):
    cy = cells[1]
    pos, axes, samples = mesh.positions, mesh.axis, mesh.samples
    for g, (first, mask) in enumerate(groups):
        r, axis = divmod(g, 3)
        z, y = divmod(r, cy + 1)
        i = first
        for x in _bits(mask):
            q = low[i] | high[i] << 8
            if q > FRACTION_ONE:
                raise MeshError("vertex %d has fraction %d > 1024" % (i, q))
            p = [x, y, z]
            samples.extend(p)
            p[axis] += q / FRACTION_ONE
            pos.extend(p)
            axes.append(axis)
            i += 1


_OCT = [u * 2 / 255 - 1 for u in range(256)]


def octahedral(u, v):
    """Section 2.4's normal decoding: a unit vector from two bytes."""
    px, py = _OCT[u], _OCT[v]
    nz = 1 - abs(px) - abs(py)
    if nz < 0:
        nx = (1 - abs(py)) * (1 if px >= 0 else -1)
        ny = (1 - abs(px)) * (1 if py >= 0 else -1)
    else:
        nx, ny = px, py
    n = math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx / n, ny / n, nz / n


def _normals(mesh, us, vs):
    out = mesh.normals
    for u, v in zip(us, vs):
        out.extend(octahedral(u, v))


def _materials(mesh, diffs):
    out, m = bytearray(len(diffs)), 0
    for i, d in enumerate(diffs):
        m = (m + d) & 0xFF
        if m == 0:
            raise MeshError("vertex %d has material 0 (air)" % i)
        out[i] = m
    mesh.materials = bytes(out)


# Cell corner bits from four 2-bit row slices a (y,z), b (y+1,z), c (y,z+1), d (y+1,z+1).
_CASE_OF_SLICES = []
for _k in range(256):
    _a, _b, _c, _d = _k & 3, (_k >> 2) & 3, (_k >> 4) & 3, (_k >> 6) & 3
    _CASE_OF_SLICES.append(_a | (_b & 1) << 3 | (_b >> 1) << 2 | _c << 4
                           | (_d & 1) << 7 | (_d >> 1) << 6)


def _mixed_cells(r00, r10, r01, r11, cx):
    """Bit x set when cell x of this cell row has both solid and air corners."""
    some = r00 | r10 | r01 | r11
    every = r00 & r10 & r01 & r11
    return ((some | (some >> 1)) & ~(every & (every >> 1))) & ((1 << cx) - 1)


def _triangles(mesh, groups, table, dropped, seam=None):
    cx, cy, cz = mesh.cells
    rows, out, ordinal, skip = mesh.rows, mesh.triangles, 0, set(dropped)
    if any(b <= a for a, b in zip(dropped, dropped[1:])):
        raise MeshError("dropped ordinals are not strictly increasing")
    stride = cy + 1
    for z in range(cz):
        for y in range(cy):
            r = z * stride + y
            quad = (rows[r], rows[r + 1], rows[r + stride], rows[r + stride + 1])
            for x in _bits(_mixed_cells(*quad, cx)):
                if seam and (x, y, z) in seam:
                    continue
                key = ((quad[0] >> x) & 3) | ((quad[1] >> x) & 3) << 2 \
                    | ((quad[2] >> x) & 3) << 4 | ((quad[3] >> x) & 3) << 6
                for tri in table[_CASE_OF_SLICES[key]]:
                    if ordinal not in skip:
                        out.extend(_vertex(groups, x, y, z, stride, e) for e in tri)
                    ordinal += 1
    if dropped and dropped[-1] >= ordinal:
        raise MeshError("dropped ordinal %d is not a table triangle" % dropped[-1])
    mesh.table_triangles, mesh.dropped = ordinal, tuple(dropped)


def _vertex(groups, x, y, z, stride, edge):
    axis, (dx, dy, dz) = CELL_EDGES[edge]
    first, mask = groups[3 * ((z + dz) * stride + y + dy) + axis]
    sx = x + dx
    if not (mask >> sx) & 1:
        raise MeshError("table edge is not a cut edge")
    return first + (mask & ((1 << sx) - 1)).bit_count()
