#!/usr/bin/env bash
# Runs the whole test suite and prints ctest's summary:
#   1. build/ (Release with debug info, the one setup.sh builds): unit, GPU (lavapipe, both
#      WebGPU implementations) and command-line tests;
#   2. the Python package's pytest suite;
#   3. build-asan/ (clang, AddressSanitizer + UndefinedBehaviorSanitizer): the same tests but the
#      GPU image comparisons the first part checks pixel by pixel (see below), plus the libFuzzer
#      targets, each replaying its kept corpus and fuzzing for a bounded time.
# Set STIPPLE_SKIP_ASAN=1 to run only the first part.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# ccache keys on paths relative to the checkout, so a fresh clone elsewhere (CI) reuses the
# objects of earlier builds.
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
cd "$root"
jobs=$(nproc)
werror="${CI:+ON}"
# Each stage says when it starts (minutes:seconds since the start), so a log shows where the
# time goes; the last line is the total.
stage() { printf '== [%d:%02d] %s ==\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*"; }
trap 'stage "end (exit $?)"' EXIT

[[ -f build/build.ninja ]] || scripts/setup.sh
stage "building build/"
cmake --build build -- -j"$jobs" | { grep -vE "^\[[0-9]+/[0-9]+\] (Building|Linking|Generating|Embedding|Re-checking)|^ninja: no work" || true; }
stage "tests (build/)"
ctest --test-dir build --output-on-failure -j"$jobs"

# The Python bindings (pyproject.toml), built into build-python (incrementally) and installed
# into .deps/python, then their pytest suite.
if [[ -x .deps/python/bin/python ]] && .deps/python/bin/python -c 'import nanobind, pytest' 2>/dev/null; then
  stage "Python tests (tests/python)"
  # The native build's compilers and flags, so that ccache gives the library's objects back
  # from build/ (build-python sits beside it: the same relative paths).
  cxx=$(sed -n 's/^CMAKE_CXX_COMPILER:[A-Z]*=//p' build/CMakeCache.txt)
  cc=$(sed -n 's/^CMAKE_C_COMPILER:[A-Z]*=//p' build/CMakeCache.txt)
  .deps/python/bin/pip install -q --disable-pip-version-check --no-build-isolation \
    -C cmake.define.STIPPLE_WERROR="${werror:-OFF}" -C cmake.define.CMAKE_CXX_COMPILER="$cxx" \
    -C cmake.define.CMAKE_C_COMPILER="$cc" . >/dev/null
  (cd tests/python && ../../.deps/python/bin/python -m pytest -q -p no:cacheprovider .)
else
  echo "== Python tests skipped: .deps/python is missing (scripts/setup.sh --deps installs it) =="
fi

if [[ "${STIPPLE_SKIP_ASAN:-0}" != 1 ]]; then
  stage "building build-asan/ (AddressSanitizer + UndefinedBehaviorSanitizer, fuzzers)"
  # Line tables are all the sanitizers' reports need (file:line in every frame): 20 % less
  # compiler time than full debug info on 2 cores.
  asan_flags="-O2 -gline-tables-only -DNDEBUG"
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
    -DSTIPPLE_SANITIZE=ON -DSTIPPLE_FUZZ=ON -DSTIPPLE_WERROR="${werror:-OFF}" \
    "-DCMAKE_C_FLAGS_RELWITHDEBINFO=$asan_flags" "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=$asan_flags" \
    >/dev/null
  cmake --build build-asan -- -j"$jobs" | { grep -vE "^\[[0-9]+/[0-9]+\] (Building|Linking|Generating|Embedding|Re-checking)|^ninja: no work" || true; }
  # Leaks inside the Vulkan driver and the WebGPU libraries are not ours to fix.
  export LSAN_OPTIONS="suppressions=$root/tests/lsan.supp:print_suppressions=0"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  # Every test but the GPU image comparisons that the Release run above already checks pixel by
  # pixel: the Dawn twins of the backend-parameterised GPU tests (the C++ above webgpu.h is the
  # same for both backends; Cli.BackendsAgreeOnAutzen and the other tests that run both stay),
  # and the compute rasterizer's loop-against-loop image tests (its C++ runs in the fallback,
  # segment, streaming, filter and virtualized tests that stay).
  stage "tests under the sanitizers, with fuzzing (build-asan/)"
  ctest --test-dir build-asan --output-on-failure -j"$jobs" \
    -E '/dawn( |$)|^Backends/ComputeRaster\.(LeanLoopDrawsTheSameImageNearAndFar|FiltersAndClipsHoldInEveryKernelVariant|KernelVariantsDrawTheSameImage)/'

fi
