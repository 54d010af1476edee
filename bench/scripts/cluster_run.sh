#!/usr/bin/env bash
# A load-test run against one node of a cluster world (docs/CLUSTER.md), as
# docs/PERFORMANCE.md reports it:
#   bench/scripts/cluster_run.sh NAME PLAYERS DURATION NODES [-- extra voxel-loadtest args]
# Starts a PostgreSQL (initdb in a temporary directory, on a Unix socket) and a nats-server
# (a user and password from its configuration file) on 127.0.0.1, writes one --cluster file
# per node (nodes a, b, c, ...; zones of ZONE_CHUNKS chunks, default 16), starts nodes
# b.. in the background, then runs bench/scripts/attack_run.sh NAME PLAYERS DURATION with
# node a (the players connect to a; edits in zones another node holds are forwarded to
# it). Prints attack_run.sh's table, then each background node's CPU share over the run.
# SPREAD=1: the players are spread over all the nodes (voxel-loadtest --more-servers).
# Then the cluster's traffic over the run: NATS messages and bytes (the server's /varz),
# PostgreSQL WAL bytes, the zone log's records, and the meshes each node published.
# KILL_AT=S (with 3 nodes or more): node b is killed (kill -9) S seconds into the run; pass
# `-- --reconnect` so that its players connect to the next node. Prints, from the
# survivors' logs, each of b's zones' time from the kill to taken and to writable again;
# the load tester reports the players' time to reconnect and to a complete view.
# TAKEOVER=1: then, node a stopped (its last checkpoint written, its zones released), a
# fresh node takes the zones around the origin twice, prompted by a voxel-cli brush in each: first
# installing their checkpoints, then (checkpoint_seq set back to 0 in the database) applying
# their whole logs; prints each zone's time from taken to writable, from the fresh node's log.
# Everything is stopped at the end; files stay in /tmp/voxeld_bench/NAME.cluster.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${VOXEL_BIN:-$root/build/bin}"
name="$1" players="$2" duration="$3" nodes="$4"
shift 4
[ "${1:-}" = "--" ] && shift  # the rest is voxel-loadtest's
dir=/tmp/voxeld_bench/$name.cluster
rm -rf "$dir"; mkdir -p "$dir"; chmod 755 "$dir"
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  if [ -d "$dir/pg" ]; then as_pg "$pgbin/pg_ctl -D $dir/pg -m fast -w stop" > /dev/null 2>&1 || true; fi
}
trap cleanup EXIT

# PostgreSQL, as the postgres user when run as root.
pgbin=$(ls -d /usr/lib/postgresql/*/bin | sort -V | tail -1)
as_pg() { if [ "$(id -u)" = 0 ]; then runuser -u postgres -- sh -c "$1"; else sh -c "$1"; fi; }
mkdir -p "$dir/pg" && [ "$(id -u)" = 0 ] && chown postgres "$dir/pg" "$dir"
as_pg "$pgbin/initdb -D $dir/pg -U postgres -A trust > $dir/initdb.log 2>&1"
as_pg "$pgbin/pg_ctl -D $dir/pg -l $dir/pg.log -w -o \"-k $dir -p 55432 -c listen_addresses=''\" start" > /dev/null
as_pg "$pgbin/psql -q -h $dir -p 55432 -U postgres -c 'CREATE DATABASE vox'"
database="postgresql:///vox?host=$dir&port=55432&user=postgres"

# nats-server with a password, on a free port written to its ports file.
cat > "$dir/nats.conf" <<EOF
host: 127.0.0.1
port: -1
http_port: ${NATS_MONITOR_PORT:-58222}
authorization { user: "voxnode", password: "bench-only-secret" }
EOF
mkdir -p "$dir/ports"
nats-server -c "$dir/nats.conf" --ports_file_dir "$dir/ports" > "$dir/nats.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do ls "$dir/ports"/* > /dev/null 2>&1 && break; sleep 0.1; done
nats_url=$(grep -o 'nats://[^"]*' "$dir/ports"/* | head -1)

letters=(a b c d e f g h)
for i in $(seq 0 $((nodes - 1))); do
  n=${letters[$i]}
  cat > "$dir/$n.conf" <<EOF
database = $database
nats = $nats_url
nats_user = voxnode
nats_password = bench-only-secret
world = bench
node = $n
zone_chunks = ${ZONE_CHUNKS:-16}
EOF
  chmod 600 "$dir/$n.conf"
done
others=()
for i in $(seq 1 $((nodes - 1))); do
  n=${letters[$i]}
  "$bin/voxeld" --cluster "$dir/$n.conf" --port 0 --port-file "$dir/$n.port" --max-memory 1G \
    --max-clients 4000 --stats-interval 10 --max-per-address 0 --metrics-port 0 \
    --metrics-port-file "$dir/$n.mport" > "$dir/$n.log" 2>&1 &
  pids+=($!)
  others+=("$n:$!")
done
for o in "${others[@]}"; do
  pid=${o#*:}
  "$root/bench/scripts/thread_cpu.py" "$pid" 10 $((duration > 10 ? duration - 5 : duration)) \
    > "$dir/${o%%:*}.threads" 2>/dev/null &
done
more=()
if [ "${SPREAD:-0}" = 1 ] && [ "$nodes" -gt 1 ]; then
  list=""
  for i in $(seq 1 $((nodes - 1))); do
    n=${letters[$i]}
    for _ in $(seq 100); do [ -s "$dir/$n.port" ] && break; sleep 0.1; done
    list="$list${list:+,}127.0.0.1:$(cat "$dir/$n.port")"
  done
  more=(--more-servers "$list")
fi
varz() { curl -s "http://127.0.0.1:${NATS_MONITOR_PORT:-58222}/varz"; }
sql() { as_pg "$pgbin/psql -qtA -h $dir -p 55432 -U postgres -d vox -c \"$1\""; }
varz > "$dir/varz.before"
wal_before=$(sql "SELECT pg_current_wal_lsn()")
if [ -n "${KILL_AT:-}" ] && [ "$nodes" -ge 3 ]; then
  victim=${others[0]#*:}
  (sleep "$KILL_AT"; date -u '+%Y-%m-%d %H:%M:%S.%3N' > "$dir/killed_at"; kill -9 "$victim") &
fi
set +e
VOXELD_ARGS="--cluster $dir/a.conf ${VOXELD_ARGS:-}" "$root/bench/scripts/attack_run.sh" \
  "$name" "$players" "$duration" -- "${more[@]}" "$@"
code=$?
set -e
varz > "$dir/varz.after"
wal_bytes=$(sql "SELECT pg_wal_lsn_diff(pg_current_wal_lsn(), '$wal_before')")
records=$(sql "SELECT count(*) FROM zone_log")
split=$(sql "SELECT count(DISTINCT edit_id) FROM zone_log WHERE edit_id <> 0")
meshes=""
for i in $(seq 1 $((nodes - 1))); do
  n=${letters[$i]}
  m=$(curl -s "http://127.0.0.1:$(cat "$dir/$n.mport")/metrics" | awk '/^voxeld_meshes_published_total /{print $2}' || true)
  meshes="$meshes node $n ${m:-?},"
done
/usr/bin/python3 - "$dir/varz.before" "$dir/varz.after" "$records" "$wal_bytes" "$split" <<'PY'
import json, sys
b, a = (json.load(open(p)) for p in sys.argv[1:3])
records, wal, split = int(sys.argv[3] or 0), float(sys.argv[4] or 0), int(sys.argv[5] or 0)
d = {k: a[k] - b[k] for k in ("in_msgs", "out_msgs", "in_bytes", "out_bytes")}
per = lambda v: f"{v / records:.0f}" if records else "?"
print(f"cluster traffic: {records} zone log records ({split} edit ids: forwarded or split edits); "
      f"NATS in {d['in_msgs']} msgs / {d['in_bytes']} B, out {d['out_msgs']} msgs / {d['out_bytes']} B "
      f"= {per(d['in_bytes'] + d['out_bytes'])} B per record; PostgreSQL WAL {wal:.0f} B = {per(wal)} B per record")
PY
echo "meshes published (node a: attack_run's metrics):${meshes%,}"
for o in "${others[@]}"; do
  echo "node ${o%%:*}:"
  cat "$dir/${o%%:*}.threads" 2>/dev/null || true
done
grep -h "fenced\|took zone\|lost zone" "$dir"/*.log /tmp/voxeld_bench/"$name".log 2>/dev/null | wc -l |
  xargs echo "zone events (took, lost, fenced) in the nodes' logs:"
if [ -s "$dir/killed_at" ]; then
  /usr/bin/python3 - "$(cat "$dir/killed_at")" "$dir" /tmp/voxeld_bench/"$name".log <<'PY'
import glob, re, sys
from datetime import datetime
at = lambda l: datetime.strptime(l[1:24], "%Y-%m-%d %H:%M:%S.%f")
killed = datetime.strptime(sys.argv[1], "%Y-%m-%d %H:%M:%S.%f")
logs = [p for p in glob.glob(sys.argv[2] + "/*.log") if not re.search(r"/(b|take_\w+|nats|pg|initdb)\.log$", p)]
logs.append(sys.argv[3])
took, writable = {}, {}
for path in logs:
    for l in open(path, errors="replace"):
        if not l.startswith("[2") or at(l) < killed: continue
        if m := re.search(r"took zone \((-?\d+), (-?\d+)\)", l): took.setdefault(m.groups(), at(l))
        if m := re.search(r"zone \((-?\d+), (-?\d+)\) is writable here", l): writable.setdefault(m.groups(), at(l))
ms = lambda t: f"{(t - killed).total_seconds() * 1000:.0f}"
print("after the kill of node b:", "; ".join(
    f"zone ({z[0]}, {z[1]}) taken {ms(t)} ms, writable {ms(writable[z]) if z in writable else '?'} ms"
    for z, t in sorted(took.items())) or "no zone taken")
PY
fi
if [ "${TAKEOVER:-0}" = 1 ]; then
  for mode in checkpoint log; do
    [ "$mode" = log ] && sql "UPDATE zones SET checkpoint_seq = 0" > /dev/null
    n=take_$mode
    sed "s/^node = .*/node = $n/" "$dir/a.conf" > "$dir/$n.conf"; chmod 600 "$dir/$n.conf"
    "$bin/voxeld" --cluster "$dir/$n.conf" --port 0 --port-file "$dir/$n.port" --max-memory 1G \
      > "$dir/$n.log" 2>&1 &
    takeover=$!
    for _ in $(seq 100); do [ -s "$dir/$n.port" ] && break; sleep 0.1; done
    # An edit in each zone around the origin: forwarded, nobody holds the zone, so the node
    # (ranking first, the only one alive) takes it.
    for at in 8,0,8 -8,0,8 8,0,-8 -8,0,-8; do
      "$bin/voxel-cli" brush --server "127.0.0.1:$(cat "$dir/$n.port")" --at $at --radius 2 \
        > /dev/null 2>&1 || true
    done
    sleep 3
    kill -TERM $takeover; wait $takeover || true
    /usr/bin/python3 - "$dir/$n.log" "$mode" <<'PY'
import re, sys
from datetime import datetime
at = lambda l: datetime.strptime(l[1:24], "%Y-%m-%d %H:%M:%S.%f")
took, out = {}, []
for l in open(sys.argv[1]):
    if m := re.search(r"took zone \((-?\d+), (-?\d+)\)", l): took[m.groups()] = at(l)
    if m := re.search(r"zone \((-?\d+), (-?\d+)\) is writable here \(its log applied through record (\d+)", l):
        if m.groups()[:2] in took:
            out.append(f"({m[1]}, {m[2]}) {(at(l) - took[m.groups()[:2]]).total_seconds() * 1000:.0f} ms through record {m[3]}")
print(f"take over by {sys.argv[2]}:", "; ".join(out) or "no zone taken")
PY
  done
fi
exit "$code"
