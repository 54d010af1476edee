#!/usr/bin/python3
"""Counts in binary little-endian PLY meshes, to set voxel-cli's beside VTK's (issue 15):
triangles, triangles of non-zero area (in float64 from the file's float32 positions),
vertices, vertices no triangle uses, vertices sharing a position with another.

    /usr/bin/python3 bench/scripts/mesh_stats.py A.ply [B.ply]

With two files, also the relative difference of their non-zero-area triangle counts.
Needs python3-numpy."""
import sys

import numpy as np

PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
             "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
             "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
             "float64": "f8"}


def read_ply(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    elements, current = [], None
    for line in data[:end].decode("ascii").splitlines():
        w = line.split()
        if w[0] == "format" and w[1] != "binary_little_endian":
            raise SystemExit(f"{path}: only binary_little_endian PLY is read")
        if w[0] == "element":
            current = {"name": w[1], "count": int(w[2]), "props": []}
            elements.append(current)
        elif w[0] == "property":
            current["props"].append(w[1:])
    at, vertices, faces = end, None, None
    for e in elements:
        if e["name"] == "vertex":
            dtype = np.dtype([(p[-1], "<" + PLY_TYPES[p[0]]) for p in e["props"]])
            vertices = np.frombuffer(data, dtype, e["count"], at)
            at += dtype.itemsize * e["count"]
        elif e["name"] == "face":
            (_, count_type, index_type, _), = e["props"]
            dtype = np.dtype([("n", "<" + PLY_TYPES[count_type]),
                              ("i", "<" + PLY_TYPES[index_type], 3)])
            faces = np.frombuffer(data, dtype, e["count"], at)
            if faces.size and not np.all(faces["n"] == 3):
                raise SystemExit(f"{path}: only triangles are read")
            at += dtype.itemsize * e["count"]
    positions = np.stack([vertices["x"], vertices["y"], vertices["z"]], axis=1)
    return positions, faces["i"].astype(np.int64)


def stats(path):
    p, t = read_ply(path)
    a, b, c = (p[t[:, k]].astype(np.float64) for k in range(3))
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    used = np.zeros(len(p), bool)
    used[t.ravel()] = True
    distinct = len(np.unique(p, axis=0))
    return {"triangles": len(t), "nonzero_area": int(np.count_nonzero(area2 > 0)),
            "vertices": len(p), "unused_vertices": int(np.count_nonzero(~used)),
            "duplicate_positions": len(p) - distinct}


def main():
    results = [stats(path) for path in sys.argv[1:]]
    for path, r in zip(sys.argv[1:], results):
        print(path + ": " + ", ".join(f"{k} {v}" for k, v in r.items()))
    if len(results) == 2:
        a, b = results[0]["nonzero_area"], results[1]["nonzero_area"]
        print(f"non-zero-area triangles: {a} vs {b}, difference {100.0 * (a - b) / b:+.4f} %")


if __name__ == "__main__":
    main()
