#!/usr/bin/env bash
# Restart of a durable world as an operator sees it: voxeld started on a copy of WORLD
# (made by build/bin/bench_make_world), the time until it listens (open the store, replay
# the log since the last checkpoint), then the time a first player's radius-4 view at the
# origin takes to arrive whole (voxel-cli export). Several cold runs, median; run it on an
# empty world directory too ("fresh") for the ratio.
#   bench/scripts/restart_run.sh WORLD|fresh [runs=5]
set -euo pipefail
src=$1
runs=${2:-5}
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=$root/build/bin
tmp=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$tmp"' EXIT
now() { date +%s.%N; }
ms() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%d", (b - a) * 1000 }'; }
listen=() view=()
for ((r = 1; r <= runs; r++)); do
  rm -rf "$tmp/w"
  if [[ $src == fresh ]]; then mkdir "$tmp/w"; else cp -r "$src" "$tmp/w"; fi
  sync
  rm -f "$tmp/port"
  t0=$(now)
  "$bin/voxeld" --port 0 --port-file "$tmp/port" --world "$tmp/w" --stats-interval 0 \
    > "$tmp/log" 2>&1 &
  pid=$!
  while [[ ! -s $tmp/port ]]; do
    kill -0 $pid 2>/dev/null || { cat "$tmp/log"; exit 1; }
    sleep 0.01
  done
  t1=$(now)
  "$bin/voxel-cli" export --server "127.0.0.1:$(cat "$tmp/port")" --at 0,0,0 --radius 4 \
    --out "$tmp/view.obj" > /dev/null
  t2=$(now)
  kill -TERM $pid && wait $pid || true
  listen+=("$(ms "$t0" "$t1")") view+=("$(ms "$t1" "$t2")")
  echo "run $r: listening after ${listen[-1]} ms, first view in ${view[-1]} ms;" \
    "$(grep -o '[0-9]* stored chunks, [0-9]* logged edits replayed in [0-9]* ms' "$tmp/log")"
done
median() { printf '%s\n' "$@" | sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
echo "median: listening after $(median "${listen[@]}") ms, first view in $(median "${view[@]}") ms"
