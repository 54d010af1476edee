#!/usr/bin/env bash
# Does memory go back to the system after eviction? 100 players stay (radius 6, almost no
# edits) while four view flooders load far terrain for 20 s and leave; 30 s later (past
# --evict-after 5) voxeld's RSS is compared with its accounted bytes (from /metrics), with
# the players still there.
#   bench/scripts/memory_return.sh NAME [extra voxeld args]   (VOXELD_PRELOAD=lib.so to preload an allocator)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${VOXEL_BIN:-$root/build/bin}"
name="$1"; shift
out=/tmp/voxeld_bench; mkdir -p "$out"; rm -f "$out/$name".{port,mport}
rm -rf "$out/$name.world"
LD_PRELOAD="${VOXELD_PRELOAD:-}" "$bin/voxeld" --world "$out/$name.world" --port 0 --port-file "$out/$name.port" --metrics-port 0 \
  --metrics-port-file "$out/$name.mport" --max-memory 1G --evict-after 5 --max-per-address 0 \
  --max-handshaking-per-address 0 --max-clients 1000 --stats-interval 0 "$@" > "$out/$name.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -s "$out/$name.mport" ] && break; sleep 0.1; done
scrape() { curl -s "http://127.0.0.1:$(cat "$out/$name.mport")/metrics"; }
server_at="127.0.0.1:$(cat "$out/$name.port")"
"$bin/voxel-loadtest" --server "$server_at" --players 100 --duration 60 --ramp 5 --view-radius 6 \
  --edit-rate 0.01 > /dev/null 2>&1 &
players=$!
sleep 8
"$bin/voxel-loadtest" --server "$server_at" --players 1 --duration 20 --ramp 0 --view-radius 1 \
  --edit-rate 0.01 --attack flood:4 > /dev/null 2>&1 || true
peak=$(grep VmHWM /proc/$server/status | awk '{print $2}')
sleep 30  # the flood's chunks idle past --evict-after and are evicted
scrape | PEAK_KIB="$peak" NAME="$name" /usr/bin/python3 -c "
import os, sys
m = {}
for line in sys.stdin:
    if line.startswith('#') or ' ' not in line: continue
    k, v = line.rsplit(' ', 1); m[k] = float(v)
acc = sum(v for k, v in m.items() if k.startswith('voxeld_memory_accounted_bytes'))
rss = m['voxeld_resident_memory_bytes']
peak = int(os.environ['PEAK_KIB']) / 1024
print(os.environ['NAME'] + f': peak RSS {peak:.0f} MiB; after eviction: {m[\"voxeld_chunks_loaded\"]:.0f} chunks, '
      f'accounted {acc/2**20:.1f} MiB, RSS {rss/2**20:.1f} MiB, RSS/accounted {rss/acc:.2f}, '
      f'evicted {m[\"voxeld_chunks_evicted_total\"]:.0f}')
"
kill $players 2>/dev/null || true
