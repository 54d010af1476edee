#!/usr/bin/python3
# Failover as a stranger meets it, with the Python reference client (clients/python,
# written from docs/PROTOCOL.md) and the default lease (3 s):
#   /usr/bin/python3 bench/scripts/cluster_failover_client.py   (as root: PostgreSQL runs as postgres)
# Starts PostgreSQL and nats-server in /tmp/stranger_cluster, two voxeld nodes (a, b) with
# --cluster, a viewer on b and an editor on a; 10 explosions; kill -9 of the node holding
# zone (0, 0); the editor reconnects to the other node and makes 10 more (retrying
# STORAGE_UNAVAILABLE); prints the statuses, when the first edit was accepted after the
# kill, and what a fresh viewer on the survivor gets. Before the kill, remote visibility:
# VISIBILITY_EDITS (40) brushes on the holder, timed to their result and to a delta at a
# viewer on the other node.
import os, sys, threading, time
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stranger_cluster import Client, Cluster
D = "/tmp/stranger_cluster"
cluster = Cluster(D, 55433)
pa, pb = cluster.start("a"), cluster.start("b")
viewer = Client("127.0.0.1", pb, decode=False); viewer.hello("viewer")
vid = viewer.set_view((40, 10, 40), 3); viewer.wait_view_ready(vid, 60)
editor = Client("127.0.0.1", pa, decode=False); editor.hello("editor")
first_ok = []
def edits(n, x0):
    st=[]
    for i in range(n):
        for attempt in range(60):
            rid = editor.edit("explosion", center=(x0 + 3 * i, 2, 40), radius=3, power=1)
            r = editor.wait_result(rid, 10)
            if r.status != 12: break
            time.sleep(0.1)
        st.append(r.status)
        if r.status == 0 and not first_ok: first_ok.append(time.time())
    return st
t=time.time(); s1=edits(10, 20); print("10 edits via a:", s1, "%.1f s" % (time.time()-t))
time.sleep(1.0)
try: viewer.pump(lambda: False, 1.0)
except TimeoutError: pass
print("viewer on b holds", len(viewer.chunks), "chunks")
holder = cluster.holders()[(0, 0)]
other, oport = ("b", pb) if holder == "a" else ("a", pa)
print("holder of zone (0, 0):", holder)

# Remote visibility: brushes sent by an editor on the zone's holder; in turn, the time to
# its EditResult (the commit), and to the first delta of a chunk around the brush at a
# viewer on the other node (which follows the zone: NATS, then its own meshing).
def visibility(n):
    hport = pa if holder == "a" else pb
    editor = Client("127.0.0.1", hport, decode=False); editor.hello("vis-editor")
    viewer = Client("127.0.0.1", oport, decode=False); viewer.hello("vis-viewer")
    viewer.wait_view_ready(viewer.set_view((40, 10, 40), 3), 60)
    to_result, to_delta = [], []
    for i in range(n):
        x, z = 20 + (i % 10) * 2.5, 44 + (i // 10) * 3.0
        around = {(cx, cy, cz) for cx in range(int(x // 32) - 1, int(x // 32) + 2)
                  for cy in range(-1, 2) for cz in range(int(z // 32) - 1, int(z // 32) + 2)}
        try: viewer.pump(lambda: False, 0.3)  # the last edit's deltas are in
        except TimeoutError: pass
        seen = len(viewer.log)
        got = []
        def watch():  # the viewer's side, on its own thread
            viewer.pump(lambda: any(k == "chunk_mesh" and d[0] in around and d[2] != 0
                                    for k, d in viewer.log[seen:]), 10)
            got.append(time.monotonic())
        watcher = threading.Thread(target=watch); watcher.start()
        t0 = time.monotonic()
        rid = editor.edit("brush", center=(x, 2, z), radius=3, strength=1, material=1 + i % 4)
        if editor.wait_result(rid, 10).status == 0: to_result.append(time.monotonic() - t0)
        watcher.join()
        if got: to_delta.append(got[0] - t0)
    q = lambda v, f: 1000 * sorted(v)[min(len(v) - 1, int(f * len(v)))] if v else -1
    print("remote visibility (editor on %s, the zone's holder; viewer on %s): edit -> EditResult "
          "p50 %.1f p95 %.1f ms (n %d); edit -> first delta on %s p50 %.1f p95 %.1f ms (n %d)"
          % (holder, other, q(to_result, .5), q(to_result, .95), len(to_result),
             other, q(to_delta, .5), q(to_delta, .95), len(to_delta)))
    editor.close(); viewer.close()
visibility(int(os.environ.get("VISIBILITY_EDITS", "40")))
cluster.kill(holder); t=time.time()
editor = Client("127.0.0.1", oport, decode=False); editor.hello("editor2")
first_ok.clear()
s2=edits(10, 22)
print("10 edits via %s after kill -9 of %s:" % (other, holder), s2,
      "the first accepted %.2f s after the kill" % (first_ok[0] - t if first_ok else -1))
v2 = Client("127.0.0.1", oport, decode=False); v2.hello("viewer2")
vid = v2.set_view((40, 10, 40), 3); v2.wait_view_ready(vid, 60)
print("a fresh viewer on %s holds %d chunks" % (other, len(v2.chunks)))
print(other + "'s log tail:"); print("".join(open(D+"/"+other+".log").readlines()[-5:]))
cluster.stop()
