#!/usr/bin/python3
"""Python decode time and bytes per chunk, full copies and deltas, over one view.

    VOXELD=build/bin/voxeld /usr/bin/python3 clients/python/bench_decode.py [--radius 3]

Starts its own voxeld (seed 1 by default; or --server HOST:PORT for a running one), loads
a view around the origin, then makes edits on the surface of the view's chunks so that
deltas arrive. Every payload is then decoded again offline (zstd, then format 1 with every
check) and timed; the report gives median and p90.
"""
import argparse
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from voxelclient import Client, decode, decompress_delta, decompress_full  # noqa: E402
from voxelclient.server import Voxeld  # noqa: E402


class RecordingClient(Client):
    """Keeps (base_version, payload, base encoding) of every ChunkMesh before applying it."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.payloads = []

    def on_chunk_mesh(self, msg):
        held = self.chunks.get((msg.coord.x, msg.coord.y, msg.coord.z))
        base = held.encoding if held and msg.base_version else None
        self.payloads.append((msg.base_version, bytes(msg.payload), base))
        super().on_chunk_mesh(msg)


def surface_points(client):
    """The first vertex of every held chunk with triangles, in world voxels."""
    points = []
    for (cx, cy, cz), held in sorted(client.chunks.items()):
        if held.mesh.vertex_count:
            x, y, z = held.mesh.positions[0:3]
            points.append((x + 32 * cx, y + 32 * cy, z + 32 * cz))
    return points


BRUSHES = [dict(strength=1.5), dict(strength=1.5, remove=True), dict(strength=1, material=6)]


def run_session(host, port, radius, edits):
    c = RecordingClient(host, port)
    c.hello("bench")
    c.set_view((16.0, 16.0, 16.0), radius, 1)
    c.wait_view_ready(1, 60)
    for i, p in enumerate(surface_points(c)[:edits]):
        kind = BRUSHES[i % len(BRUSHES)]
        rid = c.edit("brush", center=p, radius=4, **kind)
        c.wait_result(rid, 20)
    c.ping(7)
    c.wait_pong(7, 30)
    if c.failures:
        raise SystemExit("decode failures: %s" % c.failures[:3])
    c.close()
    return c


def time_one(table, base_version, payload, base, repeat):
    best_z = best_d = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        enc = decompress_full(payload) if base_version == 0 else decompress_delta(payload, base)
        t1 = time.perf_counter()
        decode(enc, table)
        t2 = time.perf_counter()
        best_z = t1 - t0 if best_z is None else min(best_z, t1 - t0)
        best_d = t2 - t1 if best_d is None else min(best_d, t2 - t1)
    return len(payload), len(enc), best_z * 1e3, best_d * 1e3


def quantiles(values):
    values = sorted(values)
    return statistics.median(values), values[min(len(values) - 1, int(0.9 * len(values)))]


COLUMNS = ["payload B", "encoding B", "zstd ms", "decode ms", "total ms"]


def report(rows, label):
    if not rows:
        print("%-6s %5d" % (label, 0))
        return
    cols = [list(c) for c in zip(*rows)]
    cols.append([z + d for z, d in zip(cols[2], cols[3])])
    cells = []
    for name, col in zip(COLUMNS, cols):
        fmt = "%.0f / %.0f" if name.endswith("B") else "%.2f / %.2f"
        cells.append("%-14s" % (fmt % quantiles(col)))
    print(("%-6s %5d   %s" % (label, len(rows), "".join(cells))).rstrip())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--server", help="HOST:PORT of a running voxeld (default: start one)")
    ap.add_argument("--voxeld", default=os.environ.get("VOXELD", "build/bin/voxeld"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--radius", type=int, default=3)
    ap.add_argument("--edits", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    server = None
    if args.server:
        host, port = args.server.rsplit(":", 1)
    else:
        server = Voxeld(args.voxeld, seed=args.seed)
        host, port = server.host, server.port
    try:
        c = run_session(host, int(port), args.radius, args.edits)
    finally:
        if server:
            server.stop()
    rows = [(b, time_one(c.table, b, p, base, args.repeat)) for b, p, base in c.payloads]
    print("seed %d, radius %d view at the origin, %d edits; Python %s" % (
        args.seed, args.radius, args.edits, sys.version.split()[0]))
    print("%-6s %5s   %s(median / p90)" % ("", "n", "".join("%-14s" % n for n in COLUMNS)))
    report([r for b, r in rows if b == 0], "full")
    report([r for b, r in rows if b != 0], "delta")


if __name__ == "__main__":
    main()
