#pragma once
// The headless engine the tileset GPU tests stream with, and the loop that lets a view load.
#include <functional>
#include <string>
#include <utility>

#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"

namespace stipple::test {

// Time (a fixed step when fixed_delta > 0), transform, camera, pipelined rendering when asked,
// the GPU on `backend`, the render graph, `tiles`, and a headless target of the tiles' viewport.
inline void add_tileset_engine_plugins(Engine& engine, const std::string& backend, bool pipelined,
                                       tiles3d::TilesetPlugin tiles, double fixed_delta) {
  TimePlugin time;
  time.fixed_delta = fixed_delta;
  engine.add_plugins(time, TransformPlugin{}, CameraPlugin{});
  if (pipelined) engine.add_plugin(PipelinedRenderingPlugin{});
  GpuPlugin gpu;
  gpu.options.backend = backend;
  engine.add_plugin(std::move(gpu));
  engine.add_plugin(RenderGraphPlugin{});
  const uint32_t width = tiles.width, height = tiles.height;
  engine.add_plugin(std::move(tiles));
  engine.add_plugin(HeadlessTargetPlugin{width, height, "", 0});
}

// Updates until the streamer is idle (at most 500 frames), waiting for loads in between;
// `each_frame` runs after every update. Returns whether it went idle.
inline bool update_until_idle(Engine& engine, const std::function<void()>& each_frame = {}) {
  Registry& main = engine.main();
  for (int i = 0; i < 500; ++i) {
    engine.update();
    if (each_frame) each_frame();
    if (main.resource<tiles3d::TilesetStats>().idle) return true;
    main.resource<tiles3d::TilesetStream>().streamer->wait_for_progress();
  }
  return false;
}

}  // namespace stipple::test
