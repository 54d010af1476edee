#!/usr/bin/env bash
# A rollback of about 10,000 edits over about 1,000 chunks on a running voxeld, and what it
# costs the players editing meanwhile (docs/PERFORMANCE.md, issue 43):
#   bench/scripts/rollback_run.sh [NAME]
# 1. voxeld with player tokens (--auth-public-key) on a fresh world, --max-memory 1G;
# 2. "griefers": voxel-loadtest, GRIEFERS [110] players at 5 edits/s for 20 s within
#    +-GRIEF_AREA [520] voxels (about 10,000 edits over about 1,000 chunks);
# 3. 200 honest players at 0.5 edits/s for 60 s (after a 10 s ramp), twice: alone (the
#    baseline) and with, 25 s into the run, `voxel-cli rollback --since T0 --until T1` of
#    every griefer edit (timed). Prints both runs' edit->delta p99, the refusals (edits
#    reaching chunks being rolled back are refused SERVER_BUSY), the rollback's report and
#    its time, and each voxeld thread's CPU share over the rollback run.
# Output files: /tmp/voxeld_bench/NAME.*
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${VOXEL_BIN:-$root/build/bin}"
name="${1:-rollback}"
out=/tmp/voxeld_bench; mkdir -p "$out"
rm -rf "$out/$name".{world,keys,port,mport}; mkdir -p "$out/$name.keys"
"$bin/voxel-cli" keygen --out "$out/$name.keys/game" > /dev/null
admin=$("$bin/voxel-cli" token --key "$out/$name.keys/game.key" --player ops --name ops --role admin --ttl 3600)
"$bin/voxeld" --world "$out/$name.world" --port 0 --port-file "$out/$name.port" \
  --metrics-port 0 --metrics-port-file "$out/$name.mport" --auth-public-key "$out/$name.keys/game.pub" \
  --max-memory 1G --max-clients 4000 --log-level info > "$out/$name.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -s "$out/$name.mport" ] && break; sleep 0.1; done
addr="127.0.0.1:$(cat "$out/$name.port")"
common=(--server "$addr" --server-pid "$server" --token-key "$out/$name.keys/game.key" --spread-addresses)
utc() { date -u +%Y-%m-%dT%H:%M:%S; }
t0=$(utc); sleep 1
"$bin/voxel-loadtest" "${common[@]}" --players "${GRIEFERS:-110}" --edit-rate 5 --duration 20 --ramp 2 \
  --spawn-area "${GRIEF_AREA:-520}" --view-radius 1 --seed 7 --json "$out/$name.grief.json" > /dev/null 2>&1 || true
sleep 1; t1=$(utc); sleep 2
echo "$name: griefers: $(/usr/bin/python3 -c "import json,sys;j=json.load(open(sys.argv[1]));print(j['edits_accepted'] if 'edits_accepted' in j else j['edit_to_result_ms']['count'], 'edits answered')" "$out/$name.grief.json"), from $t0 to $t1 UTC"
"$bin/voxel-cli" rollback --since "$t0" --until "$t1" --dry-run --server "$addr" --token "$admin" | sed "s/^/$name: /"
honest=(--players 200 --edit-rate 0.5 --duration 60 --ramp 10 --view-radius 4 --seed 1)
"$bin/voxel-loadtest" "${common[@]}" "${honest[@]}" --json "$out/$name.base.json" > /dev/null 2>&1 || true
"$root/bench/scripts/thread_cpu.py" "$server" 10 60 > "$out/$name.threads" 2>/dev/null &
sampler=$!
(
  sleep 25
  start=$(date +%s.%N)
  "$bin/voxel-cli" rollback --since "$t0" --until "$t1" --server "$addr" --token "$admin" > "$out/$name.rollback" 2>&1 || true
  end=$(date +%s.%N)
  echo "wall $(/usr/bin/python3 -c "print(round($end - $start, 2))") s" >> "$out/$name.rollback"
) &
roller=$!
"$bin/voxel-loadtest" "${common[@]}" "${honest[@]}" --json "$out/$name.with.json" > /dev/null 2>&1 || true
wait $roller; wait $sampler 2>/dev/null || true
sed "s/^/$name: rollback: /" "$out/$name.rollback"
/usr/bin/python3 - "$out/$name.base.json" "$out/$name.with.json" "$name" <<'PY'
import json, sys
for label, path in (("alone", sys.argv[1]), ("with the rollback", sys.argv[2])):
    j = json.load(open(path)); d = j['edit_to_delta_ms']
    print(f"{sys.argv[3]}: 200 players {label}: edit->delta p50 {d['p50']:.1f} p99 {d['p99']:.1f} "
          f"max {d['max']:.0f} ms (n {d['count']}), refused {j.get('refused_by_status', {})}, "
          f"errors {j['errors']}, first full view p99 {j['first_view_ms']['p99']:.0f} ms")
PY
echo "$name: voxeld threads over the rollback run (name count %cpu):"; sed 's/^/  /' "$out/$name.threads"
grep -E "rollback by|rollbacks replayed" "$out/$name.log" | sed "s/^/$name: log: /" || true
echo "$name: CPU $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores"
