#!/bin/sh
# scripts/check_deps.py must refuse what the rules table forbids: a client header that
# includes a server header, and a file in a folder no row owns; and pass the real tree.
set -eu
root="$1"
py=/usr/bin/python3
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/docs" "$tmp/client" "$tmp/server/world" "$tmp/stray"
cp "$root/docs/ARCHITECTURE.md" "$tmp/docs/"
printf '#pragma once\n' > "$tmp/server/world/chunk.hpp"
printf '#include "server/world/chunk.hpp"\n' > "$tmp/client/voxel_client.hpp"
git -C "$tmp" init -q && git -C "$tmp" add -A
if out="$("$py" "$root/scripts/check_deps.py" "$tmp")"; then
  echo "FAIL: a client header including a server header was allowed"; exit 1
fi
echo "$out" | grep -q 'client/voxel_client.hpp:1: voxel_client may not include "server/world/chunk.hpp"' \
  || { echo "FAIL: unexpected report: $out"; exit 1; }
printf '#include "client/voxel_client.hpp"\n' > "$tmp/client/voxel_client.hpp"
printf 'int x;\n' > "$tmp/stray/stray.cpp"
git -C "$tmp" add -A
if out="$("$py" "$root/scripts/check_deps.py" "$tmp")"; then
  echo "FAIL: a file no row owns was allowed"; exit 1
fi
echo "$out" | grep -q 'stray/stray.cpp: its folder is in no row' || { echo "FAIL: $out"; exit 1; }
"$py" "$root/scripts/check_deps.py" "$root"
echo "check_deps: refuses both, passes the tree"
