#!/usr/bin/env bash
# bench/web_vs_potree.mjs on the GPU machine (bench/RESULTS.md, "The page against potree-core"):
# stipple's page and the potree-core page (bench/web_vs_potree.html) in the carried Chromium, the
# flags of bench/web_gpu_device.sh (WebGPU and WebGL on the NVIDIA driver through ANGLE on Vulkan)
# and --disable-gpu-vsync --disable-frame-rate-limit, each page timed by bench/web_vs_potree.js
# (bench/web_gpu.py --bench K) at each budget, one page after the other. From the repository root
# there, with what bench/web_gpu_device.sh needs carried over (the chromium parts under /tmp from
# earlier calls, or chromium already unpacked there; .devpkg/fonts/, .gl/*.deb; the page build as
# .devpkg/web-NAME/: a build with the page's ?budget= and ?camera=) and the cloud and npm files
# that `node bench/web_vs_potree.mjs --pack .devpkg/vs-potree` writes here:
#   bench/web_vs_potree_device.sh [FRAMES]      (default 60)
# WEB_DIR picks the page build (default: the first .devpkg/web-*), PACK the packed folder (default
# .devpkg/vs-potree). A cloud too large to carry: pack it here from a generated LAS
# (`stipple generate -n N --point-format 2 -o g.las`, then `web_vs_potree.mjs --input g.las --pack
# DIR`), remove DIR/cloud, and run with GENERATE=N: the same LAS is generated there (the generator
# is deterministic) and converted by the carried writer (.devpkg/write_potree.tar.xz,
# `bench/device-pack.sh build/tests/stipple_write_potree write_potree`). Writes to $OUT (or /tmp/web-vs-potree-out): a JSON report a page and
# budget, the Chromium logs, and table.md (a row per budget, as bench/web_vs_potree.mjs prints).
set -uo pipefail
out=${OUT:-/tmp/web-vs-potree-out}
frames=${1:-60}
pack=${PACK:-.devpkg/vs-potree}
web=${WEB_DIR:-$(ls -d .devpkg/web-* | head -1)}
mkdir -p "$out"
for f in .gl/*.deb; do dpkg -x "$f" /; done
ldconfig
[ -x /tmp/chromium-pkg/run ] || (cat /tmp/chromium-part-0?.xz | xz -d | tar x -C /tmp) || exit 1
export VK_ICD_FILENAMES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -n "${GENERATE:-}" ] && [ ! -f "$pack/cloud/metadata.json" ]; then
  [ -x /tmp/stipple-pkg/run ] || tar xf .devpkg/stipple.tar.xz -C /tmp || exit 1
  [ -x /tmp/write_potree-pkg/run ] || tar xf .devpkg/write_potree.tar.xz -C /tmp || exit 1
  /tmp/stipple-pkg/run generate -n "$GENERATE" --point-format 2 -o /tmp/vs-potree.las | tail -1
  /tmp/write_potree-pkg/run "$pack/cloud" /tmp/vs-potree.las 10000 3 || exit 1
  rm -f /tmp/vs-potree.las
fi
printf '<?xml version="1.0"?><fontconfig><dir>%s</dir><cachedir>/tmp/fc</cachedir></fontconfig>' \
  "$PWD/.devpkg/fonts" >/tmp/fonts.conf
export FONTCONFIG_FILE=/tmp/fonts.conf
flags="--use-angle=vulkan --enable-features=Vulkan,VulkanFromANGLE,DefaultANGLEVulkan --disable-vulkan-surface"
flags="$flags --disable-gpu-vsync --disable-frame-rate-limit"
while IFS=$'\t' read -r budget query; do
  for page in stipple potree; do
    echo "== $page, budget $budget"
    extra="frames=3"
    [ $page = potree ] && extra="min-node-pixel-size=0"
    python3 bench/web_gpu.py --chromium /tmp/chromium-pkg/run --web "$web" --data "$pack" \
      --modules "$pack/modules" --page $page --bench "$frames" --flags "$flags" --window 1280x720 \
      --query "$query&$extra" --out "$out/$page-$budget.json" --timeout-s 300 </dev/null |
      grep -E '"(medianMs|p90Ms|sustainedMs|litFraction|framesDrawn|pointsDrawn|gpuMsMedian|cpuMsMedian|renderer|vendor|webgl|error|timeout|wallS)"'
  done
done <"$pack/queries.txt"
python3 - "$out" "$pack/queries.txt" <<'PY' | tee "$out/table.md"
import json, os, sys
out, queries = sys.argv[1], sys.argv[2]
print('| budget | points drawn: stipple / potree-core | stipple: frame interval median / p90 (ms) | '
      'potree-core: frame interval median / p90 (ms) | stipple: sustained frame (ms) | '
      'potree-core: sustained frame (ms) | stipple / potree-core, sustained | stipple / potree-core, interval medians | '
      'stipple: GPU ms (median) |')
print('|---:|---:|---:|---:|---:|---:|---:|---:|---:|')
for line in open(queries):
    budget = line.split('\t')[0]
    r = {}
    for page in ('stipple', 'potree'):
        try:
            r[page] = json.load(open(os.path.join(out, f'{page}-{budget}.json'))).get('bench')
        except (OSError, ValueError):
            r[page] = None
    s, p = r['stipple'], r['potree']
    if not isinstance(s, dict) or not isinstance(p, dict):
        print(f'| {budget} | (no result: see {out}) |')
        continue
    print(f"| {int(budget):,} | {s['pointsDrawn']:,} / {p['pointsDrawn']:,} | {s['medianMs']} / {s['p90Ms']} | "
          f"{p['medianMs']} / {p['p90Ms']} | {s['sustainedMs']} | {p['sustainedMs']} | "
          f"{s['sustainedMs'] / p['sustainedMs']:.2f} | {s['medianMs'] / p['medianMs']:.2f} | {s.get('gpuMsMedian')} |")
PY
