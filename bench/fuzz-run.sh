#!/usr/bin/env bash
# run.sh [-j CORES] [-t SECONDS] [TARGET...]: the fuzzing campaign of a package made by
# bench/fuzz-pack.sh (this file is its run.sh). Every target (default: all in ./targets) runs at
# once for SECONDS (default 3600), the CORES (default: nproc) shared out among them: each target at
# least one, the rest in proportion to what one execution of the target costs (cost_of below;
# FUZZ_EVEN=1 shares them equally). A target's cores run as libFuzzer processes that fuzz for the
# whole time (-jobs/-workers, a log each: fuzz-N.log), sharing the corpus directory; a crash,
# leak, timeout or out-of-memory input ends the process that found it, its input left in
# out/<target>/ and counted. FUZZ_MODE=fork runs them as -fork jobs instead, which go on past
# findings (-ignore_crashes etc.) but restart a process per job and re-run a sample of the
# corpus each time: on 2 cores fuzz_tileset ran 46,663 executions in 60 s that way, 68,134 as
# two workers. Each starts from the kept corpus, the seeds (the LAS readers also
# the heads of real LAS/LAZ files) and the regression inputs, inputs capped in length per target
# (max_len_of below); afterwards the new corpus is minimised (-merge=1) into out/corpus/<target>/
# (bring it back to tests/fuzz/corpus/). Prints one line per target, as bench/fuzz.sh does:
# processes (forks), executions, executions per second, coverage (edges: cov, features: ft; of
# the best process in worker mode), corpus files, crashes; the whole output is also in
# out/summary.txt. TARGET:N gives that target N processes outright (the cores left are shared
# among the others as above).
#   fuzz/run.sh -j 16 -t 900
#   fuzz/run.sh -j 4 -t 60 fuzz_las fuzz_tiles
#   fuzz/run.sh -j 16 -t 540 fuzz_pointlets:2 fuzz_json:5 fuzz_potree:9
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cores=$(nproc)
seconds=3600
mode=${FUZZ_MODE:-workers}
[[ $mode == fork || $mode == workers ]] || { echo "run.sh: FUZZ_MODE is fork or workers" >&2; exit 2; }
while getopts "j:t:h" opt; do
  case $opt in
    j) cores=$OPTARG ;;
    t) seconds=$OPTARG ;;
    *) sed -n '2,21p' "$0"; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
if [[ $# -gt 0 ]]; then targets=("$@"); else mapfile -t targets <"$here/targets"; fi
# TARGET:N, forks given outright.
declare -A fixed=()
for i in "${!targets[@]}"; do
  if [[ ${targets[$i]} == *:* ]]; then
    n_forks=${targets[$i]#*:} targets[$i]=${targets[$i]%%:*}
    [[ $n_forks =~ ^[1-9][0-9]*$ ]] || { echo "run.sh: bad fork count in ${targets[$i]}:$n_forks" >&2; exit 2; }
    fixed[${targets[$i]}]=$n_forks
  fi
done
out=${FUZZ_OUT:-$here/out}
mkdir -p "$out/corpus"
export LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PROJ_DATA="$here/proj" PROJ_LIB="$here/proj"
# malloc_context_size=0: ASan records no stack for each allocation (its default is 30 frames).
# Unwinding and storing them was a third of fuzz_tileset's time (its inputs allocate JSON trees);
# against 4 frames, 0 is 1.11x the executions (41,063 against 37,022 in 40 s, one core). Errors are
# still caught where they happen; a finding is run again with the full stacks when reproduced.
export ASAN_OPTIONS="detect_leaks=1:malloc_context_size=0:${ASAN_OPTIONS:-}"
# Seconds one input may take before it counts as a hang. 20 by default; a campaign at nice 19
# beside other work can starve a process that long (one did in campaign 10), so FUZZ_TIMEOUT
# raises it there.
timeout_s=${FUZZ_TIMEOUT:-20}
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

# The longest input each target is given (libFuzzer truncates longer corpus files): what its
# parser needs to reach everything, no more. A COPC page of 8 KiB is 256 entries (coverage is
# the same as with whole 64 KiB inputs, at 20 times the rate); the two input generators and the
# JSON readers need no more than 4 KiB. Not fuzz_las: cut to 16 KiB its kept corpus loses a
# third of its coverage (EVLRs and point counts past the cut), so it keeps the corpus's longest
# (64 KiB) and its harness decodes only the first and last points instead.
max_len_of() {
  case $1 in
    fuzz_copc) echo 8192 ;;
    fuzz_tileset | fuzz_las_roundtrip | fuzz_part | fuzz_json) echo 4096 ;;
    *) echo 0 ;;  # libFuzzer's default: the longest corpus file
  esac
}
# What one execution costs, relative (microseconds a core: about the inverse of the rates
# measured on 2 shared cores, scaled to the 16-core machine's rates of the targets measured
# there; see bench/RESULTS.md): the cores left after one fork per target are shared out in
# proportion, so that the slow targets get more -fork jobs. FUZZ_EVEN=1: an equal share.
cost_of() {
  [[ ${FUZZ_EVEN:-0} == 1 ]] && { echo 1; return; }
  case $1 in
    fuzz_las) echo 200 ;;
    fuzz_copc) echo 400 ;;
    fuzz_tileset) echo 3300 ;;
    fuzz_las_roundtrip) echo 2000 ;;
    fuzz_part) echo 1200 ;;
    fuzz_tiles) echo 350 ;;
    fuzz_ept) echo 250 ;;
    fuzz_potree) echo 950 ;;
    fuzz_pointlets) echo 70 ;;
    fuzz_json) echo 200 ;;
    *) echo 1000 ;;
  esac
}

n=${#targets[@]}
campaign() {
  local t=$1 forks=$2 dir="$out/$t" max_len=()
  rm -rf "$dir" && mkdir -p "$dir/work" "$dir/seeds"
  [[ $t == fuzz_las || $t == fuzz_copc ]] && { cp "$here/las-heads"/* "$dir/seeds/" 2>/dev/null || true; }
  local len
  len=$(max_len_of "$t")
  [[ $len -gt 0 ]] && max_len=(-max_len="$len")
  [[ $t == fuzz_las_roundtrip ]] || cp "$here/seeds"/* "$dir/seeds/" 2>/dev/null || true
  cp "$dir/seeds"/* "$dir/work/" 2>/dev/null || true
  cp "$here/corpus/$t"/* "$dir/work/" 2>/dev/null || true
  cp "$here/regressions/$t"/* "$dir/work/" 2>/dev/null || true
  local rc=0
  if [[ $mode == fork ]]; then
    (cd "$dir" && "$here/bin/$t" -fork="$forks" -ignore_crashes=1 -ignore_timeouts=1 \
      -ignore_ooms=1 -max_total_time="$seconds" -rss_limit_mb=2048 -timeout="$timeout_s" \
      "${max_len[@]}" -artifact_prefix="$dir/" "$dir/work" >"$dir/log" 2>&1) || rc=$?
  else
    # One libFuzzer process a core for the whole time (fuzz-N.log each), sharing work/.
    (cd "$dir" && "$here/bin/$t" -jobs="$forks" -workers="$forks" -max_total_time="$seconds" \
      -rss_limit_mb=2048 -timeout="$timeout_s" "${max_len[@]}" -artifact_prefix="$dir/" "$dir/work" \
      >"$dir/log" 2>&1) || rc=$?
  fi
  mkdir -p "$out/corpus/$t"
  "$here/bin/$t" -merge=1 -rss_limit_mb=2048 -timeout="$timeout_s" "$out/corpus/$t" "$dir/work" \
    >"$dir/merge.log" 2>&1 || true
  local last execs cov ft rate crashes
  if [[ $mode == fork ]]; then
    # Fork mode's status lines: #EXECS: cov: C ft: F corp: N exec/s R oom/timeout/crash: a/b/c
    last=$(grep -E '^#[0-9]+: cov: ' "$dir/log" | tail -n1 || true)
    execs=$(sed -E 's/^#([0-9]+):.*/\1/' <<<"$last")
    cov=$(sed -nE 's/.* cov: ([0-9]+) .*/\1/p' <<<"$last")
    ft=$(sed -nE 's/.* ft: ([0-9]+) .*/\1/p' <<<"$last")
    rate=$(sed -nE 's/.* exec\/s:? ([0-9]+) .*/\1/p' <<<"$last")
  else
    # Each worker's last status line (#EXECS ... cov: C ft: F ...): executions summed, the
    # largest coverage of one worker (they share inputs through work/ only when they start), the
    # rate over the whole time.
    read -r execs cov ft < <(for f in "$dir"/fuzz-*.log; do
      grep -E '^#[0-9]+[[:space:]]' "$f" | tail -n1
    done | awk '{sub(/^#/, "", $1); n += $1
      for (i = 2; i < NF; ++i) { if ($i == "cov:" && $(i+1) > c) c = $(i+1)
        if ($i == "ft:" && $(i+1) > f) f = $(i+1) } }
      END {print n + 0, c + 0, f + 0}')
    rate=$((execs / seconds))
  fi
  crashes=$(find "$dir" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' -o -name 'oom-*' \) | wc -l)
  printf '%-20s %6ss %5s %12s %8s %6s %7s %6s %7s %s\n' "$t" "$seconds" "$forks" "${execs:-0}" \
    "${rate:-?}" "${cov:-?}" "${ft:-?}" "$(find "$out/corpus/$t" -type f | wc -l)" "$crashes" \
    "$([[ $rc -ne 0 ]] && echo "exit $rc: $dir/log")"
}

echo "$n targets, $cores cores, $seconds s each (all at once); output in $out"
# Forks: each target one, the cores left over in proportion to cost_of (largest remainders
# first), so that the forks add up to the cores (or to the targets, when there are fewer cores).
declare -A forks=()
shared=()
left=$cores
for t in "${targets[@]}"; do
  if [[ -n ${fixed[$t]:-} ]]; then
    forks[$t]=${fixed[$t]} left=$((left - fixed[$t]))
  else
    shared+=("$t")
  fi
done
total=0 left=$((left - ${#shared[@]}))
for t in "${shared[@]}"; do total=$((total + $(cost_of "$t"))); forks[$t]=1; done
if [[ $left -gt 0 && ${#shared[@]} -gt 0 ]]; then
  declare -A rest=()
  for t in "${shared[@]}"; do
    share=$((left * $(cost_of "$t")))
    forks[$t]=$((1 + share / total))
    rest[$t]=$((share % total))
  done
  given=0
  for t in "${shared[@]}"; do given=$((given + forks[$t] - 1)); done
  while read -r t; do
    [[ $given -lt $left ]] || break
    forks[$t]=$((forks[$t] + 1)) given=$((given + 1))
  done < <(for t in "${shared[@]}"; do echo "${rest[$t]} $t"; done | sort -rn | cut -d' ' -f2)
fi
for t in "${targets[@]}"; do
  campaign "$t" "${forks[$t]}" >"$out/$t.line" &
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
