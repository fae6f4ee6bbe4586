#!/usr/bin/env bash
# bench/fuzz-replay.sh TARGET DIR...: runs every input in DIR... once through TARGET built with
# AddressSanitizer + UndefinedBehaviorSanitizer and leak checks (the configuration of
# bench/fuzz.sh, in $STIPPLE_FUZZ_BUILD, default build-fuzz), without fuzzing. For the corpus of a
# campaign run without ASan (STIPPLE_FUZZ_SANITIZERS=undefined, several times the executions for
# the allocation-heavy parsers): every input that campaign kept, each a path it found, is then
# checked for the memory errors and leaks that build does not see. Prints the inputs run and the
# coverage ASan's build saw; a finding stops the run, its input is named and left in
# bench/fuzz-out/replay-TARGET/, and the script exits non-zero.
#   bench/fuzz-replay.sh fuzz_tileset /tmp/fo/fuzz_tileset/work
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
target=${1:?usage: bench/fuzz-replay.sh TARGET DIR...}
shift
[[ $# -gt 0 ]] || { echo "usage: bench/fuzz-replay.sh TARGET DIR..." >&2; exit 2; }
for d in "$@"; do
  [[ -d $d ]] || { echo "fuzz-replay: $d is not a directory" >&2; exit 2; }
done
build=${STIPPLE_FUZZ_BUILD:-build-fuzz}
cd "$root"
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
if [[ ! -f "$build/build.ninja" ]]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
    -DSTIPPLE_SANITIZE=ON -DSTIPPLE_FUZZ=ON >/dev/null
fi
# An ASan build: STIPPLE_SANITIZE on, and STIPPLE_SANITIZERS (when the cache has it) with address.
if ! grep -q '^STIPPLE_SANITIZE:BOOL=ON' "$build/CMakeCache.txt" ||
  { grep -q '^STIPPLE_SANITIZERS:' "$build/CMakeCache.txt" &&
    ! grep -q '^STIPPLE_SANITIZERS:STRING=.*address' "$build/CMakeCache.txt"; }; then
  echo "fuzz-replay: $build is not an AddressSanitizer build" >&2
  exit 2
fi
cmake --build "$build" --target "$target" |
  { grep -vE "^\[[0-9]+/[0-9]+\] |^ninja: no work|^-- " || true; }
out="$root/bench/fuzz-out/replay-$target"
rm -rf "$out" && mkdir -p "$out"
export ASAN_OPTIONS="detect_leaks=1:${ASAN_OPTIONS:-}"
export LSAN_OPTIONS="suppressions=$root/tests/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export PROJ_DATA=${PROJ_DATA:-/usr/share/proj}
inputs=$(find "$@" -maxdepth 1 -type f | wc -l)
# -runs=0: libFuzzer runs every input of the directories (its initial corpus), then stops.
rc=0
"$build/tests/fuzz/$target" -runs=0 -rss_limit_mb=2048 -timeout=60 -artifact_prefix="$out/" \
  "$@" >"$out/log" 2>&1 || rc=$?
inited=$(grep -E '^#[0-9]+[[:space:]]+INITED' "$out/log" | tail -n1 || true)
echo "$target: $inputs inputs from $*; ASan+UBSan build $build; ${inited:-no INITED line}"
if [[ $rc -ne 0 ]]; then
  echo "fuzz-replay: $target failed (exit $rc), log $out/log:" >&2
  grep -E 'ERROR|SUMMARY|Test unit written' "$out/log" | head -n 5 >&2
  exit 1
fi
