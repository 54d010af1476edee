"""Offline tests of the decoder: the worked example of PROTOCOL.md 2.6 and the refusals of
section 2 and 3 (no server needed)."""
import struct
import unittest

import zstandard

import harness  # noqa: F401  (puts the package on sys.path)
from voxelclient import (CompressionError, MeshError, crc32c, decode, decompress_delta,
                         decompress_full, load_table, proto)
from voxelclient.mesh import normalized, seam_cells

WORKED = bytes.fromhex("01 010101 03000000 01000000 00000000 03 01 01"
                       " 000000 020202 bf9f9f 9fbf9f 030000 e42739aa")
TABLE = load_table(proto.DEFAULT_TABLE)


def with_crc(body):
    return body + struct.pack("<I", crc32c(body))


def worked(**changes):
    """The worked example's bytes (without CRC) with some fields replaced, CRC recomputed."""
    fields = dict(head=WORKED[:4], V=3, T=1, D=0, rows=WORKED[16:19], low=b"\0\0\0",
                  high=b"\2\2\2", u=WORKED[25:28], v=WORKED[28:31], mat=b"\3\0\0", dropped=b"")
    fields.update(changes)
    f = fields
    return with_crc(f["head"] + struct.pack("<III", f["V"], f["T"], f["D"]) + f["rows"]
                    + f["low"] + f["high"] + f["u"] + f["v"] + f["mat"] + f["dropped"])


class WorkedExample(unittest.TestCase):
    def test_table_revision(self):
        self.assertEqual(TABLE.revision, 2)

    def test_crc_check_value(self):
        self.assertEqual(crc32c(b"123456789"), 0xE3069283)

    def test_decode(self):
        self.assertEqual(worked(), WORKED)
        m = decode(WORKED, TABLE)
        self.assertEqual(list(m.positions), [0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5])
        self.assertEqual(list(m.triangles), [0, 1, 2])
        self.assertEqual(m.materials, b"\3\3\3")
        self.assertEqual([round(x, 2) for x in m.normals[:3]], [0.81, 0.40, 0.42])

    def test_dropped_triangle(self):
        m = decode(worked(T=0, D=1, dropped=struct.pack("<I", 0)), TABLE)
        self.assertEqual((m.triangle_count, m.table_triangles, m.dropped), (0, 1, (0,)))


class Refusals(unittest.TestCase):
    def refuse(self, enc, what):
        with self.assertRaises(MeshError, msg=what):
            decode(enc, TABLE)

    def test_each_rule(self):
        cases = {
            "format 3": worked(head=b"\3\1\1\1"),
            "format 2 of 1 cell": worked(head=b"\2\1\1\1"),
            "cells 0": worked(head=b"\1\0\1\1"),
            "cells 33": worked(head=b"\1\41\1\1"),
            "bad CRC": WORKED[:-1] + bytes([WORKED[-1] ^ 1]),
            "one byte more": with_crc(WORKED[:-4] + b"\0"),
            "bitmap bit at R": worked(rows=b"\x13\1\1\1"),
            "zero difference": worked(rows=b"\x07\1\1\0"),
            "difference above cells_x": worked(rows=b"\x03\5\1"),
            "fraction 1025": worked(low=b"\1\0\0", high=b"\4\2\2"),
            "material 0 on a vertex": worked(mat=b"\0\3\0"),
            "V too large": worked(V=4, low=b"\0" * 4, high=b"\2" * 4, u=b"\x9f" * 4,
                                  v=b"\x9f" * 4, mat=b"\3\0\0\0"),
            "T wrong": worked(T=2),
            "dropped not a table triangle": worked(T=0, D=1, dropped=struct.pack("<I", 1)),
            "dropped not increasing": worked(T=0, D=2, dropped=struct.pack("<II", 0, 0)),
            "too short": WORKED[:10],
        }
        for what, enc in cases.items():
            with self.subTest(what):
                self.refuse(enc, what)


def lod(faces=1, edges=None, seam=None, triangles=(0, 1, 2), cells=b"\x20\x20\x20"):
    """A format-2 encoding (section 2.7) of an empty 32^3 chunk plus three seam vertices
    on its -x face and one seam triangle; fields replaceable, CRC recomputed."""
    if edges is None:
        edges = normalized(faces, 0)
    # hx, hy, hz, axis, fraction low, high, normal u, v, material difference per vertex
    seam = seam or [(0, 2, 3, 1, 0, 2, 0x9f, 0x9f, 3), (0, 3, 2, 2, 0, 1, 0x9f, 0x9f, 0),
                    (0, 5, 5, 1, 0, 4, 0x9f, 0x9f, 0)]
    rows = 33 * 33
    body = (b"\2" + cells + struct.pack("<III", 0, 0, 0)
            + struct.pack("<BHII", faces, edges, len(seam), len(triangles) // 3)
            + bytes((rows + 7) // 8)
            + b"".join(bytes(v[k] for v in seam) for k in range(9))
            + struct.pack("<%dI" % len(triangles), *triangles))
    return with_crc(body)


class LodFormat(unittest.TestCase):
    def test_decode(self):
        m = decode(lod(), TABLE)
        self.assertEqual((m.seam_faces, m.seam_edges), (1, normalized(1, 0)))
        self.assertEqual(list(m.positions), [0, 1.25, 1.5, 0, 1.5, 1.125, 0, 3.0, 2.5])
        self.assertEqual(list(m.triangles), [0, 1, 2])
        self.assertEqual(m.materials, b"\3\3\3")

    def test_seam_cells_skip_the_outer_layer_of_split_faces(self):
        cells = seam_cells(1, normalized(1, 0))
        self.assertEqual(cells, {(0, y, z) for y in range(32) for z in range(32)})
        self.assertEqual(len(seam_cells(0, 1)), 32)  # one chunk edge: the cells along it

    def test_refusals(self):
        cases = {
            "edges of a split face missing": lod(edges=0),
            "31 cells": lod(cells=b"\x1f\x20\x20"),
            "axis 3": lod(seam=[(0, 2, 3, 3, 0, 2, 0x9f, 0x9f, 3)], triangles=()),
            "half edge past the chunk": lod(seam=[(0, 64, 3, 1, 0, 2, 0x9f, 0x9f, 3)],
                                            triangles=()),
            "fraction 1025": lod(seam=[(0, 2, 3, 1, 1, 4, 0x9f, 0x9f, 3)], triangles=()),
            "material 0": lod(seam=[(0, 2, 3, 1, 0, 2, 0x9f, 0x9f, 0)], triangles=()),
            "vertex index past the end": lod(triangles=(0, 1, 3)),
            "bad CRC": lod()[:-1] + b"\0",
            "too many seam vertices": with_crc(lod()[:19] + struct.pack("<I", 50689)
                                               + lod()[23:-4]),
        }
        for what, enc in cases.items():
            with self.subTest(what), self.assertRaises(MeshError, msg=what):
                decode(enc, TABLE)


class Frames(unittest.TestCase):
    def test_full_and_delta(self):
        frame = zstandard.ZstdCompressor().compress(WORKED)
        self.assertEqual(decompress_full(frame), WORKED)
        new = worked(mat=b"\7\0\0")
        prefix = zstandard.ZstdCompressionDict(WORKED, dict_type=zstandard.DICT_TYPE_RAWCONTENT)
        delta = zstandard.ZstdCompressor(dict_data=prefix).compress(new)
        self.assertEqual(decompress_delta(delta, WORKED), new)

    def test_refusals(self):
        no_size = zstandard.ZstdCompressor(write_content_size=False).compress(WORKED)
        frame = zstandard.ZstdCompressor().compress(WORKED)
        for what, payload in {"no content size": no_size, "two frames": frame + frame,
                              "truncated": frame[:-2], "not zstd": b"\0" * 16}.items():
            with self.subTest(what), self.assertRaises(CompressionError):
                decompress_full(payload)
