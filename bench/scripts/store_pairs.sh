#!/usr/bin/env bash
# What the world store adds to the players' latency, as docs/PERFORMANCE.md reports it:
#   bench/scripts/store_pairs.sh PAIRS [TAG] [PLAYERS] [DURATION]
# Runs PAIRS pairs of bench/scripts/attack_run.sh, alternating a run with the default SQLite
# store (TAG_stN) and one with --in-memory (TAG_memN), then prints each pair's edit->result
# and edit->delta p50/p99 and the server's own edit->publish p99 (its metrics), with the
# store's excess over the in-memory run beside it, and the medians. The server's figure moves
# far less between runs than the players' (which include the load tester's own waits). One
# run's p99 moves by +-25 % on a shared 2-core machine: read the medians of several pairs,
# not one pair. STORE_ARGS / STORE_PRELOAD go to the store runs only (as VOXELD_ARGS /
# VOXELD_PRELOAD). Defaults: TAG pairs, 500 players, 60 s; ~3 minutes a pair. A run that
# fails (attack_run.sh's exit code) stops the series.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
pairs="${1:?usage: store_pairs.sh PAIRS [TAG] [PLAYERS] [DURATION]}"
tag="${2:-pairs}" players="${3:-500}" duration="${4:-60}"
run="$root/bench/scripts/attack_run.sh"
for i in $(seq 1 "$pairs"); do
  VOXELD_ARGS="${STORE_ARGS:-}" VOXELD_PRELOAD="${STORE_PRELOAD:-}" \
    "$run" "${tag}_st$i" "$players" "$duration" | sed -n 1p
  VOXELD_ARGS=--in-memory "$run" "${tag}_mem$i" "$players" "$duration" | sed -n 1p
done
PYTHONPATH="$root/bench/scripts" /usr/bin/python3 - "$tag" "$pairs" <<'PY'
import json, statistics, sys
from metrics_quantile import buckets, quantile
tag, pairs = sys.argv[1], int(sys.argv[2])
def figures(name):
    j = json.load(open(f"/tmp/voxeld_bench/{name}.json"))
    r, d = j["edit_to_result_ms"], j["edit_to_delta_ms"]
    publish = 1000 * quantile(buckets(f"/tmp/voxeld_bench/{name}.metrics",
                                      "voxeld_edit_publish_seconds"), 0.99)
    return r["p50"], r["p99"], d["p50"], d["p99"], publish
excess = {"result p99": [], "delta p99": [], "server publish p99": []}
print(f"{'pair':>4}  {'store result p50/p99':>21}  {'memory result p50/p99':>22}  "
      f"{'delta p99 store/memory':>22}  {'server publish p99':>18}  excess (result, delta, publish)")
for i in range(1, pairs + 1):
    s, m = figures(f"{tag}_st{i}"), figures(f"{tag}_mem{i}")
    ex = [s[k] / m[k] - 1 for k in (1, 3, 4)]
    for key, e in zip(excess, ex):
        excess[key].append(e)
    print(f"{i:>4}  {s[0]:>9.1f} / {s[1]:>7.1f}  {m[0]:>10.1f} / {m[1]:>7.1f}  "
          f"{s[3]:>12.1f} / {m[3]:>7.1f}  {s[4]:>8.1f} / {m[4]:>7.1f}  " +
          ", ".join(f"{100 * e:+.0f} %" for e in ex))
st = [figures(f"{tag}_st{i}") for i in range(1, pairs + 1)]
mem = [figures(f"{tag}_mem{i}") for i in range(1, pairs + 1)]
med = lambda rows, k: statistics.median(r[k] for r in rows)
print(f"median edit->result p99: store {med(st, 1):.1f} ms, in memory {med(mem, 1):.1f} ms; "
      f"edit->delta p99: store {med(st, 3):.1f}, in memory {med(mem, 3):.1f}; "
      f"server edit->publish p99: store {med(st, 4):.1f}, in memory {med(mem, 4):.1f}")
print("median excess of the pairs: " +
      ", ".join(f"{k} {100 * statistics.median(v):+.0f} %" for k, v in excess.items()))
PY
