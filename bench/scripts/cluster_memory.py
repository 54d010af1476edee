#!/usr/bin/python3
# A cluster node's memory under players who edit all over a wide world (docs/CLUSTER.md,
# "Evicting a zone's chunks"): two nodes with a small --max-memory and short eviction and
# follow timeouts, voxel-loadtest players spread over both, walking and editing within
# +-SPAWN voxels. Every few seconds each node's resident changed chunks, chunks stored,
# chunks evicted, accounted bytes and RSS are printed; at the end the CPU model, the steal,
# and the edit -> delta latency from the tester.
#
#   /usr/bin/python3 bench/scripts/cluster_memory.py [SECONDS]
#   env: PLAYERS (40), SPAWN (1500), MAX_MEMORY (512M), ZONE_CHUNKS (16), DIR, PG_PORT,
#        SETTLE (8 s before the players come: the zones placed), GATEWAY=a (every player on node a: node b only holds zones, follows none),
#        VOXELD (a voxeld binary to compare, e.g. an older build's), FOLLOW_IDLE (20 s;
#        empty: not set, for a build without follow_idle_s)
import json, os, re, subprocess, sys, time, urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stranger_cluster import ROOT, Cluster  # noqa: E402
import thread_cpu  # noqa: E402

SECONDS = int(sys.argv[1]) if len(sys.argv) > 1 else 90
PLAYERS = int(os.environ.get("PLAYERS", "40"))
SPAWN = int(os.environ.get("SPAWN", "1500"))
MAX_MEMORY = os.environ.get("MAX_MEMORY", "512M")
METRICS = {"a": 19391, "b": 19392}
WATCH = ["voxeld_chunks_modified", "voxeld_chunks_stored", "voxeld_chunks_evicted_total",
         "voxeld_chunks_loaded", "voxeld_memory_accounted_bytes",
         "voxeld_cluster_checkpoints_installed_total"]


def metrics(node):
    text = urllib.request.urlopen(f"http://127.0.0.1:{METRICS[node]}/metrics", timeout=5).read()
    out = {}
    for line in text.decode().splitlines():
        m = re.match(r"^([a-z_]+)(?:\{[^}]*\})? ([-0-9.e+]+)$", line)
        if m and m.group(1) in WATCH:
            out[m.group(1)] = out.get(m.group(1), 0.0) + float(m.group(2))
    return out


def rss_mib(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def main():
    d = os.environ.get("DIR", "/tmp/cluster_memory")
    cluster = Cluster(d, int(os.environ.get("PG_PORT", "55481")),
                      zone_chunks=int(os.environ.get("ZONE_CHUNKS", "16")))
    ports = {}
    idle = os.environ.get("FOLLOW_IDLE", "20")
    idle = f"follow_idle_s = {idle}\n" if idle else ""
    for node in ("a", "b"):
        ports[node] = cluster.start(node, ["--max-memory", MAX_MEMORY, "--evict-after", "10",
                                           "--checkpoint-interval", "2", "--metrics-port",
                                           str(METRICS[node])], more=idle)
    pids = {n: cluster.procs[n].pid for n in ports}
    time.sleep(float(os.environ.get("SETTLE", "8")))  # the zones placed over both nodes
    print(f"cpu: {thread_cpu.cpu_model()}; players {PLAYERS} within +-{SPAWN} voxels, "
          f"--max-memory {MAX_MEMORY}, zones of {cluster.zone_chunks} chunks")
    steal0 = thread_cpu.steal_seconds()
    more = [] if os.environ.get("GATEWAY") == "a" else ["--more-servers",
                                                         f"127.0.0.1:{ports['b']}"]
    cpu_from = {n: thread_cpu.sample(pids[n]) for n in pids}
    tester = subprocess.Popen(
        [ROOT + "/build/bin/voxel-loadtest", "--server", f"127.0.0.1:{ports['a']}", *more,
         "--players", str(PLAYERS),
         "--duration", str(SECONDS), "--spawn-area", str(SPAWN), "--edit-rate", "1",
         "--spread-addresses",
         "--json", f"{d}/load.json"], stdout=open(f"{d}/load.log", "w"),
        stderr=subprocess.STDOUT)
    start = time.time()
    print("  s node modified stored evicted resident accounted_MiB RSS_MiB installed")
    while tester.poll() is None:
        time.sleep(10)
        for node in ports:
            try:
                m = metrics(node)
            except OSError as e:
                print(node, "metrics:", e)
                continue
            print(f"{time.time() - start:4.0f} {node:>4} {m.get(WATCH[0], 0):8.0f} "
                  f"{m.get(WATCH[1], 0):6.0f} {m.get(WATCH[2], 0):7.0f} {m.get(WATCH[3], 0):8.0f} "
                  f"{m.get(WATCH[4], 0) / 2**20:13.0f} {rss_mib(pids[node]):7.0f} "
                  f"{m.get(WATCH[5], 0):9.0f}")
    elapsed = time.time() - start
    steal = thread_cpu.steal_seconds() - steal0
    print(f"steal: {100 * steal / elapsed / os.cpu_count():.1f} % of the CPUs over {elapsed:.0f} s")
    for n in pids:
        cpu = thread_cpu.shares(cpu_from[n], thread_cpu.sample(pids[n]), elapsed)
        print("node %s CPU %.1f %% (%s)" % (n, sum(c[2] for c in cpu), ", ".join(
            "%s%s %.1f" % (name, "x%d" % k if k > 1 else "", pct)
            for name, k, pct in cpu if pct >= 0.5)))
    try:
        r = json.load(open(f"{d}/load.json"))
        s = r.get("summary", r)
        print("tester: players connected %d of %d, edits %d, refused %s, errors %s" % (
            r["players_connected"], r["players"], r["edits_sent"], r["refused_by_status"],
            r["errors_by_cause"]))
        for k in ("edit_to_result_ms", "edit_to_delta_ms", "first_view_ms"):
            print("  %s: p50 %.1f p99 %.1f (%d)" % (k, r[k]["p50"], r[k]["p99"], r[k]["count"]))
    except (OSError, ValueError) as e:
        print("tester json:", e)
    cluster.stop()


if __name__ == "__main__":
    main()
