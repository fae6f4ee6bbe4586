#!/usr/bin/env bash
# Tiler throughput and peak memory, stipple tile vs py3dtiles convert, same input, same machine.
#   bench/tiler.sh [POINTS]   (generated input size, default 100000000)
#   PY3DTILES=path/to/py3dtiles overrides .deps/py3dtiles/bin/py3dtiles (e.g. a worktree)
# Scaling (issue 22): runs at 1 and T threads, REPEAT times each (default 3, interleaved), and
# prints per phase the median wall and CPU times, the serial fraction and Amdahl's prediction
# for PREDICT threads (default 16):
#   bench/tiler.sh --threads T [POINTS]   (default 20000000)
#   STIPPLE=path/to/stipple overrides build/stipple; TILE_ARGS adds options (e.g. --max-memory 512M)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
stipple="${STIPPLE:-$root/build/stipple}"
py3dtiles="${PY3DTILES:-$root/.deps/py3dtiles/bin/py3dtiles}"
work="${TMPDIR:-/tmp}/stipple_bench_tiler"
mkdir -p "$work"
if [[ "${1:-}" == "--threads" ]]; then
  threads="${2:?--threads takes a thread count}"
  points="${3:-20000000}"
  gen="$work/gen_${points}.las"
  [[ -f "$gen" ]] || "$stipple" generate -n "$points" -o "$gen" >/dev/null
  one=() many=()
  for r in $(seq "${REPEAT:-3}"); do
    for t in 1 "$threads"; do
      rm -rf "$work/out_scaling"
      # shellcheck disable=SC2086
      "$stipple" tile "$gen" -o "$work/out_scaling" --threads "$t" ${TILE_ARGS:-} \
        --stats "$work/scaling_${t}_${r}.json" >/dev/null
      if [[ "$t" == 1 ]]; then one+=("$work/scaling_${t}_${r}.json"); else many+=("$work/scaling_${t}_${r}.json"); fi
    done
  done
  rm -rf "$work/out_scaling"
  echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg), $(nproc) cores"
  exec python3 "$root/bench/tiler_scaling.py" "$threads" "${PREDICT:-16}" "${one[@]}" -- "${many[@]}"
fi
points="${1:-100000000}"
gen="$work/gen_${points}.las"
[[ -f "$gen" ]] || "$stipple" generate -n "$points" -o "$gen" >/dev/null
inputs=("$root/../shared/data/las/autzen_trim.las" "$gen")
run() {  # label, points, command...: prints seconds, points/s, CPU seconds and peak RSS
  local label=$1 n=$2
  shift 2
  /usr/bin/time -f "%e %M %U %S" -o "$work/time.txt" "$@" >/dev/null 2>&1
  read -r secs kb user sys <"$work/time.txt"
  printf "| %s | %s | %.2f s | %.2f M/s | %.1f s | %.0f MB |\n" "$label" "$n" "$secs" \
    "$(echo "$n / $secs / 1000000" | bc -l)" "$(echo "$user + $sys" | bc -l)" \
    "$(echo "$kb / 1024" | bc -l)"
}
# CPU time (user + sys) is the steadier figure on a shared machine; wall time is the goal's.
echo "| tool | points | wall | throughput | CPU (user+sys) | peak RSS |"
echo "|---|---|---|---|---|---|"
for in in "${inputs[@]}"; do
  n=$("$stipple" info "$in" 2>/dev/null | grep -iE "^ *points" | grep -oE "[0-9]+" | head -n1 || true)
  [[ -n "$n" ]] || n=$(python3 -c "import struct,sys;f=open(sys.argv[1],'rb');h=f.read(375);print(struct.unpack_from('<Q',h,247)[0] or struct.unpack_from('<I',h,107)[0])" "$in")
  rm -rf "$work/out_stipple" "$work/out_py3dtiles"
  run "stipple tile ($(basename "$in"))" "$n" "$stipple" tile "$in" -o "$work/out_stipple"
  if [[ -x "$py3dtiles" ]]; then
    srs=""
    [[ "$in" == "$gen" ]] && srs="--srs_in 32633"
    # shellcheck disable=SC2086
    run "py3dtiles convert ($(basename "$in"))" "$n" "$py3dtiles" convert $srs --srs_out 4978 \
      --jobs "$(nproc)" --out "$work/out_py3dtiles" --overwrite "$in"
  else
    echo "| py3dtiles | - | not installed (scripts/setup.sh installs it into .deps/py3dtiles) | | | |"
  fi
done
