#!/usr/bin/python3
"""Decode time per chunk of the three clients on the same chunks (docs/PERFORMANCE.md).

    bench/scripts/decode_compare.py [BUILD_DIR]

The chunks are voxel_mesh_fixtures' (format 1 terrain, format 2 LOD chunks with seams, an
empty and a full one): it writes them and times the C++ client's decoding (--time); this
script then times the Python reference client's on the same zstd frames, and runs the
JavaScript client's `npm run bench` (clients/web, Node). Each figure is a median per chunk
of zstd decompression plus the decoder with every check of PROTOCOL §2.
"""
import os
import statistics
import subprocess
import sys
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
build = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "build")
tool = os.path.join(build, "bin", "voxel_mesh_fixtures")
sys.path.insert(0, os.path.join(root, "clients", "python"))
from voxelclient import decode, decompress_full, load_table  # noqa: E402
from voxelclient import proto  # noqa: E402


def median_us(fn, min_s=0.3, min_runs=30):
    for _ in range(5):
        fn()
    samples, end = [], time.perf_counter() + min_s
    while len(samples) < min_runs or time.perf_counter() < end:
        t = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t)
    return statistics.median(samples) * 1e6


with tempfile.TemporaryDirectory() as out:
    cpp = subprocess.run([tool, out, "--time"], check=True, capture_output=True, text=True).stdout
    print(cpp[cpp.index("C++ decode"):].rstrip())
    table = load_table(proto.DEFAULT_TABLE)
    import json
    names = json.load(open(os.path.join(out, "manifest.json")))["fixtures"]
    print("Python decode (zstd + every check), median per chunk:")
    for name in names:
        frame = open(os.path.join(out, name + ".zst"), "rb").read()
        us = median_us(lambda: decode(decompress_full(frame), table))
        print(f"  {name:24} {us:8.1f} us")
env = dict(os.environ, VOXEL_MESH_FIXTURES=tool)
print("JavaScript (Node) decode:")
subprocess.run(["npm", "run", "--silent", "bench"], cwd=os.path.join(root, "clients", "web"), env=env,
               check=True)
