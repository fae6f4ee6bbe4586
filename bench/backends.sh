#!/usr/bin/env bash
# Compares the two WebGPU implementations on the same renders: GPU ms of the point pass
# (timestamp queries) and wall ms per frame (submit + wait: CPU and driver overhead included).
#   bench/backends.sh [STIPPLE] [LAS_FILE] [SCENE_POINTS] [OUT_DIR]
set -euo pipefail
stipple=${1:-build/stipple}
las=${2:-../shared/data/las/autzen_trim.las}
scene_points=${3:-50000000}
out=${4:-bench/out}
mkdir -p "$out"
for backend in dawn wgpu; do
  "$stipple" render "$las" --frames 30 --width 1920 --height 1080 --backend "$backend" \
    --stats "$out/file_$backend.json" -o "$out/file_$backend.png"
  "$stipple" render --scene-points "$scene_points" --frames 30 --width 1920 --height 1080 \
    --backend "$backend" --stats "$out/scene_$backend.json" -o "$out/scene_$backend.png"
done
python3 - "$out" <<'PY'
import json, sys
out = sys.argv[1]
print("| input | backend | points | GPU ms (points pass) | wall ms / frame |")
print("|---|---|---:|---:|---:|")
for case in ("file", "scene"):
    for backend in ("dawn", "wgpu"):
        j = json.load(open(f"{out}/{case}_{backend}.json"))
        print(f"| {case} | {backend} | {j['points']:,} | {j['passes']['points']['gpu_ms_median']:.3f} "
              f"| {j['frame_wall_ms_median']:.3f} |")
PY
