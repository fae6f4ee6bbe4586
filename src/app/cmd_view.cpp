// `stipple view`: an interactive window over LAS/LAZ/COPC files (or the built-in scene),
// composed from engine plugins with the render world on its own thread.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "app/camera_controller.hpp"
#include "app/commands.hpp"
#include "app/point_cloud_plugin.hpp"
#include "app/point_options.hpp"
#include "app/tileset_plugin.hpp"
#include "app/ui_plugin.hpp"
#include "app/viewer_plugin.hpp"
#include "app/window_plugins.hpp"
#include "core/error.hpp"
#include "engine/plugins.hpp"
#include "engine/render_plugins.hpp"
#include "io/fetch.hpp"
#include "math/camera.hpp"
#include "pointcloud/point_renderer.hpp"
#include "tiles3d/render_load.hpp"

namespace stipple::app {
namespace {

struct ViewArgs {
  std::vector<std::string> inputs;
  uint32_t width = 1280, height = 720;
  std::string backend;
  pc::PointRenderSettings settings;
  bool compute = false;
  uint64_t budget = 0;
  uint64_t scene_points = 1'000'000;
  uint64_t frames = 0;
  std::string screenshot;
  bool no_vsync = false;
  bool no_ui = false;
  bool single_thread = false;
  double max_sse = 16.0;     // tilesets: refine while a tile's screen-space error exceeds this
  uint64_t memory_mb = 512;  // tilesets: resident tile memory budget
};

void run_view(const ViewArgs& args) {
  Engine engine;
  engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{});
  if (!args.single_thread) engine.add_plugin(PipelinedRenderingPlugin{});
  GpuPlugin gpu;
  gpu.options.backend = args.backend;
  engine.add_plugin(std::move(gpu));
  engine.add_plugin(RenderGraphPlugin{});
  const bool tileset = args.inputs.size() == 1 && tiles3d::is_tileset_input(args.inputs[0]);
  if (tileset) {
    // 3D Tiles: streamed while the camera moves (out of core).
    if (args.compute)
      fail("--compute does not draw tilesets yet (streamed tiles use the point pipeline)");
    TilesetPlugin tiles;
    tiles.uri = args.inputs[0];
    tiles.streamer.traversal.max_sse = args.max_sse;
    tiles.streamer.traversal.memory_budget = args.memory_mb << 20;
    tiles.width = args.width;
    tiles.height = args.height;
    tiles.render = args.settings;
    engine.add_plugin(std::move(tiles));
  } else {
    PointCloudPlugin points;
    points.inputs.files.assign(args.inputs.begin(), args.inputs.end());
    points.inputs.scene.point_count = args.scene_points;
    points.inputs.chunk_points = 1 << 16;  // a finer point budget
    points.settings.render = args.settings;
    points.settings.compute = args.compute;
    points.settings.budget = args.budget;
    engine.add_plugin(std::move(points));
  }
  platform::WindowOptions window;
  window.title = "stipple";
  window.width = args.width;
  window.height = args.height;
  engine.add_plugin(WindowPlugin{window});
  engine.add_plugin(InputPlugin{});
  engine.add_plugin(SurfaceTargetPlugin{!args.no_vsync});
  if (!args.no_ui) engine.add_plugin(UiPlugin{});
  engine.add_plugin(CameraControllerPlugin{});
  engine.add_plugin(ViewerPlugin{args.frames, args.screenshot});

  // The scene: a camera framing the data, and a point size that closes the gaps from there.
  Registry& main = engine.main();
  const auto& scene = main.resource<SceneInfo>();
  glm::uvec2 size = main.resource<WindowState>().framebuffer_size;
  double aspect = size.y > 0 ? double(size.x) / size.y : double(args.width) / args.height;
  Camera camera = frame_box(scene.world_bounds, aspect);
  main.emplace<Camera>(main.create(), camera);
  auto& settings = main.resource<PointDrawSettings>();
  main.view<PointCloudData>().each([&](const PointCloudData& data) {
    if (settings.render.point_size <= 0)
      settings.render.point_size = pc::auto_point_size(*data.cloud, camera, std::max(size.y, 1u));
  });
  // Streamed tiles arrive later: a size that suits the default screen-space error.
  if (tileset && settings.render.point_size <= 0) settings.render.point_size = 2.0f;
  engine.run();
  engine.shutdown();
}

}  // namespace

void add_view_command(CLI::App& cli) {
  auto args = std::make_shared<ViewArgs>();
  auto* cmd = cli.add_subcommand(
      "view",
      "Open a window over point clouds (LAS/LAZ/COPC); with no input, the built-in scene.\n"
      "Orbit: left drag rotate, right/middle drag pan, wheel zoom to the cursor. Fly (F/Tab): "
      "WASD, Q/E, shift, drag to look. Double click: focus. P screenshot, V vsync, F1 panel, "
      "Esc quit");
  cmd->add_option("inputs", args->inputs,
                  "Input files (.las, .laz, .copc.laz), or one 3D Tiles tileset.json path or URL "
                  "(streamed while the camera moves)")
      ->check([](const std::string& in) {
        return io::is_url(in) ? std::string() : CLI::ExistingFile(in);
      });
  cmd->add_option("--width", args->width, "Window width")
      ->check(CLI::Range(64u, 16384u))
      ->capture_default_str();
  cmd->add_option("--height", args->height, "Window height")
      ->check(CLI::Range(64u, 16384u))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "WebGPU implementation: dawn or wgpu (default: $STIPPLE_BACKEND, else wgpu)")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  add_point_render_options(cmd, args->settings);
  cmd->add_flag("--compute", args->compute,
                "Draw with the compute rasterizer (1-pixel points, billions of them)");
  cmd->add_option("--budget", args->budget,
                  "Draw at most this many points, nearest chunks first (0: all)")
      ->capture_default_str();
  cmd->add_option("--scene-points", args->scene_points, "Built-in scene: number of points")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_option("--frames", args->frames, "Exit after this many frames (0: when closed)")
      ->capture_default_str();
  cmd->add_option("--screenshot", args->screenshot,
                  "With --frames: write the last frame (as shown, panel included) to this PNG");
  cmd->add_flag("--no-vsync", args->no_vsync, "Start with vsync off (Immediate or Mailbox)");
  cmd->add_flag("--no-ui", args->no_ui, "Leave out the ImGui panel (UiPlugin)");
  add_tileset_options(cmd, args->max_sse, args->memory_mb);
  cmd->add_flag("--single-thread", args->single_thread,
                "Run the render world on the main thread (no PipelinedRenderingPlugin)");
  cmd->callback([args] { run_view(*args); });
}

}  // namespace stipple::app
