#!/usr/bin/env bash
# Runs the whole test suite and prints ctest's summary:
#   1. build/ (Release with debug info, the one setup.sh builds): unit, GPU (lavapipe, both
#      WebGPU implementations) and command-line tests;
#   2. build-asan/ (clang, AddressSanitizer + UndefinedBehaviorSanitizer): the same tests plus
#      the libFuzzer targets, each fuzzed for a bounded time.
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

# The Python bindings (pyproject.toml), built into build/python (incrementally) and installed
# into .deps/python, then their pytest suite.
if [[ -x .deps/python/bin/python ]] && .deps/python/bin/python -c 'import nanobind, pytest' 2>/dev/null; then
  stage "Python tests (tests/python)"
  .deps/python/bin/pip install -q --disable-pip-version-check --no-build-isolation \
    -C cmake.define.STIPPLE_WERROR="${werror:-OFF}" . >/dev/null
  (cd tests/python && ../../.deps/python/bin/python -m pytest -q -p no:cacheprovider .)
else
  echo "== Python tests skipped: .deps/python is missing (scripts/setup.sh --deps installs it) =="
fi

if [[ "${STIPPLE_SKIP_ASAN:-0}" != 1 ]]; then
  stage "building build-asan/ (AddressSanitizer + UndefinedBehaviorSanitizer, fuzzers)"
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
    -DSTIPPLE_SANITIZE=ON -DSTIPPLE_FUZZ=ON -DSTIPPLE_WERROR="${werror:-OFF}" >/dev/null
  cmake --build build-asan -- -j"$jobs" | { grep -vE "^\[[0-9]+/[0-9]+\] (Building|Linking|Generating|Embedding|Re-checking)|^ninja: no work" || true; }
  # Leaks inside the Vulkan driver and the WebGPU libraries are not ours to fix.
  export LSAN_OPTIONS="suppressions=$root/tests/lsan.supp:print_suppressions=0"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  stage "tests under the sanitizers, with fuzzing (build-asan/)"
  ctest --test-dir build-asan --output-on-failure -j"$jobs"
fi
