#!/usr/bin/env bash
# The latency issue's five scenarios in one go (about 12 minutes on 2 cores), each against
# a fresh voxeld started by bench/scripts/attack_run.sh (load tester on the same machine,
# --spread-addresses, 0.5 edits/s per player):
#   1. 200 players on LOD views to 2,048 voxels (--lod-level 6), 90 s
#   2. 500 players, default store, 60 s
#   3. 1,000 players, default store, 60 s
#   4. 200 players with the attack mix flood:4,heavy:4,squat:4,slow:4,empty:4 against
#      200 without it, 60 s each
#   5. a login storm: 100 players playing, then 500 more joining within 5 s
# Prints the table of docs/PERFORMANCE.md's "Current figures" (markdown) with the host,
# date and commit, and writes it and a JSON to /tmp/voxeld_bench/load_table.{md,json}.
#   bench/scripts/load_table.sh [--update-doc]
# --update-doc replaces the "Current figures" section at the top of docs/PERFORMANCE.md.
# ONLY=lod200,p500,... runs some of them (names: lod200 p500 p1000 attack storm).
# SLOW=N makes a slower host of this one: `stress-ng --cpu 2 --cpu-load N` runs beside the
# whole table (N: percent of each core it takes), and the table is its own section,
# "Current figures, slowed host".
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${VOXEL_BIN:-$root/build/bin}"
out=/tmp/voxeld_bench; mkdir -p "$out"
run="$root/bench/scripts/attack_run.sh"
only="${ONLY:-lod200,p500,p1000,attack,storm}"
wants() { [[ ",$only," == *",$1,"* ]]; }
steal_before=$(awk '/^cpu /{print $9}' /proc/stat)
if [ -n "${SLOW:-}" ]; then
  command -v stress-ng > /dev/null || { echo "SLOW needs stress-ng (apt-get install stress-ng)" >&2; exit 2; }
  stress-ng --cpu 2 --cpu-load "$SLOW" --timeout 3600s > /dev/null 2>&1 &
  stress=$!
  trap 'kill $stress 2>/dev/null || true' EXIT
fi

if wants lod200; then
  VOXELD_ARGS="--io-threads 2" "$run" lt_lod200 200 90 -- --lod-level 6 || true
fi
wants p500 && { "$run" lt_p500 500 60 || true; }
wants p1000 && { "$run" lt_p1000 1000 60 || true; }
if wants attack; then
  "$run" lt_base200 200 60 || true
  "$run" lt_atk200 200 60 flood:4,heavy:4,squat:4,slow:4,empty:4 || true
fi

if wants storm; then
  # 100 players play for 60 s; at 20 s, 500 more join within 5 s and play for 30 s.
  name=lt_storm
  rm -rf "$out/$name.world" "$out/$name".{port,mport}
  "$bin/voxeld" --world "$out/$name.world" --port 0 --port-file "$out/$name.port" \
    --metrics-port 0 --metrics-port-file "$out/$name.mport" --max-memory 1G \
    --max-clients 4000 --stats-interval 10 > "$out/$name.log" 2>&1 &
  server=$!
  trap 'kill $server ${stress:-} 2>/dev/null || true' EXIT
  for _ in $(seq 100); do [ -s "$out/$name.mport" ] && break; sleep 0.1; done
  common=(--server "127.0.0.1:$(cat "$out/$name.port")" --edit-rate 0.5 --view-radius 4
          --server-pid "$server" --spread-addresses)
  "$root/bench/scripts/thread_cpu.py" "$server" 20 30 > "$out/$name.threads" 2>/dev/null &
  sampler=$!
  "$bin/voxel-loadtest" "${common[@]}" --players 100 --ramp 5 --duration 55 --seed 1 \
    --json "$out/$name.steady.json" > "$out/$name.steady.table" 2> "$out/$name.steady.progress" &
  steady=$!
  sleep 20
  "$bin/voxel-loadtest" "${common[@]}" --players 500 --ramp 5 --duration 30 --seed 2 \
    --json "$out/$name.json" > "$out/$name.table" 2> "$out/$name.progress" || true
  wait $steady || true
  wait $sampler || true
  kill -TERM $server; wait $server || true
  trap - EXIT
fi
[ -n "${SLOW:-}" ] && { kill "$stress" 2>/dev/null || true; wait "$stress" 2>/dev/null || true; }

steal_after=$(awk '/^cpu /{print $9}' /proc/stat)
/usr/bin/python3 "$root/bench/scripts/load_table.py" "$out" "$root" \
  "$(( (steal_after - steal_before) ))" "$@"
