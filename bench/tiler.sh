#!/usr/bin/env bash
# Tiler throughput and peak memory, stipple tile vs py3dtiles convert, same input, same machine.
#   bench/tiler.sh [POINTS]   (generated input size, default 100000000)
#   PY3DTILES=path/to/py3dtiles overrides .deps/py3dtiles/bin/py3dtiles (e.g. a worktree)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
stipple="$root/build/stipple"
py3dtiles="${PY3DTILES:-$root/.deps/py3dtiles/bin/py3dtiles}"
work="${TMPDIR:-/tmp}/stipple_bench_tiler"
mkdir -p "$work"
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
