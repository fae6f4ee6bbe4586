#!/usr/bin/env bash
# run_fuzzer.sh FUZZER SECONDS CORPUS_DIR [SEED_DIR [EXTRA_SEED_DIR]]: runs a libFuzzer binary for a bounded time
# on a fresh working corpus seeded with the real files (LAS, LAZ) when they exist.
set -euo pipefail
fuzzer=$1 seconds=$2 corpus=$3 seeds=${4:-} extra=${5:-}
rm -rf "$corpus" && mkdir -p "$corpus"
if [[ -n "$seeds" && -d "$seeds" ]]; then
  # Small seeds keep the run fast: the first 64 KiB of each file holds header, VLRs and points.
  while IFS= read -r -d '' f; do
    head -c 65536 "$f" >"$corpus/$(basename "$f")"
  done < <(find "$seeds" -type f \( -name '*.las' -o -name '*.laz' \) -print0)
else
  echo "seed corpus not found (../shared/data absent): fuzzing from an empty corpus"
fi
# Generated seeds (small 3D Tiles files; Potree and EPT files as *.seed) are copied whole.
if [[ -n "$extra" && -d "$extra" ]]; then
  while IFS= read -r -d '' f; do
    cp "$f" "$corpus/$(basename "$f")"
  done < <(find "$extra" -type f \( -name '*.pnts' -o -name '*.glb' -o -name '*.subtree' -o -name '*.pointlets' -o -name '*.page' -o -name '*.seed' -o -name '*.geojson' -o -name '*.json' \) -print0)
fi
exec "$fuzzer" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=20 -print_final_stats=1 "$corpus"
