#!/usr/bin/env bash
# The measurements that wait for a GPU machine (bench/RESULTS.md, "Waiting for a GPU machine"),
# in one call: issue 46's splat frame and sort (old build, this build, this build with the
# block-rank sort of bench/pending/), and issue 47's 1B-point cache build (old build, this build,
# this build with its writes forced back to pwrite).
#
# Prepared on this machine (a checkout of the old commit built beside this one):
#   git worktree add /tmp/old c5549d57 && (cd /tmp/old && scripts/setup.sh)
#   bash bench/device-pack.sh /tmp/old/build/stipple stipple-old
#   bash bench/device-pack.sh
# On the device, carrying .gl and .devpkg (the device README's Vulkan loader packages first):
#   for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig; bash bench/pending_device.sh [splats|cache]
# Logs go to $OUT (or /tmp/pending) as splats.log and cache.log. The cache build needs the
# 1B-point input generated there (about 70 s, in /dev/shm) and four builds of 26-40 s: with the
# splats, about 8 minutes, so `splats` and `cache` can also run as two calls.
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out=${OUT:-/tmp/pending}
mkdir -p "$out"
what=${1:-all}
for p in stipple stipple-old; do
  [[ -x /tmp/$p-pkg/run ]] || tar xf "$root/.devpkg/$p.tar.xz" -C /tmp
done
old=/tmp/stipple-old-pkg/run new=/tmp/stipple-pkg/run
nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1

if [[ $what == all || $what == splats ]]; then
  # The shaders of this build, and the same with the pending sort: one binary, two shader dirs.
  rm -rf /tmp/pending-shaders && mkdir -p /tmp/pending-shaders/{new,rank}
  cp -r "$root/shaders" /tmp/pending-shaders/new/ && cp -r "$root/shaders" /tmp/pending-shaders/rank/
  patch -s -p1 -d /tmp/pending-shaders/rank <"$root/bench/pending/splat-sort-block-rank.patch"
  {
    for backend in dawn wgpu; do
      for view in far close; do
        # old, new, rank, new, old: the order balanced. On wgpu-native also each without naga's
        # bounds checks (STIPPLE_SHADER_CHECKS=off): the sort indexes workgroup arrays, which the
        # driver's robust buffer access does not cover, so naga clamps every such index (on
        # lavapipe the sort alone took 8-10 % less without them); Dawn ignores the switch.
        variants="old new rank new old"
        [[ $backend == wgpu ]] && variants="old new new-unchecked rank rank-unchecked new old"
        for v in $variants; do
          echo "== $v $backend $view"
          checks=  # empty: each shader as the build compiles it
          [[ $v == *-unchecked ]] && checks=off
          if [[ $v == old ]]; then
            "$old" bench splats --count 6000000 --sh 3 --size 1920x1080 --frames 60 \
              --backend $backend --rasterizer tiles --view $view
          else
            STIPPLE_SHADER_CHECKS=$checks STIPPLE_SHADER_DIR=/tmp/pending-shaders/${v%-unchecked}/shaders \
              "$new" bench splats --count 6000000 --sh 3 --size 1920x1080 --frames 60 \
              --backend $backend --rasterizer tiles --view $view
          fi
        done
      done
    done
  } 2>&1 | tee "$out/splats.log" | grep -E "^==|sort|frame|raster|bin"
fi

if [[ $what == all || $what == cache ]]; then
  # The new build with pwrite() instead of the mapped writes: a wrapper the bench calls like a
  # build.
  printf '#!/usr/bin/env bash\nSTIPPLE_CACHE_WRITE=pwrite exec %s "$@"\n' "$new" >/tmp/stipple-pwrite
  chmod +x /tmp/stipple-pwrite
  CACHE=/tmp/stipple-pointlets-cache bash "$root/bench/pointlets.sh" 1000000000 las 4G \
    "$old" "$new" /tmp/stipple-pwrite "$new" "$old" 2>&1 | tee "$out/cache.log"
fi
