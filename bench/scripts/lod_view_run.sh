#!/usr/bin/env bash
# A fresh voxeld streaming one view to one client, as docs/PERFORMANCE.md reports it
# (issue 16): today's level-0 view of radius 8 against a level-of-detail view to the
# horizon (level 0 within 4 chunks, levels 1..6: 2,048 voxels and more).
#   bench/scripts/lod_view_run.sh [RUNS]   (default 5)
# Each run starts build/bin/voxeld on a fresh world (in memory), runs `voxel-cli export`
# of the view (it returns at the view's ViewReady), then reads voxeld's CPU time from
# /proc and the bytes it sent from its metrics. Prints one line per run and the medians.
# VOXELD_ARGS: more voxeld options (e.g. "--load-budget 0" lifts the per-player load
# budget, which paces a first view of more than --load-burst work).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${VOXEL_BIN:-$root/build/bin}"
runs="${1:-5}"
out=/tmp/voxeld_lod_view; mkdir -p "$out"
at="${AT:-16,40,16}"
tick=$(getconf CLK_TCK)

one_run() {  # NAME, then voxel-cli export options
  local name="$1"; shift
  rm -f "$out/port" "$out/mport"
  "$bin/voxeld" --in-memory --port 0 --port-file "$out/port" --metrics-port 0 \
    --metrics-port-file "$out/mport" --stats-interval 0 --log-level warn ${VOXELD_ARGS:-} \
    > "$out/$name.log" 2>&1 &
  local server=$!
  for _ in $(seq 100); do [ -s "$out/mport" ] && break; sleep 0.1; done
  local t0 t1 line
  t0=$(date +%s.%N)
  line=$("$bin/voxel-cli" export --server "127.0.0.1:$(cat "$out/port")" --at "$at" \
    --out "$out/$name.obj" "$@")
  t1=$(date +%s.%N)
  # utime + stime (fields 14, 15 of /proc/PID/stat; the name field has no spaces here)
  local cpu bytes triangles
  cpu=$(awk -v t="$tick" '{printf "%.3f", ($14 + $15) / t}' "/proc/$server/stat")
  bytes=$(curl -s "127.0.0.1:$(cat "$out/mport")/metrics" | awk '/^voxeld_sent_bytes_total/ {print $2}')
  triangles=$(echo "$line" | sed -E 's/.* ([0-9]+) triangles.*/\1/')
  kill -9 "$server"; wait "$server" 2>/dev/null || true
  printf "%s view_ready_s %.3f cpu_s %s bytes %s triangles %s\n" "$name" \
    "$(echo "$t1 - $t0" | bc)" "$cpu" "$bytes" "$triangles"
}

median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR + 1) / 2)]}'; }

for i in $(seq "$runs"); do
  one_run radius8 --radius 8
  one_run lod2048 --radius 4 --lod-distance 1 --lod-level 6
done | tee "$out/runs.txt"
for name in radius8 lod2048; do
  printf "%s median: view_ready_s %s cpu_s %s bytes %s triangles %s\n" "$name" \
    "$(grep "^$name " "$out/runs.txt" | awk '{print $3}' | median)" \
    "$(grep "^$name " "$out/runs.txt" | awk '{print $5}' | median)" \
    "$(grep "^$name " "$out/runs.txt" | awk '{print $7}' | median)" \
    "$(grep "^$name " "$out/runs.txt" | awk '{print $9}' | median)"
done
