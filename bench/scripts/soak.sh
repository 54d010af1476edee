#!/usr/bin/env bash
# A soak as an operator runs one before opening a server (docs/PERFORMANCE.md, issue 18):
#   bench/scripts/soak.sh NAME MINUTES [PLAYERS] [-- extra voxel-loadtest args]
# PLAYERS (default 300) play for MINUTES against a fresh voxeld with its default world store
# and a 1 GiB memory budget (bench/scripts/attack_run.sh), edit rate 0.5/s (EDIT_RATE=N), view
# radius 4 and a 10 s ramp are set there (passing them again after -- is a usage error, exit 2).
# The load tester reports per second and per minute, draws NAME.svg and exits 1 when a minute's
# edit->delta p99 is above 150 ms (MAX_P99_MS) or voxeld's RSS above MAX_RSS_MIB (when set).
# Meanwhile voxeld's metrics are scraped every 10 s into NAME.series, and at the end the
# server's own edit->publish and edit->delta-written p99 per 10 s are set beside the tester's
# worst seconds: whose part a stall was.
# Output files: /tmp/voxeld_bench/NAME.{json,svg,table,progress,log,metrics,series}.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
name="$1" minutes="$2" players=300
shift 2
if [ $# -gt 0 ] && [ "$1" != "--" ]; then players="$1"; shift; fi
[ "${1:-}" = "--" ] && shift
case "$minutes" in ''|*[!0-9]*) echo "soak.sh: MINUTES is a whole number" >&2; exit 2 ;; esac
out=/tmp/voxeld_bench; mkdir -p "$out"
rm -f "$out/$name".{series,mport,json}
limits=(--max-p99-ms "${MAX_P99_MS:-150}")
[ -n "${MAX_RSS_MIB:-}" ] && limits+=(--max-rss "$MAX_RSS_MIB")

# The scraper: waits for the metrics port, then appends "=== UNIX_SECONDS" and the
# histograms' lines every 10 s until voxeld is gone.
(
  for _ in $(seq 300); do [ -s "$out/$name.mport" ] && break; sleep 0.1; done
  port="$(cat "$out/$name.mport" 2>/dev/null || true)"
  [ -n "$port" ] || exit 0
  while body="$(curl -sf "http://127.0.0.1:$port/metrics")"; do
    { echo "=== $(date +%s)"; grep -E '^voxeld_edit_(publish|delta_written)_seconds_bucket' <<<"$body"; } \
      >> "$out/$name.series"
    sleep 10
  done
) &
scraper=$!
set +e
bash "$root/bench/scripts/attack_run.sh" "$name" "$players" "$((minutes * 60))" -- \
  --svg "$out/$name.svg" "${limits[@]}" "$@"
code=$?
set -e
wait $scraper 2>/dev/null || true
[ -s "$out/$name.json" ] && [ -s "$out/$name.series" ] || exit "$code"
grep -h '^voxel-loadtest:' "$out/$name.progress" || true
grep -A200 '^  per minute' "$out/$name.table" || true
/usr/bin/python3 - "$out/$name.series" "$out/$name.json" "$root/bench/scripts" <<'PY'
import json, sys
sys.path.insert(0, sys.argv[3])
from metrics_quantile import quantile
snaps, cur = [], None
for line in open(sys.argv[1]):
    if line.startswith('==='):
        cur = {'t': int(line.split()[1]), 'h': {}}; snaps.append(cur); continue
    name, rest = line.split('_bucket{le="', 1)
    le, count = rest.split('"} ')
    cur['h'].setdefault(name, []).append((float('inf') if le == '+Inf' else float(le), float(count)))
def p99_between(a, b, name):
    ha, hb = dict(a['h'].get(name, [])), dict(b['h'].get(name, []))
    bs = sorted((le, hb[le] - ha.get(le, 0)) for le in hb)
    return 1000 * quantile(bs, 0.99) if bs and bs[-1][1] > 0 else float('nan')
def worst(name):  # the 10 s window with the highest p99 (windows without edits left out)
    windows = [(p99_between(a, b, name), b['t'] - snaps[0]['t']) for a, b in zip(snaps, snaps[1:])]
    windows = [w for w in windows if w[0] == w[0]]
    return max(windows) if windows else (float('nan'), 0)
worst_server = worst('voxeld_edit_publish_seconds')
worst_written = worst('voxeld_edit_delta_written_seconds')
j = json.load(open(sys.argv[2]))
print(f"server, worst 10 s: edit->publish p99 {worst_server[0]:.0f} ms (ending {worst_server[1]} s after "
      f"the first scrape), edit->delta written p99 {worst_written[0]:.0f} ms (ending {worst_written[1]} s)")
print(f"tester: worst second {j['worst_second']['t']} s, p99 {j['worst_second']['p99_ms']:.0f} ms; "
      f"edit->delta p99.9 {j['edit_to_delta_ms']['p999']:.1f} ms, max {j['edit_to_delta_ms']['max']:.0f} ms; "
      f"first view p99 {j['first_view_ms']['p99']:.0f} ms")
PY
exit "$code"
