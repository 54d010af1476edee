#!/bin/sh
# scripts/check_deps.py must refuse what docs/ARCHITECTURE.md forbids: a client header that
# includes a server header, a file in a folder no row owns, and a page that names a path
# that does not exist; and pass the real tree. The cases run on a copy of the tracked files,
# where every path the real page names exists, so each fails for its own reason alone.
set -eu
root="$1"
py=/usr/bin/python3
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
git -C "$root" ls-files -z |
  tar -C "$root" -cf - --null -T - --ignore-failed-read 2>/dev/null | tar -C "$tmp" -xf -
git -C "$tmp" init -q && git -C "$tmp" add -A
missing_lines() { echo "$1" | grep -c 'which does not exist' || true; }

# A client header that includes a server header.
printf '#include "server/world/chunk.hpp"\n' > "$tmp/client/voxel_client.hpp"
if out="$("$py" "$root/scripts/check_deps.py" "$tmp")"; then
  echo "FAIL: a client header including a server header was allowed"; exit 1
fi
echo "$out" | grep -q 'client/voxel_client.hpp:1: voxel_client may not include "server/world/chunk.hpp"' \
  || { echo "FAIL: unexpected report: $out"; exit 1; }
[ "$(missing_lines "$out")" = 0 ] || { echo "FAIL: the copy lacks paths the page names: $out"; exit 1; }
cp "$root/client/voxel_client.hpp" "$tmp/client/voxel_client.hpp"

# A file in a folder no row owns.
mkdir -p "$tmp/stray"
printf 'int x;\n' > "$tmp/stray/stray.cpp"
git -C "$tmp" add -A
if out="$("$py" "$root/scripts/check_deps.py" "$tmp")"; then
  echo "FAIL: a file no row owns was allowed"; exit 1
fi
echo "$out" | grep -q 'stray/stray.cpp: its folder is in no row' || { echo "FAIL: $out"; exit 1; }
git -C "$tmp" rm -q -r --cached stray && rm -r "$tmp/stray"

# A page naming paths that do not exist: a file, a folder, a bare file name, a glob that
# matches nothing, and a file in a figure. Paths that exist in other spellings, and words
# that are not repository paths, pass.
cat >> "$tmp/docs/ARCHITECTURE.md" <<'EOF'

Missing: `server/world/no_such_file.hpp`, `server/nowhere/`, `no_such_header.hpp`,
`server/net/no_such_*.cpp`. Present: `server/net/server.cpp:42`, `server/net/`,
`sh tests/scripts/check_deps_test.sh ROOT`, `server/net/send_scheduler.*`, `chunk.hpp`,
`world_pipeline_*.cpp`, `voxel.pb.h`. Not paths: `world/no_such.hpp`, `/metrics`,
`build/bin/voxeld`, `WorldPipeline::run()`, `HOST:PORT`.

```
vox-pipeline  server/pipeline/no_such_step.cpp   run → server/pipeline/world_pipeline.cpp
```
EOF
if out="$("$py" "$root/scripts/check_deps.py" "$tmp")"; then
  echo "FAIL: a page naming missing paths was allowed"; exit 1
fi
for p in server/world/no_such_file.hpp server/nowhere/ no_such_header.hpp \
         'server/net/no_such_*.cpp' server/pipeline/no_such_step.cpp; do
  echo "$out" | grep -qxF "docs/ARCHITECTURE.md names $p, which does not exist" \
    || { echo "FAIL: $p not reported: $out"; exit 1; }
done
[ "$(missing_lines "$out")" = 5 ] || { echo "FAIL: unexpected report: $out"; exit 1; }
echo "$out" | grep -q 'check_deps: 5 path(s) named in docs/ARCHITECTURE.md do not exist' \
  || { echo "FAIL: no summary: $out"; exit 1; }

"$py" "$root/scripts/check_deps.py" "$root"
echo "check_deps: refuses all three, passes the tree"
