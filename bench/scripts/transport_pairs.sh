#!/usr/bin/env bash
# voxeld's CPU per player over TCP against WebSocket (docs/PERFORMANCE.md, the browser):
#   bench/scripts/transport_pairs.sh PAIRS [PLAYERS] [DURATION]
# Runs bench/scripts/attack_run.sh alternately with TRANSPORT=tcp and ws (PAIRS pairs of
# PLAYERS players, default 200, for DURATION s, default 70; attack_run.sh samples each
# voxeld thread's CPU share with thread_cpu.py), and prints one line per run:
# voxeld CPU (mean of the load tester's per-second samples in that window), per player,
# the tester's CPU, steal, edit->result and edit->delta p99, bytes/s per player, threads.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
pairs="$1" players="${2:-200}" duration="${3:-70}"
out=/tmp/voxeld_bench
echo "CPU: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores; load before: $(cut -d' ' -f1-3 /proc/loadavg)"
for i in $(seq "$pairs"); do
  for t in tcp ws; do
    name="transport_${t}_$i"
    TRANSPORT=$t "$root/bench/scripts/attack_run.sh" "$name" "$players" "$duration" > "$out/$name.summary" 2>&1 || true
    /usr/bin/python3 - "$out/$name.json" "$out/$name.threads" "$name" "$players" "$duration" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
name, players, duration = sys.argv[3], int(sys.argv[4]), int(sys.argv[5])
window = [s for s in j["per_second"] if 10 <= s["t"] < duration + 5 and s.get("cpu_percent") is not None]
mean = lambda k: sum(s[k] or 0 for s in window) / max(1, len(window))
cpu = mean("cpu_percent")
threads = ", ".join(" ".join(l.split()[::2]) + "%" for l in open(sys.argv[2]).read().split("\n") if l.strip())
print(f"{name}: voxeld {cpu:.1f} % ({cpu / players:.3f} % per player), tester {mean('tester_cpu_percent'):.1f} %, "
      f"steal {mean('steal_percent'):.1f} %, edit->result p99 {j['edit_to_result_ms']['p99']:.1f} ms, "
      f"edit->delta p99 {j['edit_to_delta_ms']['p99']:.1f} ms, {j['bytes_per_player_per_s']:.0f} B/s per player; "
      f"threads: {threads}")
PY
  done
done
