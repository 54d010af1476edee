#!/usr/bin/python3
# Edit latency by where the edit falls, with the Python reference client (clients/python):
#   /usr/bin/python3 bench/scripts/cluster_edit_kinds.py [EDITS_PER_KIND]   (as root or not)
# Starts PostgreSQL and nats-server in /tmp/edit_kinds, three voxeld nodes (a, b, c; zones
# of 16 x 16 chunks, the default lease), and an editor on node a. One brush in each of
# the 3 x 3 zones around the origin makes their holders take them (rendezvous placement);
# then, for each kind, the editor views the place and sends EDITS_PER_KIND (default 200)
# brushes one after another (radius 3, in the air above the hills, so that each one adds
# a blob and changes the mesh) after WARM_UP (5) shown apart, timing each to its EditResult and to the first delta of a
# chunk it touched at the editor itself. Kinds: inside a zone node a holds ("own"),
# inside a zone another node holds ("elsewhere"), on the border of two zones held by
# different nodes ("across 2"), at the corner of four zones held by at least two nodes
# ("across 4"). LOAD=N: N voxel-loadtest players spread over the three nodes play around
# the origin meanwhile (0.5 edits/s each). Prints p50/p95/p99 per kind and the zones used.
import os, subprocess, sys, time
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stranger_cluster import ROOT, Client, Cluster
import thread_cpu

ZONE = 16 * 32  # voxels per zone side
WARM_UP = 5  # edits per kind timed apart: the node starts following the place's zones
per_kind = int(sys.argv[1]) if len(sys.argv) > 1 else 200
cluster = Cluster("/tmp/edit_kinds", 55434, zone_chunks=16)
load_players = int(os.environ.get("LOAD", "0"))
load_args = ["--max-per-address", "0", "--max-clients", "4000"] if load_players else []
ports = {n: cluster.start(n, load_args) for n in "abc"}
editor = Client("127.0.0.1", ports["a"], decode=False)
editor.hello("kinds-editor")


def brush(x, y, z, timeout=10):
    rid = editor.edit("brush", center=(x, y, z), radius=3, strength=1, material=2)
    return editor.wait_result(rid, timeout)


# Every zone of the 3 x 3 around the origin taken by its holder.
for zx in (-1, 0, 1):
    for zz in (-1, 0, 1):
        for _ in range(100):
            if brush(zx * ZONE + 100, 200, zz * ZONE + 100).status == 0:
                break
            time.sleep(0.1)
holder = cluster.holders()
print("holders:", {k: holder[k] for k in sorted(holder)})


def centre(zone):
    return zone[0] * ZONE + ZONE // 2, zone[1] * ZONE + ZONE // 2


def pick():
    zones = sorted(holder)
    own = next((z for z in zones if holder[z] == "a"), None)
    other = next((z for z in zones if holder[z] != "a"), None)
    kinds = {}
    if own:
        kinds["own zone"] = (centre(own), [own])
    if other:
        kinds["zone held elsewhere"] = (centre(other), [other])
    for z in zones:  # a border between two zones held by different nodes
        right = (z[0] + 1, z[1])
        if right in holder and holder[right] != holder[z]:
            kinds["across 2 zones"] = (((z[0] + 1) * ZONE, z[1] * ZONE + ZONE // 2), [z, right])
            break
    for z in zones:  # a corner of four zones, at least two holders
        four = [z, (z[0] + 1, z[1]), (z[0], z[1] + 1), (z[0] + 1, z[1] + 1)]
        if all(q in holder for q in four) and len({holder[q] for q in four}) > 1:
            kinds["across 4 zones"] = (((z[0] + 1) * ZONE, (z[1] + 1) * ZONE), four)
            break
    return kinds


load = None
if load_players:
    load = subprocess.Popen(
        [ROOT + "/build/bin/voxel-loadtest", "--server", f"127.0.0.1:{ports['a']}",
         "--more-servers", f"127.0.0.1:{ports['b']},127.0.0.1:{ports['c']}",
         "--players", str(load_players), "--duration", "600", "--server-pid", "-1",
         "--spread-addresses"],
        stdout=open("/tmp/edit_kinds/loadtest.log", "w"), stderr=subprocess.STDOUT)
    cluster.procs["loadtest"] = load  # stopped with the nodes, or killed should we fail
    time.sleep(8)


def q(v, f):
    return 1000 * sorted(v)[min(len(v) - 1, int(f * len(v)))] if v else -1


cpu_from = {n: thread_cpu.sample(p.pid) for n, p in cluster.procs.items()}
t_from, steal_from = time.monotonic(), thread_cpu.steal_seconds()
for kind, ((bx, bz), zones) in pick().items():
    vid = editor.set_view((bx, 60, bz), 3)
    editor.wait_view_ready(vid, 60)
    to_result, to_delta, refused, warm = [], [], 0, []
    for i in range(per_kind + WARM_UP):
        j = i // 10
        x, y, z = bx + (j % 5) - 2, 40 + 7 * (i % 10), bz + (j // 5) % 5 - 2
        around = {(cx, cy, cz) for cx in range((x - 4) // 32, (x + 4) // 32 + 1)
                  for cy in range((y - 4) // 32, (y + 4) // 32 + 1)
                  for cz in range((z - 4) // 32, (z + 4) // 32 + 1)}
        try:  # the last edit's deltas are in
            editor.pump(lambda: False, 0.03)
        except TimeoutError:
            pass
        seen = len(editor.log)
        t0 = time.monotonic()
        rid = editor.edit("brush", center=(x, y, z), radius=3, strength=3, material=1 + i % 4)
        done = {}

        def until():
            now = time.monotonic()
            if "result" not in done and rid in editor.results:
                done["result"] = now
            if "delta" not in done and any(k == "chunk_mesh" and d[0] in around
                                           for k, d in editor.log[seen:]):
                done["delta"] = now
            failed = rid in editor.results and editor.results[rid].status != 0
            return failed or len(done) == 2

        try:
            editor.pump(until, 15)
        except TimeoutError:
            print("no answer in 15 s:", kind, (x, y, z), done, editor.results.get(rid),
                  [d for k, d in editor.log[seen:] if k == "chunk_mesh"][:5], sorted(around))
            raise
        if editor.results[rid].status != 0:
            refused += 1
            continue
        if i < WARM_UP:
            warm.append(max(done.values()) - t0)
            continue
        to_result.append(done["result"] - t0)
        to_delta.append(done["delta"] - t0)
    print("%-20s zones %s held by %s: edit -> EditResult p50 %.1f p95 %.1f p99 %.1f ms; "
          "edit -> delta p50 %.1f p95 %.1f p99 %.1f ms (n %d, refused %d); the first "
          "%d edits (not counted): %s ms"
          % (kind, zones, "".join(holder[z] for z in zones), q(to_result, .5),
             q(to_result, .95), q(to_result, .99), q(to_delta, .5), q(to_delta, .95),
             q(to_delta, .99), len(to_result), refused, WARM_UP,
             " ".join("%.0f" % (1000 * w) for w in warm)), flush=True)
elapsed = time.monotonic() - t_from
print("%s; stolen %.1f %% of the CPUs over %.0f s" % (
    thread_cpu.cpu_model(),
    100 * (thread_cpu.steal_seconds() - steal_from) / elapsed / os.cpu_count(), elapsed))
for n, p in cluster.procs.items():
    cpu = thread_cpu.shares(cpu_from[n], thread_cpu.sample(p.pid), elapsed)
    print("node %s CPU %.1f %% (%s)" % (n, sum(c[2] for c in cpu), ", ".join(
        "%s%s %.1f" % (name, "x%d" % k if k > 1 else "", pct) for name, k, pct in cpu if pct >= 0.1)))
if load:
    load.terminate()
    load.wait()
editor.close()
cluster.stop()
