#!/usr/bin/env bash
# Bytes a point and tiling throughput of each `stipple tile` output option, beside py3dtiles on
# the same input and machine. Bytes are the whole output folder (`du -sb`: tiles, tileset.json,
# subtrees) over the input's points.
#   bench/tiler_compress.sh [POINTS]   (generated input size, default 5000000)
#   bench/tiler_compress.sh --matrix FILE...   (bytes a point only: a row per file, a column per
#                                               option, py3dtiles last)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
stipple="$root/build/stipple"
py3dtiles="${PY3DTILES:-$root/.deps/py3dtiles/bin/py3dtiles}"
work="${TMPDIR:-/tmp}/stipple_bench_tiler_compress"
mkdir -p "$work"
matrix=0
if [[ "${1:-}" == "--matrix" ]]; then
  matrix=1
  shift
fi
points=5000000
[[ $matrix -eq 0 ]] && points="${1:-5000000}"
gen="$work/gen_${points}.las"
if [[ $matrix -eq 1 ]]; then
  inputs=("$@")
else
  [[ -f "$gen" ]] || "$stipple" generate -n "$points" -o "$gen" >/dev/null
  inputs=("$gen")
  [[ -f "$root/../shared/data/las/autzen_trim.las" ]] && inputs=("$root/../shared/data/las/autzen_trim.las" "$gen")
fi
options=("glb none" "glb meshopt" "pnts none" "pnts draco" "glb meshopt --implicit")
count() {  # LAS 1.4 headers hold the 64-bit count; older ones the 32-bit legacy count.
  python3 -c "import struct,sys;h=open(sys.argv[1],'rb').read(375);print(struct.unpack_from('<Q',h,247)[0] if h[25]>=4 else struct.unpack_from('<I',h,107)[0])" "$1"
}
if [[ $matrix -eq 1 ]]; then
  echo "| input | points | glb | glb meshopt | pnts | pnts draco | glb meshopt implicit | py3dtiles pnts |"
  echo "|---|---|---|---|---|---|---|---|"
  for in in "${inputs[@]}"; do
    n=$(count "$in")
    row="| $(basename "$in") | $n |"
    # Files without a CRS (PDAL's small test files) are tiled as $BENCH_CRS: the bytes do not
    # depend on where the points are.
    crs=()
    py_crs=()
    if "$stipple" info "$in" 2>/dev/null | grep -q "CRS:        none"; then
      bench_crs="${BENCH_CRS:-EPSG:2994}"
      crs=(--crs "$bench_crs")
      py_crs=(--srs_in "${bench_crs#EPSG:}")
      row="| $(basename "$in") (as $bench_crs) | $n |"
    fi
    for opt in "${options[@]}"; do
      set -- $opt
      rm -rf "$work/out"
      if "$stipple" tile "$in" -o "$work/out" --force "${crs[@]}" --format "$1" --compress "$2" \
        ${3:-} >/dev/null 2>&1; then
        row="$row $(printf "%.2f" "$(echo "$(du -sb "$work/out" | cut -f1) / $n" | bc -l)") |"
      else
        row="$row failed |"
      fi
    done
    rm -rf "$work/out_py3dtiles"
    # Bounded: py3dtiles can stall on some LAZ inputs (shown as "-").
    if [[ -x "$py3dtiles" ]] && timeout 300 "$py3dtiles" convert "${py_crs[@]}" --srs_out 4978 \
      --jobs "$(nproc)" --out "$work/out_py3dtiles" --overwrite "$in" >/dev/null 2>&1; then
      row="$row $(printf "%.2f" "$(echo "$(du -sb "$work/out_py3dtiles" | cut -f1) / $n" | bc -l)") |"
    else
      row="$row - |"
    fi
    echo "$row"
  done
  exit 0
fi
run() {  # label, points, output dir, command...
  local label=$1 n=$2 out=$3
  shift 3
  rm -rf "$out"
  /usr/bin/time -f "%e %U %S" -o "$work/time.txt" "$@" >/dev/null 2>&1
  read -r secs user sys <"$work/time.txt"
  local bytes
  bytes=$(du -sb "$out" | cut -f1)
  printf "| %s | %s | %.2f | %.2f s | %.2f M/s | %.1f s |\n" "$label" "$n" \
    "$(echo "$bytes / $n" | bc -l)" "$secs" "$(echo "$n / $secs / 1000000" | bc -l)" \
    "$(echo "$user + $sys" | bc -l)"
}
echo "| output | points | bytes/point | wall | throughput | CPU (user+sys) |"
echo "|---|---|---|---|---|---|"
for in in "${inputs[@]}"; do
  n=$(count "$in")
  name=$(basename "$in")
  crs=()
  [[ "$in" == "$gen" ]] && crs=(--crs EPSG:32633)
  for opt in "${options[@]}"; do
    set -- $opt
    run "stipple tile --format $1 --compress $2 ${3:-} ($name)" "$n" "$work/out" \
      "$stipple" tile "$in" -o "$work/out" --force "${crs[@]}" --format "$1" --compress "$2" ${3:-}
  done
  if [[ -x "$py3dtiles" ]]; then
    srs=""
    [[ "$in" == "$gen" ]] && srs="--srs_in 32633"
    # shellcheck disable=SC2086
    run "py3dtiles convert, pnts ($name)" "$n" "$work/out_py3dtiles" "$py3dtiles" convert $srs \
      --srs_out 4978 --jobs "$(nproc)" --out "$work/out_py3dtiles" --overwrite "$in"
  else
    echo "| py3dtiles | - | not installed (scripts/setup.sh installs it into .deps/py3dtiles) | | | |"
  fi
done
