#!/usr/bin/env bash
# Issue 47's frame goal on the GPU machine: the virtualized path over the seed's camera path
# (1B generated points, B = 25M, 1920x1080, 600 frames, 4G host and GPU budgets), today's build
# and this one side by side on the same instance, from the repository root there. Needs
# .devpkg/stipple.tar.xz (this build) and .devpkg/stipple-old.tar.xz (the build to compare with),
# both packed here by bench/device-pack.sh:
#   bash bench/device-pack.sh /path/to/old/stipple stipple-old && bash bench/device-pack.sh
#   bench/virtual_frame_device.sh [POINTS] [FRAMES]          (default 1000000000 600)
# Runs, each in a fresh process with the cache reused: old (sequential, as the issue measured),
# new with the selection in the frame and --no-gpu-wait (--sync-selection: the old way's best
# mode), then new with the selection on its own thread (bench virtual's default since 4df96704):
# sequential, --no-gpu-wait, --pipelined. These fly the path by frame, so a build whose frames
# come faster flies it faster in wall time, and an async selection then lags the camera (fewer
# points drawn). The "paced" runs fly it by the clock (--duration) in the time the old build's
# run took, so every build sees the camera move at the same speed: new with the selection in the
# frame, then on its own thread in each frame mode. RUNS=... picks runs by name; the paced runs
# need the old run's JSON (DURATION=seconds overrides). Writes $OUT (or
# /tmp/virtual-frame-out)/NAME.json and prints each run's table and CPU phases. The input
# (/dev/shm, 26 GB at 1B) and the cache (/tmp/vf-cache, 20 GB) are kept for later calls on the
# same machine, so a call cut short repeats without redoing them; STEP=prepare stops once they
# exist (generating and sorting 1B points takes minutes: a call of its own keeps each under the
# 10-minute limit). PKGS, DATA and CACHE move the unpacked packages (/tmp), the input
# (/dev/shm) and the cache (/tmp/vf-cache).
set -uo pipefail
n=${1:-1000000000}
frames=${2:-600}
out=${OUT:-/tmp/virtual-frame-out}
pkgs=${PKGS:-/tmp}            # where the packages are unpacked
in=${DATA:-/dev/shm}/g$n.las
cache=${CACHE:-/tmp/vf-cache}
mkdir -p "$out" "$pkgs"
for p in stipple stipple-old; do
  [ -x $pkgs/$p-pkg/run ] || tar xf .devpkg/$p.tar.xz -C "$pkgs" || exit 1
done
if [ ! -s "$in" ]; then
  part=${in%.las}.part.las
  $pkgs/stipple-pkg/run generate -n "$n" --point-format 2 -o "$part" | tail -1 && mv "$part" "$in" || exit 1
fi
# Both builds read the same cache when its format did not change; otherwise each builds its own
# beside it (the cache's name carries its format).
for p in stipple-old stipple; do
  echo "== $p pointlets"
  (time $pkgs/$p-pkg/run pointlets "$in" --cache "$cache" --host-memory 40G) 2>&1 | tail -6
done
[ "${STEP:-}" = prepare ] && exit 0
common=(bench virtual "$in" --bucket 25000000 --host-memory 4G --gpu-memory 4G --cache "$cache")
names=(old new-sync-no-gpu-wait new new-no-gpu-wait new-pipelined paced-sync-no-gpu-wait paced
       paced-no-gpu-wait paced-pipelined)
for run in "old stipple-old" "new-sync-no-gpu-wait stipple --sync-selection --no-gpu-wait" \
           "new stipple" "new-no-gpu-wait stipple --no-gpu-wait" "new-pipelined stipple --pipelined" \
           "paced-sync-no-gpu-wait stipple --sync-selection --no-gpu-wait" "paced stipple" \
           "paced-no-gpu-wait stipple --no-gpu-wait" "paced-pipelined stipple --pipelined"; do
  set -- $run
  name=$1 pkg=$2
  [ -n "${RUNS:-}" ] && [[ " $RUNS " != *" $name "* ]] && continue
  shift 2
  if [[ $name == paced* ]]; then
    dur=${DURATION:-$(python3 -c 'import json,sys; print("%.3f" % (sum(json.load(open(sys.argv[1]))["runs"][0]["frame_wall_ms"]) / 1e3))' "$out/old.json" 2>/dev/null)}
    [ -n "$dur" ] || { echo "$name: no old.json to take the duration from (set DURATION)"; continue; }
    set -- "$@" --duration "$dur" --frames 1000000
  else
    set -- "$@" --frames "$frames"
  fi
  echo "== $name ($pkg $*)"
  $pkgs/$pkg-pkg/run "${common[@]}" "$@" --json "$out/$name.json" 2>&1 |
    grep -vE '^\s*$|frames \[|%\|' | tail -8
done
python3 - "$out" "${names[@]}" <<'PY'
import json, sys, pathlib
rows = []
for name in sys.argv[2:]:
    p = pathlib.Path(sys.argv[1]) / f"{name}.json"
    if not p.exists():
        continue
    r = json.loads(p.read_text())["runs"][0]
    f, c = r["fps"], r["cpu_ms_mean"]
    rows.append(f"| {name} | {f['average']:.1f} | {f['low_1pct']:.1f} | {f['gpu_average']:.1f} | "
                f"{c['selection']:.2f} | {c['store_update']:.2f} | {c['residency']:.2f} | "
                f"{c.get('render_queue', float('nan')):.2f} | {c.get('render_draw', float('nan')):.2f} | "
                f"{r['points_drawn_mean'] / 1e6:.2f} | {r.get('selections', float('nan'))} | "
                f"{r.get('async_selection_ms_mean', float('nan')):.2f} | {len(r['frame_wall_ms'])} | "
                f"{sum(r['frame_wall_ms']) / 1e3:.2f} |")
print("| build | FPS avg | 1% low | GPU FPS | selection ms | store update | residency | Queue | Draw | "
      "drawn M | selections | async selection ms | frames | seconds |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
print("\n".join(rows))
PY
