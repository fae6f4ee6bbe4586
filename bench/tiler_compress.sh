#!/usr/bin/env bash
# Bytes a point and tiling throughput of each `stipple tile` output option, beside py3dtiles on
# the same input and machine. Bytes are the whole output folder (`du -sb`: tiles, tileset.json,
# subtrees) over the input's points.
#   bench/tiler_compress.sh [POINTS]   (generated input size, default 5000000)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
stipple="$root/build/stipple"
py3dtiles="${PY3DTILES:-$root/.deps/py3dtiles/bin/py3dtiles}"
work="${TMPDIR:-/tmp}/stipple_bench_tiler_compress"
mkdir -p "$work"
points="${1:-5000000}"
gen="$work/gen_${points}.las"
[[ -f "$gen" ]] || "$stipple" generate -n "$points" -o "$gen" >/dev/null
inputs=("$gen")
[[ -f "$root/../shared/data/las/autzen_trim.las" ]] && inputs=("$root/../shared/data/las/autzen_trim.las" "$gen")
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
  # LAS 1.4 headers hold the 64-bit count; older ones the 32-bit legacy count.
  n=$(python3 -c "import struct,sys;h=open(sys.argv[1],'rb').read(375);print(struct.unpack_from('<Q',h,247)[0] if h[25]>=4 else struct.unpack_from('<I',h,107)[0])" "$in")
  name=$(basename "$in")
  crs=()
  [[ "$in" == "$gen" ]] && crs=(--crs EPSG:32633)
  for opt in "glb none" "glb meshopt" "pnts none" "pnts draco" "glb meshopt --implicit"; do
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
