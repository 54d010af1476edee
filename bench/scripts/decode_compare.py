#!/usr/bin/python3
"""Decode time per chunk of the three clients on the same chunks (docs/PERFORMANCE.md).

    bench/scripts/decode_compare.py [BUILD_DIR]

The chunks are voxel_mesh_fixtures' (format 1 terrain, format 2 LOD chunks with seams, an
empty and a full one): it writes them and times the C++ client's decoding (--time); this
script then times the Python reference client's on the same zstd frames, runs the
JavaScript client's `npm run bench` (clients/web, Node) and its decode_bench_browser.js (the
same decoder bundled by esbuild, timed inside headless Chromium through puppeteer-core;
left out when Chromium or puppeteer-core is missing), and prints the four side by side.
Each figure is a median per chunk of zstd decompression plus the decoder with every check
of PROTOCOL §2 (Chromium's: the median of batch means, its clock being coarse).
"""
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
build = os.path.abspath(sys.argv[1]) if len(sys.argv) > 1 else os.path.join(root, "build")
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


figures = {}  # chunk -> {client: µs}


def note(client, name, us):
    figures.setdefault(name, {})[client] = us


with tempfile.TemporaryDirectory() as out:
    cpp = subprocess.run([tool, out, "--time"], check=True, capture_output=True, text=True).stdout
    print(cpp[cpp.index("C++ decode"):].rstrip())
    for m in re.finditer(r"^  (\S+)\s+([\d.]+) us$", cpp, re.M):
        note("C++", m.group(1), float(m.group(2)))
    table = load_table(proto.DEFAULT_TABLE)
    import json
    names = json.load(open(os.path.join(out, "manifest.json")))["fixtures"]
    print("Python decode (zstd + every check), median per chunk:")
    for name in names:
        frame = open(os.path.join(out, name + ".zst"), "rb").read()
        us = median_us(lambda: decode(decompress_full(frame), table))
        note("Python", name, us)
        print(f"  {name:24} {us:8.1f} us")
env = dict(os.environ, VOXEL_MESH_FIXTURES=tool)
web = os.path.join(root, "clients", "web")
# A row of decode_bench.js / decode_bench_browser.js: name, format, bytes, zst, triangles,
# zstd+decode, decode only.
ROW = re.compile(r"^(\S+)\s+\d+\s+\d+\s+\d+\s+\d+\s+([\d.]+) µs", re.M)
print("JavaScript (Node) decode:")
node = subprocess.run(["npm", "run", "--silent", "bench"], cwd=web, env=env, check=True,
                      stdout=subprocess.PIPE, text=True).stdout
print(node.rstrip())
for m in ROW.finditer(node):
    note("Node", m.group(1), float(m.group(2)))
print("JavaScript (Chromium) decode:")
browser = subprocess.run(["node", os.path.join("bench", "decode_bench_browser.js")], cwd=web, env=env,
                         capture_output=True, text=True)
if browser.returncode == 77:
    print("  skipped: " + browser.stderr.strip())
elif browser.returncode != 0:
    sys.exit("decode_bench_browser.js failed: " + browser.stderr.strip())
else:
    print(browser.stdout.rstrip())
    for m in ROW.finditer(browser.stdout):
        note("Chromium", m.group(1), float(m.group(2)))

clients = [c for c in ("C++", "Node", "Chromium", "Python") if any(c in f for f in figures.values())]
print("\nzstd + decode, median per chunk (µs):")
print(f"  {'chunk':24}" + "".join(f"{c:>10}" for c in clients))
for name, f in figures.items():
    print(f"  {name:24}" + "".join(f"{f[c]:10.1f}" if c in f else f"{'-':>10}" for c in clients))
