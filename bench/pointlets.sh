#!/usr/bin/env bash
# The pointlet cache's build speed (issue 47: >= 40 M points/s on 16 cores at the default host
# budget) and its phases, for one or more builds of stipple on the same input in one call.
#   bench/pointlets.sh POINTS FORMAT MEMORY STIPPLE...
#     POINTS   generated input size (e.g. 1000000000)
#     FORMAT   las or laz (`stipple generate --point-format $POINT_FORMAT`, default 2: 26 bytes
#              a point as LAS; 7 is LAS 1.4's layered LAZ, where the build skips unused layers)
#     MEMORY   --host-memory of the build: 4G is what render and view give it on a machine with
#              32 GB or more (half their default budget, a quarter of RAM, at most 4G); 48G
#              keeps 1B points in one run (the earlier measurement's 40G run under two thirds)
#     STIPPLE  runners, e.g. /tmp/stipple-pkg/run (bench/device-pack.sh) or build/stipple
# The input goes to $WORK (default /dev/shm/stipple-pointlets: in RAM, as the 64 GB disk holds
# the 20 GB cache and the runs), the cache and its runs to $CACHE (default
# /tmp/stipple-pointlets-cache), emptied before each build. Prints each build's summary and,
# where the build has --stats, its phases (read, sort, merge, encode, write).
set -euo pipefail
points=${1:?POINTS}
format=${2:?FORMAT: las or laz}
memory=${3:?MEMORY, e.g. 4G}
shift 3
[[ $# -gt 0 ]] || { echo "give at least one stipple runner" >&2; exit 2; }
work=${WORK:-/dev/shm/stipple-pointlets}
cache=${CACHE:-/tmp/stipple-pointlets-cache}
mkdir -p "$work"
pf=${POINT_FORMAT:-2}
input="$work/g$points-f$pf.$format"
if [[ ! -f $input ]]; then
  "$1" generate -n "$points" --point-format "$pf" -o "$input" | tail -1
fi
echo "input: $input ($(du -h "$input" | cut -f1)), $(nproc) cores, --host-memory $memory"
for bin in "$@"; do
  rm -rf "$cache"
  mkdir -p "$cache"
  stats=()
  "$bin" pointlets --help | grep -q -- '--stats' && stats=(--stats)
  echo "== $bin"
  timer=()
  [[ -x /usr/bin/time ]] && timer=(/usr/bin/time -f "wall %e s, CPU %U+%S s, peak RSS %M KB")
  "${timer[@]}" "$bin" pointlets "$input" --cache "$cache" --host-memory "$memory" \
    "${stats[@]}" 2>&1 | grep -E 'built|cache build|wall|pointlets of' || true
done
rm -rf "$cache"
