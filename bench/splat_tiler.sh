#!/usr/bin/env bash
# The splat tiler's output size against the SPZ of the same splats (issue 46's goal: <= 1.1x),
# its time and peak memory. For each input: `stipple tile` (default options) and the same splats
# as one tile (--max-leaf-splats above the count: one glb around one gzipped SPZ of every splat,
# in the same Morton order), both `du -sb`; the input file's own size beside them.
#   bench/splat_tiler.sh [--max-memory M] [--threads T] [FILE... | N...]
# An argument that is a number N generates N splats of the procedural scene (stipple generate,
# .ply, streamed); with no argument: every splat file of ../shared/data/splats plus 1M and 10M.
# CPU only: runs on any machine, the packed binary included (STIPPLE=.../stipple).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
stipple="${STIPPLE:-$root/build/stipple}"
work="${TMPDIR:-/tmp}/stipple_bench_splat_tiler"
mkdir -p "$work"
memory=2G
threads=0
args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --max-memory) memory="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
if [[ ${#args[@]} -eq 0 ]]; then
  data="$root/../shared/data/splats"
  for f in "$data"/playcanvas-engine/biker.spz "$data"/playcanvas-engine/guitar.compressed.ply \
           "$data"/v3dg/donut_fused.ply; do
    [[ -f "$f" ]] && args+=("$f")
  done
  args+=(1000000 10000000)
fi
thread_args=()
[[ "$threads" != 0 ]] && thread_args=(--threads "$threads")
echo "| input | splats | input bytes | one-tile SPZ bytes | tiled bytes | tiled / SPZ | tiles | inner splats | tile s | peak RSS MB |"
echo "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|"
for in in "${args[@]}"; do
  if [[ "$in" =~ ^[0-9]+$ ]]; then
    gen="$work/gen_${in}.ply"
    [[ -f "$gen" ]] || "$stipple" generate -n "$in" -o "$gen" >/dev/null
    in="$gen"
  fi
  out="$work/tiled" one="$work/one"
  rm -rf "$out" "$one"
  log=$( { /usr/bin/time -f "RSS %M" "$stipple" tile "$in" -o "$out" --max-memory "$memory" \
           "${thread_args[@]}" 2>&1 | grep -v '\[info\]'; } 2>&1 )
  "$stipple" tile "$in" -o "$one" --max-leaf-splats 1000000000 --max-memory "$memory" \
    "${thread_args[@]}" >/dev/null 2>&1
  tiled=$(du -sb "$out" | cut -f1)
  single=$(du -sb "$one/tiles" | cut -f1)
  python3 - "$in" "$tiled" "$single" "$log" <<'PY'
import os, re, sys
path, tiled, single, log = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
m = re.search(r"tiled (\d+) splats .*into (\d+) tiles .*; (\d+) merged splats.* in ([\d.]+) s", log)
rss = re.search(r"RSS (\d+)", log)
print(f"| {os.path.basename(path)} | {m.group(1)} | {os.path.getsize(path)} | {single} | {tiled} | "
      f"{tiled / single:.3f} | {m.group(2)} | {m.group(3)} | {m.group(4)} | "
      f"{int(rss.group(1)) / 1024:.0f} |")
PY
done
rm -rf "$work/tiled" "$work/one"
