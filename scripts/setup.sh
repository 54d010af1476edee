#!/usr/bin/env bash
# One setup step for voxeld on Debian 12: install the packages the project needs (only
# those missing), then configure and build with CMake (through ccache when present).
#   scripts/setup.sh            install + build
#   scripts/setup.sh run        ... then start the demo (see README)
#   scripts/setup.sh test       ... then run the whole test suite with ctest
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${VOXEL_BUILD_DIR:-$root/build}"
mode="${1:-build}"

packages=(
  build-essential cmake pkg-config ccache
  libboost-dev libboost-program-options-dev
  libtbb-dev libprotobuf-dev protobuf-compiler libzstd-dev libspdlog-dev
  libgtest-dev libgmock-dev libbenchmark-dev libsqlite3-dev libmeshoptimizer-dev
  prometheus-cpp-dev libjemalloc-dev libsodium-dev zlib1g-dev
  python3-protobuf python3-zstandard
  clang-format clang libclang-rt-14-dev
  libpqxx-dev postgresql
  nats-server libnats-dev
)

# The web client and viewer (clients/web): node and npm, Debian's unless the machine has
# them already; the test step also drives Debian's chromium, headless, and runs the
# viewer behind haproxy with a certificate openssl makes, and checks deploy/voxeld.service
# with systemd's systemd-analyze (nothing is started).
command -v node >/dev/null || packages+=(nodejs)
command -v npm >/dev/null || packages+=(npm)
[ "$mode" = test ] && packages+=(chromium haproxy openssl systemd)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=()
  [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The web client's packages, exactly as its lock says (again only when the lock changed).
web="$root/clients/web"
if ! cmp -s "$web/package-lock.json" "$web/node_modules/.voxel-lock"; then
  echo "setup: npm ci in clients/web"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
  cp "$web/package-lock.json" "$web/node_modules/.voxel-lock"
fi

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE="${VOXEL_BUILD_TYPE:-Release}" "${launcher[@]}" ${VOXEL_CMAKE_ARGS:-} >/dev/null
jobs="$(nproc)"
cmake --build "$build" -j "$jobs"

case "$mode" in
  build) ;;
  run)
    shift || true
    echo "setup: starting voxeld on 127.0.0.1:7777 with the default world (seed 1); Ctrl-C stops it"
    exec "$build/bin/voxeld" --port 7777 --seed 1 "$@"
    ;;
  test)
    # The written rules first (seconds): the folders' dependency table and the format.
    /usr/bin/python3 "$root/scripts/check_deps.py" "$root"
    bash "$root/scripts/check_format.sh"
    (cd "$build" && ctest --output-on-failure -j "$jobs" --timeout 900)
    # The same tests under AddressSanitizer+UndefinedBehaviorSanitizer and under
    # ThreadSanitizer (set VOXEL_SKIP_SANITIZERS=1 to skip them locally).
    if [ "${VOXEL_SKIP_SANITIZERS:-0}" != 1 ]; then
      for san in address,undefined thread; do
        sbuild="$build-${san//,/-}"
        echo "setup: tests under -fsanitize=$san ($sbuild)"
        # The ASan+UBSan build is clang's and also builds the libFuzzer targets (one build
        # for both; scripts/fuzz.sh runs them below).
        extra=()
        [ "$san" = address,undefined ] && extra=(-DCMAKE_CXX_COMPILER=clang++ -DVOXEL_FUZZ=ON)
        cmake -S "$root" -B "$sbuild" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DVOXEL_SANITIZE="$san" \
          -DVOXEL_BUILD_BENCH=OFF "${extra[@]}" "${launcher[@]}" >/dev/null
        cmake --build "$sbuild" -j "$jobs"
        (cd "$sbuild" && \
          ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 LSAN_OPTIONS="suppressions=$root/tests/lsan.supp" \
          UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
          TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$root/tests/tsan.supp" \
          ctest --output-on-failure -j "$jobs" --timeout 1800)
        if [ "$san" = address,undefined ]; then
          # Each libFuzzer target for a bounded time on its seed corpus (about 2.5 minutes).
          VOXEL_FUZZ_BUILD_DIR="$sbuild" VOXEL_FUZZ_CONFIGURED=1 bash "$root/scripts/fuzz.sh"
        fi
      done
    fi
    ;;
  *) echo "usage: scripts/setup.sh [build|run|test]" >&2; exit 2 ;;
esac
