#!/usr/bin/env bash
# run.sh [-j CORES] [-t SECONDS] [TARGET...]: the fuzzing campaign of a package made by
# bench/fuzz-pack.sh (this file is its run.sh). Every target (default: all in ./targets) runs at
# once for SECONDS (default 3600), the CORES (default: nproc) shared out among them as libFuzzer
# -fork jobs (each target at least one); crashes, leaks, timeouts and out-of-memory inputs do
# not stop a target (-ignore_crashes etc.): each is left in out/<target>/ and counted. Each
# starts from the kept corpus, the seeds (the LAS readers: the heads of real LAS/LAZ files;
# fuzz_tileset and fuzz_las_roundtrip, input generators, get 4 KiB inputs) and the regression
# inputs; afterwards the new corpus is minimised (-merge=1) into out/corpus/<target>/ (bring it
# back to tests/fuzz/corpus/). Prints one line per target, as bench/fuzz.sh does: executions,
# executions per second, coverage (edges: cov, features: ft), corpus files, crashes; the
# whole output is also in out/summary.txt.
#   fuzz/run.sh -j 16 -t 3600
#   fuzz/run.sh -j 4 -t 60 fuzz_las fuzz_tiles
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cores=$(nproc)
seconds=3600
while getopts "j:t:h" opt; do
  case $opt in
    j) cores=$OPTARG ;;
    t) seconds=$OPTARG ;;
    *) sed -n '2,14p' "$0"; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
if [[ $# -gt 0 ]]; then targets=("$@"); else mapfile -t targets <"$here/targets"; fi
out=${FUZZ_OUT:-$here/out}
mkdir -p "$out/corpus"
export LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PROJ_DATA="$here/proj" PROJ_LIB="$here/proj"
export ASAN_OPTIONS="detect_leaks=1:${ASAN_OPTIONS:-}"
export LSAN_OPTIONS="suppressions=$here/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
for t in "${targets[@]}"; do
  [[ -x "$here/bin/$t" ]] || { echo "run.sh: no target $t in $here/bin" >&2; exit 2; }
  # A target that cannot start here (a library missing, glibc too old) fails now, not later.
  if ! "$here/bin/$t" -runs=0 >"$out/$t.start.log" 2>&1; then
    echo "run.sh: $t does not start on this machine:" >&2
    tail -n 5 "$out/$t.start.log" >&2
    exit 2
  fi
done

n=${#targets[@]}
campaign() {
  local t=$1 forks=$2 dir="$out/$t" max_len=()
  rm -rf "$dir" && mkdir -p "$dir/work" "$dir/seeds"
  case $t in
    fuzz_las | fuzz_copc) cp "$here/las-heads"/* "$dir/seeds/" 2>/dev/null || true ;;
    fuzz_tileset | fuzz_las_roundtrip) max_len=(-max_len=4096) ;;
  esac
  [[ $t == fuzz_las_roundtrip ]] || cp "$here/seeds"/* "$dir/seeds/" 2>/dev/null || true
  cp "$dir/seeds"/* "$dir/work/" 2>/dev/null || true
  cp "$here/corpus/$t"/* "$dir/work/" 2>/dev/null || true
  cp "$here/regressions/$t"/* "$dir/work/" 2>/dev/null || true
  local rc=0
  (cd "$dir" && "$here/bin/$t" -fork="$forks" -ignore_crashes=1 -ignore_timeouts=1 \
    -ignore_ooms=1 -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=20 \
    "${max_len[@]}" -artifact_prefix="$dir/" "$dir/work" >"$dir/log" 2>&1) || rc=$?
  mkdir -p "$out/corpus/$t"
  "$here/bin/$t" -merge=1 -rss_limit_mb=2048 -timeout=20 "$out/corpus/$t" "$dir/work" \
    >"$dir/merge.log" 2>&1 || true
  # Fork mode's status lines: #EXECS: cov: C ft: F corp: N exec/s R oom/timeout/crash: a/b/c
  local last execs cov ft rate crashes
  last=$(grep -E '^#[0-9]+: cov: ' "$dir/log" | tail -n1 || true)
  execs=$(sed -E 's/^#([0-9]+):.*/\1/' <<<"$last")
  cov=$(sed -nE 's/.* cov: ([0-9]+) .*/\1/p' <<<"$last")
  ft=$(sed -nE 's/.* ft: ([0-9]+) .*/\1/p' <<<"$last")
  rate=$(sed -nE 's/.* exec\/s:? ([0-9]+) .*/\1/p' <<<"$last")
  crashes=$(find "$dir" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' -o -name 'oom-*' \) | wc -l)
  printf '%-20s %6ss %5s %12s %8s %6s %7s %6s %7s %s\n' "$t" "$seconds" "$forks" "${execs:-0}" \
    "${rate:-?}" "${cov:-?}" "${ft:-?}" "$(find "$out/corpus/$t" -type f | wc -l)" "$crashes" \
    "$([[ $rc -ne 0 ]] && echo "exit $rc: $dir/log")"
}

echo "$n targets, $cores cores, $seconds s each (all at once); output in $out"
i=0
for t in "${targets[@]}"; do
  forks=$((cores / n + (i < cores % n ? 1 : 0)))
  [[ $forks -ge 1 ]] || forks=1
  campaign "$t" "$forks" >"$out/$t.line" &
  i=$((i + 1))
done
wait
{
  printf '%-20s %7s %5s %12s %8s %6s %7s %6s %7s\n' target time forks execs exec/s cov ft corpus crashes
  for t in "${targets[@]}"; do cat "$out/$t.line"; done
} | tee "$out/summary.txt"
# Non-zero when any target found something or ended in an error.
for t in "${targets[@]}"; do
  awk '$9 > 0 || / exit [0-9]/ {bad = 1} END {exit bad}' "$out/$t.line" || exit 1
done
