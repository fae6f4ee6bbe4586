#!/usr/bin/env bash
# scripts/tsan.sh [TEST_BINARY...] [-- GTEST_ARGS...]: builds the library and the unit tests of the
# threaded modules with ThreadSanitizer (clang-14, build-tsan/, -DSTIPPLE_TSAN=ON) and runs them.
# Default binaries: core (thread pool, progress), tiler (worker pools, the pipelined writer),
# engine (frame pipeline) and tiles3d (tileset streaming: fetch workers, lazy expansion, HTTP).
# Tests that run the command line run the plain build's build/stipple (STIPPLE_TEST_BINARY), so
# build/ must exist (scripts/setup.sh). Exits non-zero on a race report or a failed test.
#   scripts/tsan.sh                                    all four
#   scripts/tsan.sh stipple_tiler_unit_tests -- --gtest_filter='Tiler*'
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
bins=()
# Memory.ResidentBytesFollowTouchedMemory measures the process's RSS, which under ThreadSanitizer
# is its runtime's too (shadow memory it maps and releases on its own): not a race, left out.
gtest=(--gtest_filter=-Memory.ResidentBytesFollowTouchedMemory)
while [[ $# -gt 0 ]]; do
  if [[ $1 == -- ]]; then shift; gtest=("$@"); break; fi
  bins+=("$1"); shift
done
[[ ${#bins[@]} -gt 0 ]] || bins=(stipple_core_unit_tests stipple_tiler_unit_tests
  stipple_engine_unit_tests stipple_tiles3d_unit_tests)
binary=${STIPPLE_TEST_BINARY:-$root/build/stipple}
[[ -x "$binary" ]] || { echo "tsan.sh: $binary not found (run scripts/setup.sh first)" >&2; exit 2; }
cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
  -DSTIPPLE_TSAN=ON -DSTIPPLE_TEST_BINARY="$binary" >/dev/null
cmake --build build-tsan --target "${bins[@]}" -- -j"$(nproc)" |
  { grep -vE "^\[[0-9]+/[0-9]+\] (Building|Linking|Generating|Embedding|Re-checking)|^ninja: no work" || true; }
# Races inside uninstrumented third-party libraries (the Vulkan driver, WebGPU, libcurl's
# resolver) are not ours: tests/tsan.supp.
export TSAN_OPTIONS="halt_on_error=0:second_deadlock_stack=1:suppressions=$root/tests/tsan.supp:${TSAN_OPTIONS:-}"
status=0
for b in "${bins[@]}"; do
  log="build-tsan/$b.log"
  echo "== $b"
  set +e
  "build-tsan/tests/$b" --gtest_brief=1 "${gtest[@]}" >"$log" 2>&1
  rc=$?
  set -e
  races=$(grep -c '^WARNING: ThreadSanitizer' "$log" || true)
  grep -E '^\[  (PASSED|FAILED) |tests? ran' "$log" | tail -n 3 || true
  echo "   exit $rc, ThreadSanitizer reports: $races (log: $log)"
  [[ $rc -eq 0 && $races -eq 0 ]] || status=1
done
exit $status
