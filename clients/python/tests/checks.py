"""Geometry checks of decoded meshes against PROTOCOL.md section 1."""
import math
from array import array

CHUNK = 32


def view_sphere(center, radius):
    """Every chunk c with |c - center|^2 <= radius^2 (section 4.2, item 3)."""
    cx, cy, cz = center
    r = radius
    return {(cx + x, cy + y, cz + z)
            for x in range(-r, r + 1) for y in range(-r, r + 1) for z in range(-r, r + 1)
            if x * x + y * y + z * z <= r * r}


def dist2(a, b):
    return sum((p - q) ** 2 for p, q in zip(a, b))


def world_positions(coord, mesh):
    """float32 world positions: 32*coord + local, rounded to float32 as the page computes."""
    origin = [CHUNK * c for c in coord]
    return array("f", (p + origin[i % 3] for i, p in enumerate(mesh.positions)))


def _vertex(values, i):
    return values[3 * i], values[3 * i + 1], values[3 * i + 2]


def _sub(a, b):
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def triangle_stats(mesh):
    """Lists of triangles: (of zero area, wound against the sum of their vertex normals,
    wound against the air side). The air side of a triangle is the sum over its vertices of
    the unit step along the vertex's edge from its solid sample to its air sample.
    Positions are multiples of 1/1024, so the cross product is exact."""
    pos, nor, tri = mesh.positions, mesh.normals, mesh.triangles
    zero, against_normals, against_air = [], [], []
    for t in range(len(tri) // 3):
        vs = tri[3 * t:3 * t + 3]
        a, b, c = (_vertex(pos, v) for v in vs)
        face = _cross(_sub(b, a), _sub(c, a))
        if face == (0.0, 0.0, 0.0):
            zero.append(t)
            continue
        n = [sum(k) for k in zip(*(_vertex(nor, v) for v in vs))]
        if _dot(face, n) <= 0:
            against_normals.append(t)
        if _dot(face, _air_side(mesh, vs)) <= 0:
            against_air.append(t)
    return zero, against_normals, against_air


def _air_side(mesh, vertices):
    d = [0, 0, 0]
    for v in vertices:
        d[mesh.axis[v]] += 1 if solid(mesh, *_vertex(mesh.samples, v)) else -1
    return d


def on_sample(mesh, v):
    """True when vertex v's fraction is 0 or 1024: it lies exactly on a sample."""
    return all(float(p).is_integer() for p in _vertex(mesh.positions, v))


def solid(mesh, x, y, z):
    cy = mesh.cells[1]
    return (mesh.rows[z * (cy + 1) + y] >> x) & 1


def normal_stats(mesh):
    """(normals not of unit length, normals pointing from air to solid along their edge)."""
    not_unit, backwards = [], []
    for i in range(mesh.vertex_count):
        n = _vertex(mesh.normals, i)
        if abs(math.sqrt(_dot(n, n)) - 1) > 1e-5:
            not_unit.append(i)
        axis = mesh.axis[i]
        lower = _vertex(mesh.samples, i)
        # solid lower sample: the air is towards +axis, so the normal's component is > 0
        sign = 1 if solid(mesh, *lower) else -1
        if n[axis] * sign <= 0:
            backwards.append(i)
    return not_unit, backwards


def face_vertices(coord, mesh, axis, side):
    """World positions (float32 triples) of the vertices on the chunk face `side` (0 or the
    cell count) of `axis`: those on edges across the face, with the sample on the face."""
    world = world_positions(coord, mesh)
    out = []
    for i in range(mesh.vertex_count):
        if mesh.axis[i] != axis and mesh.samples[3 * i + axis] == side:
            out.append(_vertex(world, i))
    return sorted(out)


def shared_faces(chunks):
    """For every pair of held neighbours (c, c + axis): (pair, axis, vertices of c, of c+1)."""
    pairs = []
    for c, held in chunks.items():
        for axis in range(3):
            n = list(c)
            n[axis] += 1
            other = chunks.get(tuple(n))
            if other is None:
                continue
            mine = face_vertices(c, held.mesh, axis, held.mesh.cells[axis])
            theirs = face_vertices(tuple(n), other.mesh, axis, 0)
            pairs.append(((c, tuple(n)), axis, mine, theirs))
    return pairs
