#!/usr/bin/env bash
# The web viewer beside native stipple on the GPU machine (bench/RESULTS.md, "The page on a
# GPU"), from the repository root there, with what bench/device-chromium-pack.sh and
# bench/device-pack.sh packed here carried over: the four chromium parts kept under /tmp by
# earlier calls (or chromium already unpacked there), .devpkg/stipple.tar.xz, each page build to
# measure as .devpkg/web-NAME/ (stipple.html, .mjs, .js, .wasm), .devpkg/fonts/ (a TrueType font:
# Chromium's font manager aborts without one) and the Vulkan loader's .gl/*.deb (device README).
#   bench/web_gpu_device.sh [QUERY...]     (default: the built-in scene at 1M and 136M points)
# Writes to $OUT (or /tmp/web-gpu-out): one JSON report a page and query, the Chromium logs, and
# native.txt (stipple render of the same scene and size, Dawn and wgpu-native, 20 frames, the
# renderer chosen as the page chooses it; once per scene size, NATIVE_RUNS times, after the pages).
# WEB_DIRS picks page builds; RETRY_ADAPTER=1 has the harness ask for an adapter again where the
# page's first request gets null; SHOTS=1 keeps the page's view (NAME-I.png) and the native images
# (native-BACKEND-POINTS.png) to compare.
set -uo pipefail
out=${OUT:-/tmp/web-gpu-out}
mkdir -p "$out"
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
[ -x /tmp/chromium-pkg/run ] || (cat /tmp/chromium-part-0?.xz | xz -d | tar x -C /tmp) || exit 1
[ -x /tmp/stipple-pkg/run ] || tar xf .devpkg/stipple.tar.xz -C /tmp || exit 1
export VK_ICD_FILENAMES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
printf '<?xml version="1.0"?><fontconfig><dir>%s</dir><cachedir>/tmp/fc</cachedir></fontconfig>' \
  "$PWD/.devpkg/fonts" >/tmp/fonts.conf
export FONTCONFIG_FILE=/tmp/fonts.conf
# WebGPU on the NVIDIA driver: ANGLE on Vulkan, no Vulkan surface (no display). With Chromium's
# Vulkan alone (the tests' flags) it offers SwiftShader.
# Frames not paced by a display (none here): rAF unthrottled, so a frame's time is the page's.
flags="--use-angle=vulkan --enable-features=Vulkan,VulkanFromANGLE,DefaultANGLEVulkan --disable-vulkan-surface --disable-gpu-vsync --disable-frame-rate-limit"
queries=("$@")
[ ${#queries[@]} -gt 0 ] || queries=("width=1280&height=720&scene-points=1000000"
                                    "width=1280&height=720&scene-points=136000000")
for web in ${WEB_DIRS:-.devpkg/web-*}; do
  name=$(basename "$web")
  i=0
  for q in "${queries[@]}"; do
    i=$((i + 1))
    echo "== $name: $q"
    python3 bench/web_gpu.py --chromium /tmp/chromium-pkg/run --web "$web" --flags "$flags" \
      ${RETRY_ADAPTER:+--retry-adapter} ${SHOTS:+--screenshot "$out/$name-$i.png"} --moves 30 --query "$q" --out "$out/$name-$i.json" --timeout-s 240 |
      grep -E '"(renderer|visibility|adapter|points|ms|loadMs|error|vendor|wallS|timeout|fps|framesDrawn|pageFrameMsMedian|cpuMsMedian|cpuMsP90|gpuMsMedian|gpuMsP90|gpuSamples)"'
  done
done
# Native once per scene size (the page's query options are the page's own), NATIVE_RUNS times.
points_of() { sed -n 's/.*scene-points=\([0-9]*\).*/\1/p' <<<"$1"; }
for pts in $(for q in "${queries[@]}"; do points_of "$q"; done | awk '!seen[$0]++'); do
  for backend in dawn wgpu; do
    for run in $(seq 1 "${NATIVE_RUNS:-1}"); do
      echo "== native $backend: $pts points (run $run)"
      png=/tmp/native.png
      [ -n "${SHOTS:-}" ] && png="$out/native-$backend-$pts.png"
      /tmp/stipple-pkg/run render --scene-points "${pts:-1000000}" --width 1280 --height 720 \
        --backend $backend --frames 20 --stats /tmp/native.json -o "$png" 2>&1 | tail -3
      python3 -c "import json,sys;d=json.load(open(sys.argv[1]));r={k:d[k] for k in ('renderer','points','frame_gpu_ms_median','frame_wall_ms_median')};r['passes']={n:round(p['gpu_ms_median'],3) for n,p in d.get('passes',{}).items()};print(r)" /tmp/native.json
    done
  done
done | tee "$out/native.txt"
# SHOTS=1: each page's view against the native images of the same query (bench/png_diff.py).
if [ -n "${SHOTS:-}" ]; then
  for web in ${WEB_DIRS:-.devpkg/web-*}; do
    name=$(basename "$web")
    for i in $(seq 1 ${#queries[@]}); do
      pts=$(points_of "${queries[$((i - 1))]}")
      for backend in dawn wgpu; do
        [ -f "$out/$name-$i.png" ] && [ -f "$out/native-$backend-$pts.png" ] &&
          python3 bench/png_diff.py "$out/$name-$i.png" "$out/native-$backend-$pts.png"
      done
    done
  done | tee "$out/diff.txt"
fi
