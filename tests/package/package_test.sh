#!/usr/bin/env bash
# package_test.sh BUILD_DIR EXAMPLE_DIR WORK_DIR STIPPLE_BINARY
# Installs libstipple from BUILD_DIR into WORK_DIR/prefix, checks the installed library's
# symbols, configures and builds the example against that prefix alone, and runs it on a LAS
# file written by `stipple generate` (the example checks its own image and exits non-zero if
# the points or its pass are missing).
set -euo pipefail
build=$(cd "$1" && pwd) example=$2 work=$3 stipple=$4
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" >/dev/null
lib="$work/prefix/lib/libstipple.so"
for f in "$lib" "$work/prefix/lib/libstipple.a" "$work/prefix/lib/cmake/stipple/stippleConfig.cmake" \
  "$work/prefix/include/stipple/engine/engine.hpp" "$work/prefix/include/webgpu/webgpu.h"; do
  [[ -e "$f" ]] || { echo "not installed: $f"; exit 1; }
done
# The plugins are in the library (not in the command line).
symbols=$(nm -C --defined-only "$lib")
for p in 'stipple::pc::PointCloudPlugin::build' 'stipple::tiles3d::TilesetPlugin::build' \
  'stipple::viewer::ViewerPlugin::build' 'stipple::viewer::WindowPlugin::build' \
  'stipple::viewer::UiPlugin::build' 'stipple::viewer::CameraControllerPlugin::build' \
  'stipple::HeadlessTargetPlugin::build' 'stipple::RenderGraphPlugin::build'; do
  grep -qF "$p(stipple::Engine&)" <<<"$symbols" || { echo "libstipple.so lacks $p"; exit 1; }
done
echo "installed libstipple.so defines every plugin's build()"
# Only the installed prefix is searched: the build tree is not on any path.
cmake -S "$example" -B "$work/example-build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF >"$work/configure.log" || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/example-build" >"$work/build.log" || { cat "$work/build.log"; exit 1; }
# Neither the build tree's libraries nor the source tree's include roots are used.
if grep -qE -- "$build/libstipple|/src/[a-z0-9]+/include" "$work/example-build/build.ninja"; then
  echo "the example's build refers to the build or source tree"; exit 1
fi
"$stipple" generate -n 200000 -o "$work/scene.las" >/dev/null
for backend in wgpu dawn; do
  STIPPLE_BACKEND=$backend "$work/example-build/custom_pass" "$work/scene.las" "$work/custom_pass-$backend.png"
done

