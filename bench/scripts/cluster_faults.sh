#!/usr/bin/env bash
# The issue's fault rounds as docs/PERFORMANCE.md reports them:
#   bench/scripts/cluster_faults.sh [KILL_ROUNDS=20] [STOP_ROUNDS=10]
# Repeats the cluster tests that kill -9 a zone's holder while players on two other nodes
# edit its zones, and that SIGSTOP a holder past its lease (build/bin/voxel_cluster_node_tests,
# which starts its own PostgreSQL and nats-server; lease 1 s, zones of 2 x 2 chunks). Each
# round checks the zones' logs (every accepted edit exactly once, nothing unsent) and the
# nodes' worlds against the logs replayed; this prints the rounds that passed, the edits
# accepted, how soon edits were accepted again after each kill (median and worst), and in
# how many stop rounds the fence refused the stale holder's append. VOXEL_FAULT_EVICT=1:
# the nodes of the kill rounds evict their zones' changed chunks after a second and read
# them back from checkpoints taken every 0.2 s.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${VOXEL_BIN:-$root/build/bin}"
kills="${1:-20}" stops="${2:-10}"
out=/tmp/voxeld_bench/cluster_faults; mkdir -p "$out"
set +e
"$bin/voxel_cluster_node_tests" --gtest_filter='*KillNineOfAHolder*' --gtest_repeat="$kills" \
  > "$out/kills.log" 2>&1
"$bin/voxel_cluster_node_tests" --gtest_filter='*AnOwnerStoppedPastItsLease*' \
  --gtest_repeat="$stops" > "$out/stops.log" 2>&1
set -e
/usr/bin/python3 - "$out/kills.log" "$out/stops.log" <<'PY'
import re, statistics, sys
kills = open(sys.argv[1]).read()
stops = open(sys.argv[2]).read()
ok_k = len(re.findall(r"\[       OK \] .*KillNine", kills))
bad_k = len(re.findall(r"\[  FAILED  \] .*KillNine.*\(", kills))
acc = [int(m) for m in re.findall(r"accepted (\d+) edits", kills)]
ref = [int(m) for m in re.findall(r"(\d+) refused during the failover", kills)]
ms = [float(m) for m in re.findall(r"answered (-?\d+) ms after it", kills)]
print(f"kill -9 rounds: {ok_k} passed, {bad_k} failed; {sum(acc)} edits accepted, "
      f"{sum(ref)} refused during failovers; none lost or doubled in a passed round")
if ms:
    print(f"  edits accepted again after a kill: median {statistics.median(ms):.0f} ms, "
          f"worst {max(ms):.0f} ms (lease 1 s)")
evicted = [int(m) for m in re.findall(r"a survivor evicted (\d+) chunks", kills)]
if evicted:
    print(f"  chunks the survivors evicted (and read back as edited): {sum(evicted)} in "
          f"{len(evicted)} survivors' runs, {sum(1 for e in evicted if e > 0)} of them evicting")
ok_s = len(re.findall(r"\[       OK \] .*AnOwnerStopped", stops))
bad_s = len(re.findall(r"\[  FAILED  \] .*AnOwnerStopped.*\(", stops))
fenced = re.findall(r"a's appends fenced: (\d+)", stops)
forwarded = len(re.findall(r"the late edit: accepted through b", stops))
print(f"SIGSTOP rounds: {ok_s} passed, {bad_s} failed; the fence refused the stale holder in "
      f"{sum(1 for f in fenced if int(f) > 0)} of {len(fenced)}; its late edit forwarded to the "
      f"new holder in {forwarded}")
PY
