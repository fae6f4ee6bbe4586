#!/usr/bin/env bash
# bench/fuzz.sh SECONDS [TARGET...]: a fuzzing campaign. Builds the libFuzzer targets (clang-14,
# AddressSanitizer + UndefinedBehaviorSanitizer, the configuration of scripts/test.sh) and runs
# each (default: every one in tests/fuzz/CMakeLists.txt) for SECONDS, JOBS at a time (default:
# the number of cores), starting from the kept corpus in tests/fuzz/corpus/<target>/, the
# generated seeds (tests/fuzz/seeds/) and, for the LAS readers, the heads of the real files in
# ../shared/data, inputs capped in length per target as bench/fuzz-run.sh caps them. After
# the run the kept corpus is replaced by the minimised union of old and new (libFuzzer -merge=1),
# so the next campaign, and CI's short runs, start where this one stopped.
# Prints one line per target: executions, executions per second, coverage (edges: cov, features:
# ft), corpus files kept, and crashes (crash, leak, timeout, out-of-memory); a crash's input is
# left in bench/fuzz-out/<target>/ and the script exits non-zero. Slow units (over 10 s, which a
# loaded machine produces too) are left there as well but not counted.
#   JOBS=2 bench/fuzz.sh 600                 every target, 10 minutes each, two at a time
#   STIPPLE_FUZZ_BUILD=build-fuzz bench/fuzz.sh 60 fuzz_las   another build directory
#   STIPPLE_FUZZ_BUILD=build-fuzz-ub STIPPLE_FUZZ_SANITIZERS=undefined bench/fuzz.sh 600 fuzz_tileset
#                                            without ASan (a new build directory), then replay the
#                                            corpus under ASan: bench/fuzz-replay.sh
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
seconds=${1:?usage: bench/fuzz.sh SECONDS [TARGET...]}
shift
jobs=${JOBS:-$(nproc)}
build=${STIPPLE_FUZZ_BUILD:-build-asan}
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=1
if [[ $# -gt 0 ]]; then
  targets=("$@")
else
  mapfile -t targets < <(sed -n '/^set(STIPPLE_FUZZ_TARGETS/,/)/p' tests/fuzz/CMakeLists.txt |
    tr ' ()' '\n\n\n' | grep '^fuzz_')
fi

if [[ ! -f "$build/build.ninja" ]]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
    -DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
    -DSTIPPLE_SANITIZE=ON -DSTIPPLE_SANITIZERS="${STIPPLE_FUZZ_SANITIZERS:-address,undefined}" \
    -DSTIPPLE_FUZZ=ON >/dev/null
fi
cmake --build "$build" --target "${targets[@]}" -- -j"$jobs" |
  { grep -vE "^\[[0-9]+/[0-9]+\] |^ninja: no work|^-- " || true; }

out="$root/bench/fuzz-out"
mkdir -p "$out"
export ASAN_OPTIONS="detect_leaks=1:malloc_context_size=0:${ASAN_OPTIONS:-}"  # as fuzz-run.sh, which says why
export LSAN_OPTIONS="suppressions=$root/tests/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"

# One campaign: seeds -> working corpus -> fuzz -> merge into the kept corpus -> a result line.
campaign() {
  local t=$1 exe="$build/tests/fuzz/$1" work="$out/$1/work" kept="tests/fuzz/corpus/$1"
  rm -rf "$out/$t" && mkdir -p "$work" "$kept"
  # Seeds: the heads of the real LAS/LAZ files for the targets that read LAS, the generated
  # files of tests/fuzz/seeds for the others. They are not kept (every run adds them again).
  local seeds="$out/$t/seeds" max_len=() len
  mkdir -p "$seeds"
  case $t in
    fuzz_las | fuzz_copc)
      if [[ -d ../shared/data ]]; then
        while IFS= read -r -d '' f; do
          head -c 65536 "$f" >"$seeds/$(basename "$f")"
        done < <(find ../shared/data -type f \( -name '*.las' -o -name '*.laz' \) -print0)
      fi
      ;;
  esac
  # The input length cap of bench/fuzz-run.sh (max_len_of there: why each).
  len=$(bash -c "source <(sed -n '/^max_len_of()/,/^}/p' bench/fuzz-run.sh); max_len_of $t")
  [[ $len -gt 0 ]] && max_len=(-max_len="$len")
  [[ $t == fuzz_las_roundtrip ]] || find tests/fuzz/seeds -type f -exec cp {} "$seeds"/ \;
  cp "$seeds"/* "$work"/ 2>/dev/null || true
  cp "$kept"/* "$work"/ 2>/dev/null || true
  local rc=0
  "$exe" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=20 -print_final_stats=1 \
    "${max_len[@]}" -artifact_prefix="$out/$t/" "$work" >"$out/$t/log" 2>&1 || rc=$?
  # Minimise old + new into a fresh directory, then keep that.
  mkdir -p "$out/$t/merged"
  "$exe" -merge=1 -rss_limit_mb=2048 -timeout=20 "$out/$t/merged" "$work" "$kept" \
    >"$out/$t/merge.log" 2>&1 || true
  # Seeds stay out of the kept corpus (merge names files by their SHA-1).
  for f in "$seeds"/*; do
    [[ -f $f ]] && rm -f "$out/$t/merged/$(sha1sum "$f" | cut -d' ' -f1)"
  done
  if [[ -n "$(ls -A "$out/$t/merged")" ]]; then
    rm -rf "$kept" && mv "$out/$t/merged" "$kept"
  fi
  rm -rf "$work" "$seeds"
  local execs cov ft crashes
  execs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$out/$t/log" | grep -o '[0-9]*$' || echo 0)
  cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+' "$out/$t/log" | tail -n1 || true)
  ft=${cov##*ft: } cov=${cov%% ft*} cov=${cov#cov: }
  crashes=$(find "$out/$t" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' -o -name 'oom-*' \) | wc -l)
  printf '%-20s %6ss %12s %8s %6s %7s %6s %7s %s\n' "$t" "$seconds" "${execs:-0}" \
    "$(( ${execs:-0} / (seconds > 0 ? seconds : 1) ))" "${cov:-?}" "${ft:-?}" \
    "$(find "$kept" -type f | wc -l)" "$crashes" "$([[ $rc -ne 0 ]] && echo "exit $rc: $out/$t/log")"
}

printf '%-20s %7s %12s %8s %6s %7s %6s %7s\n' target time execs exec/s cov ft corpus crashes
running=0
for t in "${targets[@]}"; do
  campaign "$t" >"$out/$t.line" &
  running=$((running + 1))
  if [[ $running -ge $jobs ]]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait
status=0
for t in "${targets[@]}"; do
  cat "$out/$t.line"
  grep -q 'exit [0-9]' "$out/$t.line" && status=1
done
exit $status
