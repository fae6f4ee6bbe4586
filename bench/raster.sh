#!/usr/bin/env bash
# Compute rasterizer vs billboards on the built-in scene (seed 001, Tables 1-2): one process per
# size, so each starts with free GPU memory; tables on stdout, JSON per size in OUT_DIR.
#   bench/raster.sh [STIPPLE] [OUT_DIR] [SIZES...]
# Defaults: build/stipple, bench/out, 100M 500M 1B points at 2560x1140 with wgpu-native.
# The billboard variant needs 16 more bytes per point on the GPU; pass NO_BILLBOARD=1 to skip it.
set -euo pipefail
stipple=${1:-build/stipple}
out=${2:-bench/out}
shift $(( $# > 2 ? 2 : $# ))
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(100000000 500000000 1000000000)
mkdir -p "$out"
extra=()
[ "${NO_BILLBOARD:-0}" = 1 ] && extra+=(--no-billboard)
for n in "${sizes[@]}"; do
  "$stipple" bench raster --backend "${BACKEND:-wgpu}" --points "$n" --width 2560 --height 1140 \
    --frames 20 --warmup 3 "${extra[@]}" --json "$out/raster_$n.json" | tee "$out/raster_$n.txt"
done
