#!/usr/bin/env bash
# The web viewer on the GPU machine streaming tiled sets of the built-in scene along a flight,
# beside native stipple drawing the same tileset from the flight's last view (bench/RESULTS.md,
# "The page on a GPU"). From the repository root there, after bench/web_gpu_device.sh's setup
# (Chromium unpacked under /tmp by earlier calls, .devpkg/stipple.tar.xz, .devpkg/fonts, .gl,
# and .devpkg/proj/proj.db: Debian's PROJ database, which the tiler needs and the machine lacks).
#   bench/web_gpu_stream_device.sh POINTS...        e.g. 136000000 1000000000
# For each POINTS: `stipple generate` (LAS, point format 2: positions, classes, colours) and
# `stipple tile` into /tmp/data/tPOINTS (kept for later calls while the machine stays warm; the
# LAS is removed once tiled; with LAS_DIR, LAS_DIR/gPOINTS.las is tiled instead and kept), then
# the page opens /data/tPOINTS/tileset.json at 1280x720, streams it, flies FLIGHT steps (default
# 150; over FLIGHT_SECONDS of wall time where given, so that tiles stream in during the flight)
# down over it (bench/web_gpu.py --flight) and reports its CPU and GPU ms per frame and the
# points drawn; native Dawn and wgpu-native render the same tileset from the flight's
# last camera, 20 frames (--stats). QUERY_EXTRA adds to the page's query (e.g. '&max-sse=2'),
# NATIVE_EXTRA to native render's options (e.g. '--max-sse 2'), so both draw the same tiles.
# Writes $OUT (or /tmp/web-gpu-out)/stream-POINTS*.
set -uo pipefail
out=${OUT:-/tmp/web-gpu-out}
mkdir -p "$out" /tmp/data
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
[ -x /tmp/chromium-pkg/run ] || (cat /tmp/chromium-part-0?.xz | xz -d | tar x -C /tmp) || exit 1
[ -x /tmp/stipple-pkg/run ] || tar xf .devpkg/stipple.tar.xz -C /tmp || exit 1
export VK_ICD_FILENAMES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
printf '<?xml version="1.0"?><fontconfig><dir>%s</dir><cachedir>/tmp/fc</cachedir></fontconfig>' \
  "$PWD/.devpkg/fonts" >/tmp/fonts.conf
export FONTCONFIG_FILE=/tmp/fonts.conf
# The tiler turns the generated scene's CRS (EPSG:32633) to ECEF through PROJ, whose database the
# machine lacks: .devpkg/proj/proj.db (Debian's proj-data) carried.
[ -f .devpkg/proj/proj.db ] && export PROJ_DATA=$PWD/.devpkg/proj PROJ_LIB=$PWD/.devpkg/proj
flags="--use-angle=vulkan --enable-features=Vulkan,VulkanFromANGLE,DefaultANGLEVulkan --disable-vulkan-surface --disable-gpu-vsync --disable-frame-rate-limit"
stipple=/tmp/stipple-pkg/run
for n in "$@"; do
  set_dir=/tmp/data/t$n
  if [ ! -f "$set_dir/tileset.json" ]; then
    echo "== generating and tiling $n points"
    start=$(date +%s)
    # LAZ above 700M points: the LAS, the tiler's chunks and the tiles do not fit the 64 GB disk.
    # A LAS of these points already made (LAS_DIR/gN.las: bench/virtual_frame_device.sh's
    # /dev/shm input) is tiled as it is, and kept.
    if [ -f "${LAS_DIR:-/nonexistent}/g$n.las" ]; then
      $stipple tile "$LAS_DIR/g$n.las" -o "$set_dir" 2>&1 | tail -2
    else
      gen=/tmp/gen.las
      [ "$n" -gt 700000000 ] && gen=/tmp/gen.laz
      $stipple generate -n "$n" --point-format 2 -o $gen 2>&1 | tail -1
      $stipple tile $gen -o "$set_dir" 2>&1 | tail -2
      rm -f $gen
    fi
    echo "   $(( $(date +%s) - start )) s; $(du -sh "$set_dir" | cut -f1) of tiles; $(df -h /tmp | tail -1)"
  fi
  for web in ${WEB_DIRS:-.devpkg/web}; do
    echo "== page $(basename "$web"): $n points streamed"
    python3 bench/web_gpu.py --chromium /tmp/chromium-pkg/run --web "$web" --data /tmp/data \
      --flags "$flags" --flight "${FLIGHT:-150}" --flight-seconds "${FLIGHT_SECONDS:-0}" --timeout-s 400 \
      --query "url=/data/t$n/tileset.json&width=1280&height=720${QUERY_EXTRA:-}" --out "$out/stream-$n.json" >/dev/null
    python3 - "$out/stream-$n.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
s = r.get('stipple', {})
print(json.dumps({k: s.get(k) for k in ('renderer', 'adapter', 'tiles', 'points', 'ms', 'frameMs', 'error')}))
f = r.get('flight')
print(json.dumps({k: f.get(k) for k in ('steps', 'framesDrawn', 'seconds', 'fps', 'cpuMsMedian', 'cpuMsP90',
                                          'gpuMsMedian', 'gpuMsP90', 'gpuSamples', 'tilesLoadingMax',
                                          'pointsDrawnMean', 'pointsDrawnMax')}
                 if isinstance(f, dict) else f))
if isinstance(f, dict):
    last = f['last']
    open('/tmp/last-camera', 'w').write(','.join(repr(x) for x in last['position'] + last['target']))
    print('last stats:', json.dumps({k: f['stats'].get(k) for k in ('pointsDrawn', 'tilesDrawn', 'gpuMs', 'cpuMs')}))
PY
  done
  cam=$(cat /tmp/last-camera 2>/dev/null)
  for backend in dawn wgpu; do
    echo "== native $backend: $n points streamed, the flight's last view"
    $stipple render "$set_dir/tileset.json" --width 1280 --height 720 --backend $backend --frames 20 ${NATIVE_EXTRA:-} \
      ${cam:+--camera "$cam"} --stats "$out/stream-$n-$backend.json" -o "$out/stream-$n-$backend.png" 2>&1 | tail -2
    python3 -c "import json,sys;d=json.load(open(sys.argv[1]));print({k:d[k] for k in ('renderer','points','frame_gpu_ms_median','frame_wall_ms_median')})" \
      "$out/stream-$n-$backend.json"
  done
done 2>&1 | tee "$out/stream.txt"
