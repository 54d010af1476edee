"""End-to-end test of the reference Python client against a real voxeld.

Run: VOXELD=/path/to/voxeld /usr/bin/python3 -m unittest -v test_voxeld   (from this folder)
"""
import math
import os
import struct
import time
import unittest

import checks
import harness as h
from harness import Shared
from voxelclient import Client, volumes
from voxelclient.server import Voxeld

ORIGIN_VIEW = (16.0, 16.0, 16.0)  # centre chunk (0, 0, 0)


def setUpModule():
    h.start()


def tearDownModule():
    code, errors, elapsed = h.stop()
    shutting_down = Shared.pb.Error.SHUTTING_DOWN
    if code != 0 or shutting_down not in errors or elapsed > h.TEST_BUDGET:
        raise AssertionError("voxeld stop: exit %s, watcher got %s, test took %.1f s"
                             % (code, errors, elapsed))


class Case(unittest.TestCase):
    """Clients made here are closed when the test ends."""

    def connect(self, name):
        return self._closing(h.connect(name))

    def raw(self):
        return self._closing(h.raw_client())

    def fresh(self, position, radius):
        client, ready = h.fresh_view(position, radius)
        self._closing(client)
        return client, ready

    def _closing(self, client):
        self.addCleanup(client.close)
        return client


class T1Session(Case):
    def test_welcome(self):
        c = self.connect("welcome")
        w = c.welcome
        self.assertTrue(w.server_version)
        self.assertEqual((w.world_seed, w.chunk_size, w.protocol_version, w.mesh_format),
                         (1, 32, 1, 1))
        self.assertEqual((w.max_view_radius, w.max_frame_bytes, w.max_edits_in_flight),
                         (12, 65536, 256))
        self.assertGreater(w.max_edit_radius, 0)
        self.assertGreater(w.max_edit_strength, 0)
        self.assertGreaterEqual(w.players, 1)
        self.assertEqual((w.edit_budget_per_second, w.edit_budget_burst), (300000, 600000))
        self.assertEqual(w.max_set_views_per_second, 2)
        self.assertEqual((w.max_connections_per_address, w.max_resync_chunks), (16, 64))
        h.sync(c, 12345)

    def test_view_ready(self):
        c = self.connect("viewer")
        ready = h.load_view(c, ORIGIN_VIEW, 3, 1001)
        sphere = checks.view_sphere((0, 0, 0), 3)
        self.assertEqual(ready.view_id, 1001)
        center = ready.center
        self.assertEqual((center.x, center.y, center.z, ready.radius), (0, 0, 0, 3))
        meshes = [d for k, d in c.log if k == "chunk_mesh"]
        coords = [d[0] for d in meshes]
        self.assertEqual(len(coords), len(set(coords)), "a chunk was sent twice")
        self.assertTrue(all(d[2] == 0 for d in meshes), "first copies must be full")
        self.assertEqual(ready.chunks_sent, len(c.chunks))
        self.assertEqual(set(c.chunks), set(coords))
        self.assertLessEqual(set(coords), sphere)
        self.assertEqual(ready.chunks_sent + ready.chunks_empty, len(sphere))
        dists = [checks.dist2(x, (0, 0, 0)) for x in coords]
        self.assertEqual(dists, sorted(dists), "chunks new to the client go nearest first")
        self.assertEqual(c.log[-1][0], "view_ready")
        # the same SetView again: one more ViewReady, no mesh
        before = len(c.log)
        again = h.load_view(c, ORIGIN_VIEW, 3, 1002)
        self.assertEqual((again.chunks_sent, again.chunks_empty),
                         (ready.chunks_sent, ready.chunks_empty))
        self.assertEqual([k for k, _ in c.log[before:]], ["view_ready"])
        self._move(c)

    def _move(self, c):
        held_before = set(c.chunks)
        ready = h.load_view(c, (16.0 + 32, 16.0, 16.0), 3, 1003)
        sphere = checks.view_sphere((1, 0, 0), 3)
        self.assertEqual(set(c.unloaded), held_before - sphere)
        self.assertLessEqual(set(c.chunks), sphere)
        self.assertEqual(ready.chunks_sent, len(c.chunks))
        self.assertEqual(ready.chunks_sent + ready.chunks_empty, len(sphere))


class T2Meshes(unittest.TestCase):
    """Every mesh of a radius-3 view decodes (the client decodes each one: CRC, every
    check of section 2, triangles from the table); then the geometry of section 1."""

    @classmethod
    def setUpClass(cls):
        cls.client, cls.ready = h.fresh_view(ORIGIN_VIEW, 3, "meshes")
        cls.chunks = cls.client.chunks

    @classmethod
    def tearDownClass(cls):
        cls.client.close()

    def test_decoded(self):
        self.assertEqual(self.client.failures, [])
        self.assertGreater(len(self.chunks), 10)
        for coord, held in self.chunks.items():
            m = held.mesh
            self.assertEqual(m.triangle_count, m.table_triangles - len(m.dropped), coord)
            self.assertTrue(set(m.materials) <= {1, 2, 3, 4}, (coord, set(m.materials)))

    def stats(self):
        if not hasattr(self, "_stats"):
            T2Meshes._stats = {c: checks.triangle_stats(held.mesh)
                               for c, held in self.chunks.items()}
        return self._stats

    def test_no_zero_area_triangle(self):
        zero = {c: s[0] for c, s in self.stats().items() if s[0]}
        self.assertEqual(zero, {}, "zero-area triangles the server did not drop")

    def test_winding(self):
        total = against_normals = 0
        for coord, (_, normals, air) in self.stats().items():
            self.assertEqual(air, [], "triangles of %s wound against the air side" % (coord,))
            total += self.chunks[coord].mesh.triangle_count
            against_normals += len(normals)
        # per-vertex (gradient) normals may disagree with a face now and then
        self.assertLess(against_normals, total * 0.005, "%d of %d triangles wound against "
                        "their vertex normals" % (against_normals, total))

    def test_normals(self):
        count = backwards = 0
        for coord, held in self.chunks.items():
            not_unit, wrong = checks.normal_stats(held.mesh)
            self.assertEqual(not_unit, [], coord)
            count += held.mesh.vertex_count
            backwards += len(wrong)
        self.assertLess(backwards, count * 0.02, "%d of %d normals point from air to solid "
                        "along their edge" % (backwards, count))

    def test_shared_faces_bit_identical(self):
        pairs = checks.shared_faces(self.chunks)
        self.assertGreater(len(pairs), 10)
        compared = 0
        for pair, axis, mine, theirs in pairs:
            self.assertEqual(mine, theirs, "face %s axis %d" % (pair, axis))
            compared += len(mine)
        self.assertGreater(compared, 100)


class T3Edits(Case):
    def test_every_edit_kind_then_equal_to_fresh_client(self):
        c = self.connect("editor")
        h.load_view(c, ORIGIN_VIEW, 2, 1)
        p = h.surface_point(c, (0, 0, 0))
        for kind, fields in edits_at(p):
            with self.subTest(kind=kind, fields=sorted(fields)):
                self._edit(c, kind, fields)
        h.sync(c, 1)
        self.assertEqual(c.failures, [])
        fresh, _ = self.fresh(ORIGIN_VIEW, 2)
        self.assertEqual(sorted(c.chunks), sorted(fresh.chunks))
        for coord, held in c.chunks.items():
            self.assertEqual(held.version, fresh.chunks[coord].version, coord)
            self.assertEqual(held.encoding, fresh.chunks[coord].encoding, coord)

    def _edit(self, c, kind, fields):
        held = {k: v.version for k, v in c.chunks.items()}
        seen = len(c.log)
        rid = c.edit(kind, **fields)
        result = c.wait_result(rid)
        self.assertEqual(result.status, Shared.pb.EditResult.ACCEPTED, result.reason)
        changed = {(x.x, x.y, x.z) for x in result.changed_chunks}
        self.assertTrue(changed, "an accepted edit changed no chunk")
        waiting = {k: v for k, v in held.items() if k in changed}
        self.assertTrue(waiting, "the edit changed no chunk the client holds")
        h.wait_newer(c, waiting)
        h.sync(c, rid)
        log = c.log[seen:]
        deltas = [d for k, d in log if k == "chunk_mesh" and d[2] != 0]
        self.assertTrue(deltas, "no delta followed the edit")
        first_mesh = min(i for i, (k, d) in enumerate(log) if k == "chunk_mesh" and d[0] in changed)
        self.assertLess(log.index(("edit_result", rid)), first_mesh, "EditResult before its meshes")
        if fields.get("material"):
            held_now = [c.chunks[k].mesh.materials for k in changed if k in c.chunks]
            self.assertTrue(any(fields["material"] in m for m in held_now), "material not seen")
        self.assertEqual(c.result_log.count(rid), 1)


class T3bResend(Case):
    def test_a_resent_edit_id_is_answered_not_applied_twice(self):
        first = self.connect("resender")
        h.load_view(first, ORIGIN_VIEW, 1, 1)
        p = h.surface_point(first, (0, 0, 0))
        rid = first.edit("explosion", edit_id=0x5eed, center=p, radius=4, power=2)
        result = first.wait_result(rid)
        self.assertEqual(result.status, Shared.pb.EditResult.ACCEPTED, result.reason)
        self.assertFalse(result.already_applied)
        self.assertTrue(result.changed_chunks)
        self.assertTrue(result.volumes, "an accepted explosion yields material (4.4)")
        first.close()
        again = self.connect("resender")  # a reconnect: the same player resends it
        rid = again.edit("explosion", edit_id=0x5eed, center=p, radius=4, power=2)
        result = again.wait_result(rid)
        self.assertEqual(result.status, Shared.pb.EditResult.ACCEPTED, result.reason)
        self.assertTrue(result.already_applied, "the resend was applied again")
        self.assertEqual(len(result.changed_chunks), 0)
        self.assertEqual(len(result.volumes), 0, "a resend yields nothing (4.4)")
        other = self.connect("someone-else")  # another player's edit with the same id
        rid = other.edit("explosion", edit_id=0x5eed, center=p, radius=4, power=2)
        result = other.wait_result(rid)
        self.assertEqual(result.status, Shared.pb.EditResult.ACCEPTED, result.reason)
        self.assertFalse(result.already_applied)


def edits_at(p):
    x, y, z = p
    return [
        ("paint", dict(center=p, radius=6, material=7)),
        ("brush", dict(center=p, radius=4, strength=2, material=5)),
        ("smooth", dict(center=p, radius=5, strength=0.8)),
        ("brush", dict(center=p, radius=3, strength=2, remove=True)),
        ("stamp", dict(shape="box", min=(x - 3, y - 2, z - 3), max=(x + 3, y + 4, z + 3),
                       solid=True, material=9)),
        ("stamp", dict(shape="sphere", center=(x + 2, y + 3, z), radius=3, solid=False)),
        ("explosion", dict(center=p, radius=5, power=2)),
    ]


class T4Resync(Case):
    def test_corrupt_base_detected_and_resynced(self):
        c = self.connect("resyncer")
        h.load_view(c, ORIGIN_VIEW, 1, 1)
        p = h.surface_point(c, (0, 0, 0))
        k = (0, 0, 0)
        c.chunks[k].encoding = bytes(b ^ 0x5A for b in c.chunks[k].encoding)
        rid = c.edit("brush", center=p, radius=3, strength=1, material=6)
        self.assertEqual(c.wait_result(rid).status, Shared.pb.EditResult.ACCEPTED)
        c.pump(lambda: c.failures and k in c.chunks, 10)
        self.assertEqual([f[0] for f in c.failures], [k])
        self.assertIn("CRC", c.failures[0][1])
        self.assertEqual(c.received[-1][:1] + c.received[-1][2:3], (k, 0), "full copy")
        fresh, _ = self.fresh(ORIGIN_VIEW, 1)
        self.assertEqual(c.chunks[k].encoding, fresh.chunks[k].encoding)
        self.assertEqual(c.chunks[k].version, fresh.chunks[k].version)
        # later changes are deltas against the resynced copy
        version = c.chunks[k].version
        rid = c.edit("brush", center=p, radius=3, strength=1, remove=True)
        self.assertEqual(c.wait_result(rid).status, Shared.pb.EditResult.ACCEPTED)
        h.wait_newer(c, {k: version})
        self.assertNotEqual(c.received[-1][2], 0)
        self.assertEqual(len(c.failures), 1)

    def test_resync_of_held_and_outside_chunks(self):
        c = self.connect("resync2")
        h.load_view(c, ORIGIN_VIEW, 1, 1)
        k = (0, 0, 0)
        old = c.chunks[k]
        c.resync([k, (40, 0, 40)])
        c.pump(lambda: k in c.chunks, 10)
        h.sync(c, 2)
        self.assertEqual((c.chunks[k].version, c.chunks[k].encoding), (old.version, old.encoding))
        got = [d for kind, d in c.log if kind == "chunk_mesh"]
        self.assertEqual(got[-1], (k, old.version, 0))
        self.assertNotIn((40, 0, 40), [d[0] for d in got])
        self.assertEqual(c.errors, [])


    def test_resync_twice_sends_at_most_two_copies(self):
        """PROTOCOL.md 4.3/4.6: each Resync is answered with one full copy, the same version
        again if nothing changed; a client must take it (not resync it again)."""
        c = self.connect("resync3")
        h.load_view(c, ORIGIN_VIEW, 1, 1)
        seen = len(c.log)
        c.resync([(0, 0, 0)])
        c.resync([(0, 0, 0)])
        c.pump(lambda: (0, 0, 0) in c.chunks, 10)
        h.sync(c, 3)
        h.sync(c, 4)  # a second round trip: copies still queued behind the first Pong
        copies = [d for k, d in c.log[seen:] if k == "chunk_mesh"]
        self.assertLessEqual(len(copies), 2, copies)

    def test_resync_over_limit_is_ignored(self):
        c = self.connect("resync4")
        h.load_view(c, ORIGIN_VIEW, 1, 1)
        seen = len(c.log)
        coords = [c.chunk_coord((0, 0, 0))] * (c.welcome.max_resync_chunks + 1)
        c.send_message(resync=Shared.pb.Resync(coords=coords))  # not c.resync: keep the chunk
        err = c.wait_error()
        self.assertEqual(Shared.pb.Error.Code.Name(err.code), "BAD_VALUE", err.message)
        h.sync(c, 5)
        self.assertEqual([k for k, _ in c.log[seen:] if k == "chunk_mesh"], [])
        self.assertFalse(c.closed)


class T5Errors(Case):
    def expect_error(self, c, name, closed):
        err = c.wait_error(10)
        self.assertEqual(Shared.pb.Error.Code.Name(err.code), name, err.message)
        c.errors.pop(0)
        if closed:
            c.wait_closed(10)
            self.assertTrue(c.closed, "the connection should be closed after %s" % name)
        else:
            h.sync(c, 99)
            self.assertFalse(c.closed)

    def test_handshake_errors(self):
        pb = Shared.pb
        cases = [
            ("NOT_HELLO", pb.Envelope(ping=pb.Ping(nonce=1)).SerializeToString()),
            ("BAD_VERSION", pb.Envelope(hello=pb.Hello(protocol_version=2, player_name="a"))
             .SerializeToString()),
            ("BAD_VALUE", pb.Envelope(hello=pb.Hello(protocol_version=1)).SerializeToString()),
            ("BAD_VALUE", pb.Envelope(hello=pb.Hello(protocol_version=1, player_name="n" * 33))
             .SerializeToString()),
            ("MALFORMED", b"\x0a\xff"),
            ("MALFORMED", b"\x0a\x05\x08\x01\x12\x01\xff"),  # Hello name: invalid UTF-8
        ]
        for name, frame in cases:
            with self.subTest(error=name, frame=frame[:12]):
                c = self.raw()
                c.send_raw(frame)
                self.expect_error(c, name, closed=True)
        c = self.raw()
        self.expect_error(c, "HANDSHAKE_TIMEOUT", closed=True)

    def test_session_errors(self):
        pb, c = Shared.pb, self.connect("errors")
        limit = c.welcome.max_frame_bytes
        c.send_raw(big_hello(pb, limit))  # exactly the limit: read, a DUPLICATE_HELLO
        self.expect_error(c, "DUPLICATE_HELLO", closed=False)
        c.send_message()
        self.expect_error(c, "UNKNOWN_MESSAGE", closed=False)
        c.send_message(pong=pb.Pong(nonce=3))
        self.expect_error(c, "UNKNOWN_MESSAGE", closed=False)
        for pos, radius in [(ORIGIN_VIEW, c.welcome.max_view_radius + 1),
                            ((math.nan, 0, 0), 1), ((0, 1e7, 0), 1)]:
            c.set_view(pos, radius)
            self.expect_error(c, "BAD_VALUE", closed=False)
        c.resync([(i, 0, 0) for i in range(c.welcome.max_resync_chunks + 1)])
        self.expect_error(c, "BAD_VALUE", closed=False)
        c.send_raw(b"\x22\x04\x08\x01\x78\x01")  # Ping with an undefined field 15
        self.expect_error(c, "UNKNOWN_MESSAGE", closed=False)
        c.sock.sendall(struct.pack("<I", limit + 1))
        self.expect_error(c, "FRAME_TOO_LARGE", closed=True)

    def test_refused_edits(self):
        c = self.connect("refused")
        h.load_view(c, ORIGIN_VIEW, 1, 1)
        meshes = len(c.received)
        w, pb = c.welcome, Shared.pb
        sent = []
        for status, kind, fields in refusals(w):
            rid = c.edit(kind, **fields)
            sent.append(rid)
            with self.subTest(expected=status, kind=kind, fields=fields):
                got = c.wait_result(rid)
                self.assertEqual(pb.EditResult.Status.Name(got.status), status, got.reason)
                self.assertEqual(list(got.changed_chunks), [])
        rid = c.edit("stamp", shape=7, center=(0, 0, 0), radius=2, solid=False)
        self.assertEqual(pb.EditResult.Status.Name(c.wait_result(rid).status), "BAD_VALUE")
        self.expect_error(c, "UNKNOWN_ENUM", closed=False)
        self.assertEqual(c.result_log, sent + [rid], "one result per edit, in order")
        self.assertEqual(len(c.received), meshes, "a refused edit changes nothing")

    def test_world_bounds_inclusive(self):
        c = self.connect("bounds")
        edge = 2.0 ** 20 - 1 - 3  # a radius-3 brush here reaches exactly 2^20 - 1
        for x, status in [(edge, "ACCEPTED"), (edge + 0.5, "OUT_OF_BOUNDS"),
                          (-(2.0 ** 20) + 3, "ACCEPTED"), (-(2.0 ** 20) + 2.5, "OUT_OF_BOUNDS")]:
            rid = c.edit("brush", center=(x, 10, 0), radius=3, strength=1)
            got = c.wait_result(rid, 20)
            with self.subTest(x=x):
                self.assertEqual(Shared.pb.EditResult.Status.Name(got.status), status, got.reason)


class T6LevelOfDetail(Case):
    """Section 4.10: a view to the horizon, decoded by this client alone."""

    def test_lod_view_is_one_surface_across_levels(self):
        c = self.connect("lod")
        w = c.welcome
        self.assertEqual((w.max_lod_level, w.max_lod_distance), (6, 2.0))
        view = c.set_view(ORIGIN_VIEW, 1, lod_level=2, lod_distance=1.0)
        ready = c.wait_view_ready(view, h.VIEW_TIMEOUT)
        self.assertEqual(ready.lod_chunks_sent, len(c.lod_chunks))
        self.assertGreater(len(c.lod_chunks), 0)
        self.assertEqual(ready.chunks_sent, len(c.chunks))
        levels = {key[0] for key in c.lod_chunks}
        self.assertEqual(levels, {1, 2})
        # World positions of every level; edges by exact position (seam vertices are
        # bit-identical to their twins): open only on the layout's outer box, the 3x3x3
        # level-2 chunks (128 voxels) around the centre's.
        uses = {}
        held = [((0,) + k, v) for k, v in c.chunks.items()]
        held += list(c.lod_chunks.items())
        for (level, x, y, z), chunk in held:
            m, s = chunk.mesh, float(1 << level)
            p = m.positions
            pos = [(32 * s * x + p[3 * i] * s, 32 * s * y + p[3 * i + 1] * s,
                    32 * s * z + p[3 * i + 2] * s) for i in range(m.vertex_count)]
            idx = m.triangles
            for t in range(0, len(idx), 3):
                a, b, d = pos[idx[t]], pos[idx[t + 1]], pos[idx[t + 2]]
                for e in ((a, b), (b, d), (d, a)):
                    key = (min(e), max(e))
                    uses[key] = uses.get(key, 0) + 1
        lo, hi = -128.0, 256.0
        inner_open = [e for e, n in uses.items() if n == 1 and not any(
            e[0][a] == e[1][a] and e[0][a] in (lo, hi) for a in range(3))]
        self.assertEqual(inner_open[:5], [], "a crack between chunks")
        # Back to level 0 only: every coarse chunk is unloaded.
        again = c.set_view(ORIGIN_VIEW, 1)
        c.wait_view_ready(again, h.VIEW_TIMEOUT)
        self.assertEqual(c.lod_chunks, {})
        self.assertGreater(len(c.lod_unloaded), 0)

    def test_lod_limits(self):
        c = self.connect("lod-limits")
        c.set_view(ORIGIN_VIEW, 1, lod_level=7)
        err = c.wait_error()
        self.assertEqual(err.code, Shared.pb.Error.BAD_VALUE)


class T7Queries(Case):
    """Section 4.13 (queries) and the material yield of section 4.4, on the shared server."""

    def status(self, answer):
        return answer.status_name

    def test_welcome_limits(self):
        w = self.connect("query-limits").welcome
        self.assertEqual((w.max_query_distance, w.max_query_samples, w.max_queries_in_flight,
                          w.queries_per_second), (512, 32768, 8, 20))

    def test_ground_raycast_and_samples_agree(self):
        c = self.connect("ground")
        g = c.ground(0, 0, 200, 400)
        self.assertEqual(self.status(g), "OK", g.reason)
        self.assertTrue(g.hit)
        x, y, z = g.point
        self.assertEqual((x, z), (0, 0))
        self.assertGreater(g.normal[1], 0, "the normal points into the air, upwards")
        self.assertAlmostEqual(math.hypot(*g.normal), 1, places=5)
        self.assertAlmostEqual(g.distance, 200 - y, places=3)
        self.assertIn(g.material, range(1, 256))
        # the same ray as a raycast (direction of any length)
        r = c.raycast((0, 200, 0), (0, -3, 0), 400)
        self.assertEqual(self.status(r), "OK", r.reason)
        self.assertEqual((r.hit, r.point, r.normal, r.material, r.distance),
                         (True, g.point, g.normal, g.material, g.distance))
        up = c.raycast((0, y + 5, 0), (0, 1, 0), 100)
        self.assertEqual((self.status(up), up.hit, up.point), ("OK", False, None))
        # the samples around it: a 4 x 5 x 6 box, x fastest
        fy = math.floor(y)
        lo, hi = (-1, fy - 2, -2), (2, fy + 2, 3)
        s = c.samples(lo, hi)
        self.assertEqual(self.status(s), "OK", s.reason)
        self.assertEqual((s.box, s.size), ((lo, hi), (4, 5, 6)))
        self.assertEqual((len(s.densities), len(s.materials)), (120, 120))
        self.assertEqual((len(s.result.densities), s.densities.typecode), (240, "h"))
        column = [s.sample(0, yy, 0) for yy in range(lo[1], hi[1] + 1)]
        self.assertEqual([d > 0 for d, _ in column], [yy <= fy for yy in range(lo[1], hi[1] + 1)],
                         "solid below the ground point, air above: %s" % column)
        for d, m in zip(s.densities, s.materials):
            if d > 0:
                self.assertNotEqual(m, 0, "a solid sample of material 0 (air)")
        # the crossing on the y-edge under (0, 0), interpolated from the two samples
        below, above = s.sample(0, fy, 0)[0], s.sample(0, fy + 1, 0)[0]
        self.assertAlmostEqual(fy + below / (below - above), y, delta=0.5 / 1024 + 1e-6)
        # single samples agree with the box: the order is x fastest, then y, then z
        for p in [(2, fy - 1, 3), (-1, fy, -2), (0, fy + 1, 1), (1, fy, 0)]:
            one = c.samples(p, p)
            self.assertEqual((one.size, one.sample(*p)), ((1, 1, 1), s.sample(*p)), p)

    def test_rays_hit_the_drawn_surface(self):
        """The hit is where the ray meets the level-0 meshes this client decoded."""
        c = self.connect("rays")
        h.load_view(c, ORIGIN_VIEW, 1, 1)
        rays = [((6.25, 40, 7.5), (0.3, -1, 0.2)), ((20.5, 30, 9.75), (-0.2, -1, 0.4)),
                ((11.3, 25, 22.6), (0.05, -1, -0.1)), ((9.5, 30, 12.5), (1, -2, 0)),
                ((8.5, -10, 8.5), (0, 1, 0))]  # from inside the rock: its surface from below
        for origin, direction in rays:
            with self.subTest(origin=origin, direction=direction):
                got = c.raycast(origin, direction, 80)
                self.assertEqual(self.status(got), "OK", got.reason)
                want = checks.first_hit(c.chunks, origin, direction, 80)
                self.assertIsNotNone(want, "the ray meets no held triangle")
                self.assertTrue(got.hit)
                distance, point, normal, material = want
                self.assertAlmostEqual(got.distance, distance, delta=1e-4)
                for a, b in zip(got.point, point):
                    self.assertAlmostEqual(a, b, delta=1e-4)
                self.assertGreater(sum(a * b for a, b in zip(got.normal, normal)), 0.99,
                                   (got.normal, normal))
                self.assertEqual(got.material, material)
                self.assertGreater(got.normal[1], 0)

    def test_explosion_yield(self):
        c = self.connect("miner")
        g = c.ground(-10.5, -9.5, 200, 400)
        self.assertTrue(g.hit, g)
        cx, cy, cz = (math.floor(v) for v in g.point)
        lo, hi = (cx - 7, cy - 7, cz - 7), (cx + 7, cy + 7, cz + 7)
        before = c.samples(lo, hi)
        self.assertEqual(self.status(before), "OK", before.reason)
        rid = c.edit("explosion", center=g.point, radius=4, power=2)
        qid = c.query("samples", min=lo, max=hi)  # sent after the edit: it sees it
        result, after = c.wait_result(rid), c.wait_query(qid)
        self.assertEqual(result.status, Shared.pb.EditResult.ACCEPTED, result.reason)
        got = volumes(result)
        self.assertTrue(any(removed > 0 for removed, _ in got.values()), got)
        materials = [v.material for v in result.volumes]
        self.assertEqual(materials, sorted(set(materials)), "one entry per material, in order")
        self.assertTrue(all(1 <= m <= 255 for m in materials))
        self.assert_yield(got, checks.yield_between(before, after))
        # a paint changes materials only: old material removed, new one added, whole
        rid = c.edit("paint", center=g.point, radius=5, material=7)
        painted = c.wait_query(c.query("samples", min=lo, max=hi))
        result = c.wait_result(rid)
        self.assertEqual(result.status, Shared.pb.EditResult.ACCEPTED, result.reason)
        self.assertEqual(painted.densities, after.densities)
        self.assertGreater(volumes(result)[7][1], 0)
        self.assert_yield(volumes(result), checks.yield_between(after, painted))

    def assert_yield(self, got, want):
        self.assertEqual(sorted(got), sorted(want))
        for m, (removed, added) in want.items():
            self.assertAlmostEqual(got[m][0], removed, delta=1e-6, msg="material %d" % m)
            self.assertAlmostEqual(got[m][1], added, delta=1e-6, msg="material %d" % m)

    def test_refused(self):
        c = self.connect("bad-queries")
        w = c.welcome
        far, side = w.max_query_distance, 32
        cases = [
            ("raycast", dict(origin=(0, 10, 0), direction=(0, 0, 0), max_distance=10)),
            ("raycast", dict(origin=(0, 10, 0), direction=(1e-7, 0, 0), max_distance=10)),
            ("raycast", dict(origin=(math.nan, 10, 0), direction=(0, -1, 0), max_distance=10)),
            ("raycast", dict(origin=(0, 10, 0), direction=(0, -1, math.inf), max_distance=10)),
            ("raycast", dict(origin=(0, 10, 0), direction=(0, -1, 0), max_distance=far * 1.01)),
            ("raycast", dict(origin=(0, 10, 0), direction=(0, -1, 0), max_distance=0)),
            ("raycast", dict(origin=(0, 5000, 0), direction=(0, -1, 0), max_distance=10)),
            ("ground", dict(x=0, z=0, from_y=math.nan, max_depth=10)),
            ("ground", dict(x=0, z=0, from_y=10, max_depth=far + 1)),
            ("ground", dict(x=0, z=0, from_y=10, max_depth=-1)),
            ("samples", dict(min=(0, 0, 0), max=(side, side - 1, side - 1))),  # 33 * 32 * 32
            ("samples", dict(min=(1, 0, 0), max=(0, 0, 0))),
            ("samples", dict(min=(0, 4095, 0), max=(0, 4096, 0))),
            (None, {}),
        ]
        for kind, fields in cases:
            with self.subTest(kind=kind, fields=fields):
                a = c.wait_query(c.query(kind, **fields))
                self.assertEqual(self.status(a), "BAD_VALUE", a)
                self.assertTrue(a.reason)
                self.assertEqual((a.hit, a.box, len(a.result.densities), len(a.result.materials)),
                                 (False, None, 0, 0))
        ok = c.samples((0, 0, 0), (side - 1, side - 1, side - 1))  # exactly the cap
        self.assertEqual((self.status(ok), len(ok.densities)), ("OK", w.max_query_samples))
        self.assertEqual(c.errors, [])

    def test_rate_limited(self):
        c = self.connect("query-rate")
        rate = c.welcome.queries_per_second
        self.assertGreater(rate, 0)
        burst, window = int(2 * rate), min(4, c.welcome.max_queries_in_flight)
        start, answers = time.monotonic(), []
        while len(answers) < 3 * burst and "RATE_LIMITED" not in [a.status_name for a in answers]:
            ids = [c.query("samples", min=(0, 0, 0), max=(0, 0, 0)) for _ in range(window)]
            answers += [c.wait_query(i) for i in ids]
        elapsed = time.monotonic() - start
        names = [a.status_name for a in answers]
        self.assertLessEqual(set(names), {"OK", "RATE_LIMITED"})
        self.assertIn("RATE_LIMITED", names)
        accepted = names.index("RATE_LIMITED")
        self.assertGreaterEqual(accepted, burst)
        self.assertLessEqual(accepted, burst + rate * elapsed + window)
        limited = answers[accepted]
        self.assertGreater(limited.retry_after_ms, 0)
        self.assertLessEqual(limited.retry_after_ms, 1000 / rate + 1)
        self.assertEqual((limited.hit, limited.box), (False, None))
        c.pause(limited.retry_after_ms / 1000 + 0.01)
        again = c.wait_query(c.query("samples", min=(0, 0, 0), max=(0, 0, 0)))
        self.assertEqual(again.status_name, "OK", "not accepted after retry_after_ms")

    def test_in_flight_cap(self):
        """More queries at once than max_queries_in_flight: each answered once, the extra
        ones TOO_MANY (how many depends on timing). Answers may overtake each other."""
        c = self.connect("query-flood")
        cap = c.welcome.max_queries_in_flight
        ids = [c.query("samples", min=(0, 0, 0), max=(15, 15, 15)) for _ in range(3 * cap)]
        answers = [c.wait_query(i) for i in ids]
        h.sync(c, 7)
        self.assertEqual(sorted(c.query_log), sorted(ids), "one answer per query")
        names = [a.status_name for a in answers]
        self.assertLessEqual(set(names), {"OK", "TOO_MANY"})
        self.assertGreaterEqual(names.count("OK"), cap)

    def test_query_before_hello(self):
        c = self.raw()
        c.query("ground", x=0, z=0, from_y=10, max_depth=20)
        err = c.wait_error()
        self.assertEqual(Shared.pb.Error.Code.Name(err.code), "NOT_HELLO", err.message)
        c.wait_closed()
        self.assertTrue(c.closed)


class T7bQueryTerrain(unittest.TestCase):
    """Section 4.13 on servers of their own: a fresh world (nothing loaded), a viewer."""

    def server(self, *args):
        server = Voxeld(os.environ["VOXELD"], seed=1,
                        extra_args=["--threads", "2", "--http-port", "0", *args])
        self.addCleanup(server.stop)
        client = Client(server.host, server.port, pb=Shared.pb, table=Shared.table)
        self.addCleanup(client.close)
        client.hello("terrain")
        return client

    def test_viewer_may_ask(self):
        c = self.server("--open-role", "viewer")
        rid = c.edit("brush", center=(0, 0, 0), radius=2, strength=1)
        self.assertEqual(c.wait_result(rid).status, Shared.pb.EditResult.FORBIDDEN)
        g = c.ground(0, 0, 200, 400)
        self.assertEqual((g.status_name, g.hit), ("OK", True), g.reason)

    def test_long_ray_through_unloaded_terrain(self):
        """A query needing more than 16 chunks loaded: SERVER_BUSY, retry_after_ms 50, and
        the retries go on from there (a voxeld of its own: fresh terrain)."""
        c = self.server()
        first = c.raycast((16.5, 200.5, 16.5), (0, 1, 0), 512, busy_retries=0)
        self.assertEqual((first.status_name, first.retry_after_ms), ("SERVER_BUSY", 50))
        done = c.raycast((16.5, 200.5, 16.5), (0, 1, 0), 512, busy_retries=20)
        self.assertEqual((done.status_name, done.hit), ("OK", False), done.reason)


def big_hello(pb, size):
    """A serialized Envelope(Hello) of exactly `size` bytes (the token pads it)."""
    for pad in range(size - 16, size):
        env = pb.Envelope(hello=pb.Hello(protocol_version=1, player_name="x", token="t" * pad))
        data = env.SerializeToString()
        if len(data) == size:
            return data
    raise AssertionError("no padding gives %d bytes" % size)


def refusals(w):
    r, s, p = w.max_edit_radius, w.max_edit_strength, ORIGIN_VIEW
    return [
        ("BAD_RADIUS", "brush", dict(center=p, radius=0, strength=1)),
        ("BAD_RADIUS", "explosion", dict(center=p, radius=r * 1.01, power=1)),
        ("BAD_RADIUS", "stamp", dict(shape="box", min=(5, 5, 5), max=(4, 9, 9), solid=False)),
        ("BAD_RADIUS", "stamp", dict(shape="box", min=(0, 0, 0), max=(2 * r + 1, 1, 1),
                                            solid=False)),
        ("BAD_RADIUS", "stamp", dict(shape="sphere", center=p, radius=-1, solid=False)),
        ("BAD_STRENGTH", "brush", dict(center=p, radius=2, strength=0)),
        ("BAD_STRENGTH", "brush", dict(center=p, radius=2, strength=s * 1.01)),
        ("BAD_STRENGTH", "explosion", dict(center=p, radius=2, power=-1)),
        ("BAD_STRENGTH", "smooth", dict(center=p, radius=2, strength=1.5)),
        ("BAD_MATERIAL", "paint", dict(center=p, radius=2, material=0)),
        ("BAD_MATERIAL", "paint", dict(center=p, radius=2, material=256)),
        ("BAD_MATERIAL", "stamp", dict(shape="sphere", center=p, radius=2, solid=True)),
        ("BAD_MATERIAL", "brush", dict(center=p, radius=2, strength=1, material=300)),
        ("OUT_OF_BOUNDS", "brush", dict(center=(0, 5000, 0), radius=2, strength=1)),
        ("OUT_OF_BOUNDS", "stamp", dict(shape="sphere", center=(0, 4094, 0), radius=1,
                                        solid=False)),  # 4094 + 1 + 2 boundary > 4095
        ("NOT_FINITE", "brush", dict(center=(math.nan, 0, 0), radius=2, strength=1)),
        ("NOT_FINITE", "paint", dict(center=p, radius=math.inf, material=3)),
        ("MISSING_EDIT", None, {}),
    ]
