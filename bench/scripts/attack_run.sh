#!/usr/bin/env bash
# One load-test run against a fresh voxeld, as docs/PERFORMANCE.md reports it:
#   bench/scripts/attack_run.sh NAME PLAYERS DURATION [ATTACK_MIX] [-- extra voxel-loadtest args]
# Starts build/bin/voxeld on a free port (--max-memory 1G, metrics on, the per-address caps
# and budgets at their defaults), runs voxel-loadtest --spread-addresses (every player and
# hostile client from its own loopback address) with --json, then prints the honest players' edit->delta p50/p99, errors,
# disconnects, refusals, voxeld's max RSS, the first full view p99 and the server's own
# edit->publish and edit->delta-written p99 (bench/scripts/metrics_quantile.py), and each
# voxeld thread's CPU share while the players play (bench/scripts/thread_cpu.py).
# EDIT_RATE=N: edits per second per player (default 0.5).
# With the default world store it also prints commit p50/p99, how long the pipeline stood waiting for commits,
# edits per commit and the world's size; VOXELD_ARGS=--in-memory runs without a store.
# TRANSPORT=ws: voxeld also serves HTTP on a free port (--http-port auto) and the players
# connect there over WebSocket (voxel-loadtest --websocket); hostile clients stay on TCP.
# Output files: /tmp/voxeld_bench/NAME.{json,log,metrics}.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${VOXEL_BIN:-$root/build/bin}"
name="$1" players="$2" duration="$3" attack="${4:-}"
[ "$attack" = "--" ] && attack=""  # no attack mix, extra args follow
shift 3; [ $# -gt 0 ] && shift
[ "${1:-}" = "--" ] && shift
out=/tmp/voxeld_bench; mkdir -p "$out"
rm -f "$out/$name".{port,mport,hport}
http_args=()
[ "${TRANSPORT:-tcp}" = ws ] && http_args=(--http-port auto --http-port-file "$out/$name.hport")
rm -rf "$out/$name.world"
LD_PRELOAD="${VOXELD_PRELOAD:-}" "$bin/voxeld" --world "$out/$name.world" --port 0 --port-file "$out/$name.port" --metrics-port 0 --metrics-port-file "$out/$name.mport" \
  --max-memory 1G --max-clients 4000 --stats-interval 10 \
  "${http_args[@]}" ${VOXELD_ARGS:-} > "$out/$name.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
# Each voxeld thread's CPU share while the players play (after the 10 s ramp).
"$root/bench/scripts/thread_cpu.py" "$server" 10 $((duration > 10 ? duration - 5 : duration)) \
  > "$out/$name.threads" 2>/dev/null &
sampler=$!
for _ in $(seq 100); do [ -s "$out/$name.mport" ] && break; sleep 0.1; done
args=(--server "127.0.0.1:$(cat "$out/$name.port")" --players "$players" --duration "$duration" --ramp 10
      --edit-rate "${EDIT_RATE:-0.5}" --view-radius 4 --server-pid "$server" --json "$out/$name.json" --spread-addresses)
[ -n "$attack" ] && args+=(--attack "$attack")
if [ "${TRANSPORT:-tcp}" = ws ]; then
  for _ in $(seq 100); do [ -s "$out/$name.hport" ] && break; sleep 0.1; done
  args+=(--websocket "127.0.0.1:$(cat "$out/$name.hport")")
fi
set +e
"$bin/voxel-loadtest" "${args[@]}" "$@" > "$out/$name.table" 2> "$out/$name.progress"
code=$?
set -e
curl -s "http://127.0.0.1:$(cat "$out/$name.mport")/metrics" > "$out/$name.metrics" || true
wait $sampler 2>/dev/null || true
kill -TERM $server; wait $server || true
if [ ! -s "$out/$name.json" ]; then  # the tester refused its arguments or could not run
  echo "$name: exit $code, no results: $(tail -1 "$out/$name.progress")"
  exit "$code"
fi
/usr/bin/python3 - "$out/$name.json" "$out/$name.metrics" "$name" "$code" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
m = {}
for line in open(sys.argv[2]):
    if line.startswith('#') or ' ' not in line: continue
    k, v = line.rsplit(' ', 1); m[k] = float(v)
d, r = j['edit_to_delta_ms'], j['edit_to_result_ms']
rss = j.get('server_rss', {})
pub_n = m.get('voxeld_edit_publish_seconds_count', 0)
pub_mean = 1000 * m.get('voxeld_edit_publish_seconds_sum', 0) / pub_n if pub_n else 0
print(f"{sys.argv[3]}: exit {sys.argv[4]}, players {j['players_connected']}/{j['players']}, "
      f"edit->result p50 {r['p50']:.1f} p99 {r['p99']:.1f} ms, edit->delta p50 {d['p50']:.1f} p99 {d['p99']:.1f} "
      f"max {d['max']:.0f} ms (n {d['count']}), errors {j['errors']}, disconnects {j['disconnects']}, "
      f"refused {j.get('refused_by_status', {})}, max RSS {rss.get('max_kib', 0)/1024:.0f} MiB, "
      f"server edit->publish mean {pub_mean:.1f} ms")
PY
q="$root/bench/scripts/metrics_quantile.py"
echo "$name: first full view p99 $(/usr/bin/python3 -c "import json,sys;print(round(json.load(open(sys.argv[1]))['first_view_ms']['p99']))" "$out/$name.json") ms," \
  "server edit->publish p99 $(/usr/bin/python3 "$q" "$out/$name.metrics" voxeld_edit_publish_seconds) ms," \
  "edit->delta written p99 $(/usr/bin/python3 "$q" "$out/$name.metrics" voxeld_edit_delta_written_seconds) ms"
if grep -q '^voxeld_store_commits_total [1-9]' "$out/$name.metrics"; then
  commits=$(awk '/^voxeld_store_commits_total /{print $2}' "$out/$name.metrics")
  edits=$(awk '/^voxeld_store_committed_edits_total /{print $2}' "$out/$name.metrics")
  echo "$name: store commit p50/p99 $(/usr/bin/python3 "$q" "$out/$name.metrics" voxeld_store_commit_seconds 0.5 0.99) ms," \
    "pipeline waited p99 $(/usr/bin/python3 "$q" "$out/$name.metrics" voxeld_store_commit_wait_seconds) ms," \
    "$(/usr/bin/python3 -c "print(f'{$edits/$commits:.1f}')") edits per commit ($commits commits)," \
    "world $(du -sb "$out/$name.world" | cut -f1) bytes"
fi
echo "$name: threads (name count %CPU): $(awk '{printf "%s%s %s %s", sep, $1, $2, $3; sep=", "}' "$out/$name.threads")"
exit "$code"
