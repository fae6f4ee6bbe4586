#!/usr/bin/env bash
# A splat tileset streamed along the seed's camera path (issue 46's goal: 100M splats from the
# tiler, a 6M-splat budget, >= 60 FPS average): `stipple generate` N splats (.ply, streamed),
# `stipple tile` them (SPZ glb, merged inner tiles), then `stipple bench stream` on the tileset
# (tiles3d::SplatTilesetPlugin: traversal, SSE, budgets; the drawn tiles' splats composed into one
# set and sorted together each frame). Frames do not wait for loads, as in a viewer.
#   bench/splat_stream.sh [--splats N] [--sh D] [--budget B] [--memory-mb M] [--frames F]
#                         [--backend wgpu|dawn] [--step tile|bench|all] [--json FILE]
#                         [--max-sse S]   (bench stream's, 16 by default: the flight then stays
#                                          on coarse tiles; 1 refines to millions of splats)
# Defaults: 100M splats, SH degree 0, a 6M-splat budget, 8192 MiB resident, 600 frames at
# 1920x1080. The generated PLY and the tileset are kept in $TMPDIR/stipple_bench_splat_stream
# and reused, so --step tile and --step bench can run as separate commands (each under a
# device's per-command limit). With the packed binary: STIPPLE=/tmp/stipple-pkg/run.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
stipple="${STIPPLE:-$root/build/stipple}"
work="${TMPDIR:-/tmp}/stipple_bench_splat_stream"
splats=100000000 sh=0 budget=6000000 memory=8192 frames=600 backend=wgpu step=all json=""
max_sse=16
while [[ $# -gt 0 ]]; do
  case "$1" in
    --splats) splats="$2"; shift 2 ;;
    --sh) sh="$2"; shift 2 ;;
    --budget) budget="$2"; shift 2 ;;
    --memory-mb) memory="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --backend) backend="$2"; shift 2 ;;
    --step) step="$2"; shift 2 ;;
    --json) json="$2"; shift 2 ;;
    --max-sse) max_sse="$2"; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$work"
# /usr/bin/time where the machine has it (a bare Ubuntu image does not).
timer() { if [[ -x /usr/bin/time ]]; then /usr/bin/time -f "$1: %e s, RSS %M KB" "${@:2}"; else
  local t0=$SECONDS; "${@:2}"; echo "$1: $((SECONDS - t0)) s"; fi; }
ply="$work/gen_${splats}_sh${sh}.ply"
tiles="$work/tiles_${splats}_sh${sh}"
if [[ "$step" == tile || "$step" == all ]]; then
  if [[ ! -f "$tiles/tileset.json" ]]; then
    [[ -f "$ply" ]] || timer generate "$stipple" generate -n "$splats" --sh-degree "$sh" -o "$ply"
    rm -rf "$tiles"
    timer tile "$stipple" tile "$ply" -o "$tiles" --max-memory 16G
    rm -f "$ply"  # the tileset is what the flight reads; the disk is better spent on it
  fi
  du -sh "$tiles"
fi
if [[ "$step" == bench || "$step" == all ]]; then
  json_args=()
  [[ -n "$json" ]] && json_args=(--json "$json")
  "$stipple" bench stream "$tiles/tileset.json" --renderer billboard --width 1920 --height 1080 \
    --frames "$frames" --memory-mb "$memory" --splat-budget "$budget" --backend "$backend" \
    --max-sse "$max_sse" \
    "${json_args[@]}"
fi
