#!/usr/bin/env bash
# Fails when a tracked C++ file is not formatted as .clang-format says (Debian's
# clang-format 14); `clang-format -i FILE` fixes one.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
report="$(mktemp)"
trap 'rm -f "$report"' EXIT
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h' '*.inl' '*.cc')
if ! clang-format --dry-run -Werror "${files[@]}" 2>"$report"; then
  grep -E '^[^ ].*error:' "$report" | cut -d: -f1 | sort -u | sed 's/^/not formatted: /'
  echo "check_format: run clang-format -i on the files above"
  exit 1
fi
echo "check_format: ${#files[@]} files formatted"
