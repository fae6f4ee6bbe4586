#!/usr/bin/env bash
# run_fuzzer.sh FUZZER SECONDS CORPUS_DIR [SEED_DIR [EXTRA_SEED_DIR]]: runs a libFuzzer binary for a bounded time
# on a fresh working corpus seeded with the real files (LAS, LAZ; splats for fuzz_splats) when they exist, the generated
# seeds and the kept corpus (corpus/<fuzzer name>/).
set -euo pipefail
fuzzer=$1 seconds=$2 corpus=$3 seeds=${4:-} extra=${5:-}
rm -rf "$corpus" && mkdir -p "$corpus"
if [[ -n "$seeds" && -d "$seeds" ]]; then
  # Small seeds keep the run fast: the first 64 KiB of each file holds header, VLRs and points.
  # The splat reader's seeds are the splat files (../shared/data/splats), the others' LAS/LAZ.
  if [[ "$(basename "$fuzzer")" == fuzz_splats ]]; then
    pattern=(-path '*/splats/*' -a ! -name '*.md')
  else
    pattern=(-name '*.las' -o -name '*.laz')
  fi
  while IFS= read -r -d '' f; do
    head -c 65536 "$f" >"$corpus/$(basename "$f")"
  done < <(find "$seeds" -type f \( "${pattern[@]}" \) -print0)
else
  echo "seed corpus not found (../shared/data absent): fuzzing from an empty corpus"
fi
# Generated seeds (small 3D Tiles files; Potree and EPT files as *.seed) are copied whole.
if [[ -n "$extra" && -d "$extra" ]]; then
  while IFS= read -r -d '' f; do
    cp "$f" "$corpus/$(basename "$f")"
  done < <(find "$extra" -type f \( -name '*.pnts' -o -name '*.glb' -o -name '*.subtree' -o -name '*.pointlets' -o -name '*.page' -o -name '*.seed' -o -name '*.geojson' -o -name '*.json' \) -print0)
fi
# Inputs that once crashed or hung a target (regressions/<fuzzer name>/, one file each): each
# runs once first, so a fix that comes undone fails the test even if fuzzing misses it.
regressions="$(dirname "${BASH_SOURCE[0]}")/regressions/$(basename "$fuzzer")"
if [[ -d "$regressions" ]]; then
  "$fuzzer" -rss_limit_mb=2048 -timeout=20 "$regressions"/*
fi
# The kept, minimised corpus of the long campaigns (bench/fuzz.sh): corpus/<fuzzer name>/.
kept="$(dirname "${BASH_SOURCE[0]}")/corpus/$(basename "$fuzzer")"
if [[ -d "$kept" ]]; then
  cp "$kept"/* "$corpus"/ 2>/dev/null || true
fi
exec "$fuzzer" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=20 -print_final_stats=1 "$corpus"
