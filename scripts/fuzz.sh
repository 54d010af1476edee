#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/) with clang, ASan and UBSan into build-fuzz/
# and runs each for a bounded time on a scratch copy of its seed corpus (the corpus in
# the repository never changes).
#   scripts/fuzz.sh                 every target, FUZZ_SECONDS (default 35) each
#   scripts/fuzz.sh TARGET...       only these (e.g. envelope_fuzzer)
# Exit code 0 when no target crashed, leaked, hung (-timeout) or ran out of memory;
# otherwise 1, with one line per failing target naming the file that holds its input
# (build-fuzz/artifacts/). Reproduce one with build-fuzz/bin/TARGET FILE.
# Needs the Debian packages clang and libclang-rt-14-dev (libFuzzer and the sanitizers'
# runtimes), besides the project's own (scripts/setup.sh).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${VOXEL_FUZZ_BUILD_DIR:-$root/build-fuzz}"
seconds="${FUZZ_SECONDS:-35}"
all=(mesh_decode_fuzzer frame_decoder_fuzzer envelope_fuzzer volume_file_fuzzer token_fuzzer
     proxy_header_fuzzer)

targets=("${all[@]}")
if [ $# -gt 0 ]; then
  for t in "$@"; do
    if [[ ! " ${all[*]} " == *" $t "* ]]; then
      echo "usage: scripts/fuzz.sh [TARGET...]   targets: ${all[*]}" >&2
      exit 2
    fi
  done
  targets=("$@")
fi
if ! command -v clang++ >/dev/null; then
  echo "fuzz.sh: clang++ not found (apt-get install clang libclang-rt-14-dev)" >&2
  exit 2
fi

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# VOXEL_FUZZ_CONFIGURED=1: $build is already configured with clang, -DVOXEL_FUZZ=ON and
# -DVOXEL_SANITIZE=address,undefined (the test command's sanitizer build), so only build.
if [ "${VOXEL_FUZZ_CONFIGURED:-0}" != 1 ]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
    -DVOXEL_FUZZ=ON -DVOXEL_SANITIZE=address,undefined -DVOXEL_BUILD_TESTS=OFF \
    -DVOXEL_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
fi
build_targets=("${targets[@]}")
# All of them as one target: cmake --build builds several targets one after the other.
[ $# -eq 0 ] && build_targets=(fuzzers)
cmake --build "$build" -j "$(nproc)" --target "${build_targets[@]}"

# Readable stack traces: the symbolizer beside clang (llvm-14), when none is on the PATH.
if ! command -v llvm-symbolizer >/dev/null; then
  symbolizer="$(dirname "$(readlink -f "$(command -v clang++)")")/llvm-symbolizer"
  [ -x "$symbolizer" ] && export ASAN_SYMBOLIZER_PATH="$symbolizer"
fi
export ASAN_OPTIONS="detect_leaks=1:${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:${UBSAN_OPTIONS:-}"

artifacts="$build/artifacts"
logs="$build/fuzz-logs"
scratch="$(mktemp -d "${TMPDIR:-/tmp}/voxel-fuzz.XXXXXX")"
trap 'rm -rf "$scratch"' EXIT
mkdir -p "$artifacts" "$logs"

# A figure from libFuzzer's final statistics in log $1.
final_stat() { sed -n "s/^stat::$2: *//p" "$1" | tail -n 1; }

failed=()
for t in "${targets[@]}"; do
  mkdir -p "$scratch/$t"
  cp -R "$root/tests/fuzz/corpus/$t/." "$scratch/$t/"
  log="$logs/$t.log"
  rc=0
  "$build/bin/$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=1024 \
    -artifact_prefix="$artifacts/$t-" -print_final_stats=1 "$scratch/$t" >"$log" 2>&1 || rc=$?
  if [ "$rc" -eq 0 ]; then
    echo "fuzz.sh: $t ok: $(final_stat "$log" number_of_executed_units) runs," \
      "$(final_stat "$log" average_exec_per_sec) execs/s, $(find "$scratch/$t" -type f | wc -l)" \
      "corpus inputs, peak RSS $(final_stat "$log" peak_rss_mb) MB"
  else
    input="$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -n 1)"
    summary="$(grep -m 1 -E '^SUMMARY: |^==[0-9]+== ERROR: libFuzzer' "$log" || true)"
    # The sanitizer's or libFuzzer's report (its first lines: what and where), else the end.
    first="$(grep -n -m 1 -E 'ERROR: |runtime error: ' "$log" | cut -d: -f1 || true)"
    if [ -n "$first" ]; then
      sed -n "${first},$((first + 30))p" "$log"
    else
      tail -n 30 "$log"
    fi | sed "s/^/  $t | /" >&2
    failed+=("fuzz.sh: FAILED $t (exit $rc): input in ${input:-<none written>}; ${summary:-see log}; log $log")
  fi
done

if [ ${#failed[@]} -gt 0 ]; then
  printf '%s\n' "${failed[@]}" >&2
  exit 1
fi
