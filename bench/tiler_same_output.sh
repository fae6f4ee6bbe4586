#!/usr/bin/env bash
# Output identity (issue 22): `stipple tile` of this build and of a baseline build (e.g. main's)
# on the same inputs with the same options give the same tiles holding the same points
# (bench/tiler_same_output.py), on each of the tiler's paths: in memory, out of core re-reading
# LAS (resident chunks and temporary files), out of core staging LAZ, implicit tiling.
#   bench/tiler_same_output.sh BASELINE_STIPPLE [POINTS]   (default 3000000)
#   STIPPLE=path/to/stipple overrides build/stipple
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
stipple="${STIPPLE:-$root/build/stipple}"
base="${1:?usage: bench/tiler_same_output.sh BASELINE_STIPPLE [POINTS]}"
points="${2:-3000000}"
work="${TMPDIR:-/tmp}/stipple_same_output"
mkdir -p "$work"
[[ -f "$work/gen_$points.las" ]] || "$stipple" generate -n "$points" -o "$work/gen_$points.las" >/dev/null
[[ -f "$work/gen_$points.laz" ]] || "$stipple" generate -n "$points" -o "$work/gen_$points.laz" >/dev/null
status=0
check() {  # label, input, options...
  local label=$1 input=$2
  shift 2
  "$base" tile "$input" -o "$work/a" --force "$@" >/dev/null
  "$stipple" tile "$input" -o "$work/b" --force "$@" >/dev/null
  printf '%-48s ' "$label:"
  python3 "$root/bench/tiler_same_output.py" "$work/a" "$work/b" | tail -n 1 || status=1
}
check "in memory, 2 threads" "$work/gen_$points.las" --threads 2
check "in memory, 1 thread" "$work/gen_$points.las" --threads 1
check "out of core LAS (64M), 2 threads" "$work/gen_$points.las" --threads 2 --max-memory 64M
check "out of core LAS (64M), 3 threads" "$work/gen_$points.las" --threads 3 --max-memory 64M
check "out of core LAZ (64M), 2 threads" "$work/gen_$points.laz" --threads 2 --max-memory 64M
check "implicit, out of core LAS (64M)" "$work/gen_$points.las" --threads 2 --max-memory 64M --implicit
rm -rf "$work/a" "$work/b"
exit $status
