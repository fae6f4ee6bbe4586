#include "stipple/app/scene.hpp"

#include <utility>

#include "stipple/core/error.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"

namespace stipple::app {

bool is_tileset_scene(const SceneOptions& options) {
  return options.inputs.size() == 1 && tiles3d::is_tileset_input(options.inputs[0]);
}

void add_scene_plugin(Engine& engine, const SceneOptions& options) {
  const bool compute = options.renderer == Renderer::Compute;
  if (is_tileset_scene(options)) {
    // 3D Tiles: streamed frame by frame with the camera (out of core).
    if (compute) fail("--renderer compute does not draw tilesets yet");
    tiles3d::TilesetPlugin tiles;
    tiles.uri = options.inputs[0];
    tiles.streamer.traversal.max_sse = options.max_sse;
    tiles.streamer.traversal.memory_budget = options.memory_mb << 20;
    tiles.render = options.render;
    engine.add_plugin(std::move(tiles));
    return;
  }
  pc::PointCloudPlugin points;
  points.inputs.files.assign(options.inputs.begin(), options.inputs.end());
  points.inputs.scene.point_count = options.scene_points;
  points.inputs.scene.seed = options.seed;
  points.inputs.chunk_points = options.chunk_points;
  points.settings.render = options.render;
  points.settings.budget = options.budget;
  points.settings.compute = compute;
  points.settings.hqs = options.hqs;
  engine.add_plugin(std::move(points));
}

void add_scene_options(CLI::App* cmd, SceneOptions& options) {
  cmd->add_option_function<std::string>(
         "--renderer",
         [&options](const std::string& v) {
           options.renderer = v == "compute" ? Renderer::Compute : Renderer::Billboard;
         },
         "billboard (the point pipeline) or compute (compute rasterizer, 1-pixel points)")
      ->check(CLI::IsMember({"billboard", "compute"}))
      ->default_str("billboard");
  cmd->add_flag("--hqs", options.hqs,
                "Compute renderer: high-quality shading (average points within 1% of the "
                "nearest depth)");
  cmd->add_option("--max-sse", options.max_sse,
                  "Tilesets: refine tiles while their screen-space error exceeds this (pixels)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--memory-mb", options.memory_mb,
                  "Tilesets: resident tile memory budget in MiB (least recently used evicted)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 20))
      ->capture_default_str();
}

}  // namespace stipple::app
