#!/usr/bin/env bash
# The point pipeline's variants (naive, blend, EDL, CLOD) on a generated cloud at 1920x1080:
# GPU ms per render-graph pass (timestamp queries) and points/s, as a markdown table. Needs only
# the build and the WebGPU libraries (no input data).
#   bench/points.sh [STIPPLE] [POINTS] [BACKEND] [OUT_DIR]
set -euo pipefail
stipple=${1:-build/stipple}
points=${2:-100000000}
backend=${3:-wgpu}
out=${4:-bench/out}
mkdir -p "$out"
"$stipple" bench points --points "$points" --width 1920 --height 1080 --frames 10 \
  --backend "$backend" --json "$out/points_$backend.json"
