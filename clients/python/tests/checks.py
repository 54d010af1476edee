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


def occupancy(density):
    """Section 4.4: a sample's occupancy, its int16 density mapped from [-1, 1] onto [0, 1]."""
    return (density + 32767) / 65534


def yield_between(before, after):
    """The material yield (section 4.4) of the change from one sample answer to another of
    the same box: {material: (removed, added)}, material 0 left out."""
    out = {}

    def add(m, removed, added):
        if m:
            r, a = out.get(m, (0.0, 0.0))
            out[m] = (r + removed, a + added)
    for d0, m0, d1, m1 in zip(before.densities, before.materials, after.densities,
                              after.materials):
        if m0 == m1:
            rise = occupancy(d1) - occupancy(d0)
            if rise:
                add(m0, max(-rise, 0.0), max(rise, 0.0))
        else:
            add(m0, occupancy(d0), 0.0)
            add(m1, 0.0, occupancy(d1))
    return out


def first_hit(chunks, origin, direction, max_distance):
    """The nearest crossing of the ray with the triangles of the held level-0 meshes, in
    world voxels (64-bit floats): (distance, point, normal interpolated from the vertex
    normals, material of the vertex nearest the point), or None."""
    n = math.sqrt(_dot(direction, direction))
    d = tuple(c / n for c in direction)
    end = tuple(o + max_distance * c for o, c in zip(origin, d))
    lo = [min(a, b) for a, b in zip(origin, end)]
    hi = [max(a, b) for a, b in zip(origin, end)]
    best = None
    for coord, held in chunks.items():
        base = [CHUNK * c for c in coord]
        if any(base[a] > hi[a] + 1 or base[a] + CHUNK < lo[a] - 1 for a in range(3)):
            continue
        m = held.mesh
        pos = m.positions
        for t in range(0, len(m.triangles), 3):
            vs = m.triangles[t:t + 3]
            a, b, c = (tuple(pos[3 * v + k] + base[k] for k in range(3)) for v in vs)
            hit = _ray_triangle(origin, d, a, b, c)
            if hit is None or hit[0] > max_distance or (best and hit[0] >= best[0]):
                continue
            s, u, v = hit
            w = (1 - u - v, u, v)
            point = tuple(o + s * k for o, k in zip(origin, d))
            normal = [sum(w[i] * m.normals[3 * vs[i] + k] for i in range(3)) for k in range(3)]
            length = math.sqrt(_dot(normal, normal))
            corners = (a, b, c)
            nearest = min(range(3), key=lambda i: dist2(corners[i], point))
            best = (s, point, tuple(x / length for x in normal), m.materials[vs[nearest]])
    return best


def _ray_triangle(o, d, a, b, c, eps=1e-12):
    """Möller-Trumbore, both sides: (distance, u, v) or None."""
    e1, e2 = _sub(b, a), _sub(c, a)
    p = _cross(d, e2)
    det = _dot(e1, p)
    if abs(det) < eps:
        return None
    t = _sub(o, a)
    u = _dot(t, p) / det
    if u < -1e-9 or u > 1 + 1e-9:
        return None
    q = _cross(t, e1)
    v = _dot(d, q) / det
    if v < -1e-9 or u + v > 1 + 1e-9:
        return None
    s = _dot(e2, q) / det
    return (s, u, v) if s >= 0 else None
