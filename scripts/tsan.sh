#!/usr/bin/env bash
# scripts/tsan.sh [TEST_BINARY...] [-- GTEST_ARGS...]: builds the library and the tests of the
# threaded modules with ThreadSanitizer (clang-14, build-tsan/, -DSTIPPLE_TSAN=ON) and runs them.
# Default binaries: core (thread pool, progress), tiler (worker pools, the pipelined writer),
# engine (frame pipeline) and tiles3d (tileset streaming: fetch workers, lazy expansion, HTTP),
# then the GPU tests on lavapipe: renderer (render graph, staging through the thread pool),
# pointcloud (the engine's pipelined render thread drawing with a real device) and tiles3d (the
# streamer's GPU side: uploads, page reuse, picking, pipelined and not). A process loads one
# WebGPU implementation, so each *_gpu_tests binary runs once per backend of
# STIPPLE_TSAN_BACKENDS (default "wgpu dawn") with --gtest_filter='*/BACKEND'; GTEST_ARGS, when
# given, replace that filter (then choose one backend in them).
# Tests that run the command line run the plain build's build/stipple (STIPPLE_TEST_BINARY), so
# build/ must exist (scripts/setup.sh). Exits non-zero on a race report or a failed test.
#   scripts/tsan.sh                                    all seven
#   scripts/tsan.sh stipple_tiler_unit_tests -- --gtest_filter='Tiler*'
#   STIPPLE_TSAN_BACKENDS=wgpu scripts/tsan.sh stipple_pointcloud_gpu_tests
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
bins=()
# Memory.ResidentBytesFollowTouchedMemory measures the process's RSS, which under ThreadSanitizer
# is its runtime's too (shadow memory it maps and releases on its own): not a race, left out.
gtest=(--gtest_filter=-Memory.ResidentBytesFollowTouchedMemory)
user_gtest=0
while [[ $# -gt 0 ]]; do
  if [[ $1 == -- ]]; then shift; gtest=("$@"); user_gtest=1; break; fi
  bins+=("$1"); shift
done
[[ ${#bins[@]} -gt 0 ]] || bins=(stipple_core_unit_tests stipple_tiler_unit_tests
  stipple_engine_unit_tests stipple_tiles3d_unit_tests stipple_renderer_gpu_tests
  stipple_pointcloud_gpu_tests stipple_tiles3d_gpu_tests)
read -r -a backends <<<"${STIPPLE_TSAN_BACKENDS:-wgpu dawn}"
targets=("${bins[@]}")
[[ " ${bins[*]}" != *_gpu_tests* ]] || targets+=(stipple_tsan_keep_loaded)
binary=${STIPPLE_TEST_BINARY:-$root/build/stipple}
[[ -x "$binary" ]] || { echo "tsan.sh: $binary not found (run scripts/setup.sh first)" >&2; exit 2; }
cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
  -DSTIPPLE_TSAN=ON -DSTIPPLE_TEST_BINARY="$binary" >/dev/null
cmake --build build-tsan --target "${targets[@]}" -- -j"$(nproc)" |
  { grep -vE "^\[[0-9]+/[0-9]+\] (Building|Linking|Generating|Embedding|Re-checking)|^ninja: no work" || true; }
# Races inside uninstrumented third-party libraries (the Vulkan loader and driver, WebGPU,
# libcurl's resolver) are not ours: tests/tsan.supp says which and why.
export TSAN_OPTIONS="halt_on_error=0:second_deadlock_stack=1:suppressions=$root/tests/tsan.supp:${TSAN_OPTIONS:-}"
# The GPU tests: lavapipe alone (no other ICD loaded and unloaded on the way), and the driver kept
# loaded (tests/tools/tsan_keep_loaded.c: ThreadSanitizer aborts when a library of a
# called_from_lib suppression is unloaded, which the Vulkan loader does when an instance goes).
icd=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.json}
driver=$(sed -n 's/.*"library_path": *"\([^"]*\)".*/\1/p' "$icd" 2>/dev/null || true)
gpu_env=(VK_DRIVER_FILES="$icd" VK_ICD_FILENAMES="$icd"
  STIPPLE_TSAN_KEEP_LOADED="${driver:-libvulkan_lvp.so}"
  LD_PRELOAD="$root/build-tsan/tests/libstipple_tsan_keep_loaded.so${LD_PRELOAD:+:$LD_PRELOAD}")
status=0
run() {  # run LOG NAME ARGS...: one test process, its summary line and report count
  local log=$1 name=$2 rc races start=$SECONDS
  shift 2
  echo "== $name"
  set +e
  "$@" --gtest_brief=1 >"$log" 2>&1
  rc=$?
  set -e
  races=$(grep -c '^WARNING: ThreadSanitizer' "$log" || true)
  grep -E '^\[  (PASSED|FAILED|SKIPPED) |tests? ran|ThreadSanitizer: (library|SEGV)' "$log" | tail -n 3 || true
  echo "   exit $rc, ThreadSanitizer reports: $races, $((SECONDS - start)) s (log: $log)"
  [[ $rc -eq 0 && $races -eq 0 ]] || status=1
}
for b in "${bins[@]}"; do
  if [[ $b != *_gpu_tests ]]; then
    run "build-tsan/$b.log" "$b" "build-tsan/tests/$b" "${gtest[@]}"
  elif [[ $user_gtest -eq 1 ]]; then
    run "build-tsan/$b.log" "$b" env "${gpu_env[@]}" "build-tsan/tests/$b" "${gtest[@]}"
  else
    for be in "${backends[@]}"; do
      run "build-tsan/$b.$be.log" "$b ($be)" env "${gpu_env[@]}" "build-tsan/tests/$b" \
        --gtest_filter="*/$be"
    done
  fi
done
exit $status
