// `stipple view`: an interactive window over LAS/LAZ/COPC files (or the built-in scene),
// composed from engine plugins with the render world on its own thread.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "stipple/app/commands.hpp"
#include "stipple/app/point_options.hpp"
#include "stipple/app/scene.hpp"
#include "stipple/core/error.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/geojson.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/viewer/camera_controller.hpp"
#include "stipple/viewer/script.hpp"
#include "stipple/viewer/tools_plugin.hpp"
#include "stipple/viewer/ui_plugin.hpp"
#include "stipple/viewer/viewer_plugin.hpp"
#include "stipple/viewer/window_plugins.hpp"

namespace stipple::app {
namespace {

struct ViewArgs {
  SceneOptions scene;  // inputs, point settings, renderer, budgets
  uint32_t width = 1280, height = 720;
  std::string backend;
  uint64_t frames = 0;
  std::string screenshot;
  bool no_vsync = false;
  bool no_ui = false;
  bool single_thread = false;
  std::string camera;
  double fov = 50.0;
  std::string script;
  std::string measurements, measurements_out;
  uint64_t progressive_points = 1 << 18;
};

void run_view(const ViewArgs& args) {
  // Read before anything opens: a bad script is an error, not a window.
  viewer::InputScript script;
  if (!args.script.empty()) script = viewer::read_input_script(args.script);
  if (!args.measurements.empty()) (void)io::read_geojson(args.measurements);
  if (!args.measurements_out.empty()) {
    const std::filesystem::path out(args.measurements_out);
    const std::filesystem::path folder = out.parent_path().empty() ? "." : out.parent_path();
    if (!std::filesystem::is_directory(folder))
      fail("{}: the folder {} does not exist", out.string(), folder.string());
  }
  Engine engine;
  add_engine_core(engine, {args.backend, !args.single_thread, false, ""});
  SceneOptions options = args.scene;
  options.progressive_points = args.progressive_points;
  options.async_selection = true;  // a frame never waits for the selection of a large cloud
  options.keep_extras = true;      // the panel can turn GPS-time and point-source filters on
  options.chunk_points = 1 << 16;  // a finer point budget
  ScenePlan plan = plan_scene(options, *engine.render().resource<GpuContext>());
  std::printf("renderer: %s (%s)\n", renderer_name(plan.options.renderer),
              plan.renderer_reason.c_str());
  add_scene_plugin(engine, plan);
  platform::WindowOptions window;
  window.title = "stipple";
  window.width = args.width;
  window.height = args.height;
  engine.add_plugin(viewer::WindowPlugin{window});
  // Scripted events join the window's before InputState is built from them.
  if (!args.script.empty()) engine.add_plugin(viewer::ScriptedInputPlugin{script});
  engine.add_plugin(viewer::InputPlugin{});
  engine.add_plugin(viewer::SurfaceTargetPlugin{!args.no_vsync});
  if (!args.no_ui) engine.add_plugin(viewer::UiPlugin{});
  engine.add_plugin(viewer::CameraControllerPlugin{});
  engine.add_plugin(viewer::ViewerPlugin{args.frames, args.screenshot});
  // After the viewer: its panel section follows the viewer's in the same window.
  engine.add_plugin(viewer::ToolsPlugin{args.measurements, args.measurements_out});

  // The scene: a camera framing the data, and a point size that closes the gaps from there.
  Registry& main = engine.main();
  glm::uvec2 size = main.resource<viewer::WindowState>().framebuffer_size;
  if (size.x == 0 || size.y == 0) size = {args.width, args.height};
  SceneView view;
  view.width = size.x;
  view.height = std::max(size.y, 1u);
  view.camera = args.camera;
  view.fov = args.fov;
  place_camera(engine, plan, view, false);
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
  cmd->add_option(
         "inputs", args->scene.inputs,
         "Input files (.las, .laz, .copc.laz) and folders of LAS/LAZ tiles (one cloud), or one "
         "3D Tiles tileset.json, Potree "
         "metadata.json or cloud.js, or EPT ept.json path or URL "
         "(streamed while the camera moves); Gaussian splat files (.ply, .splat, .spz, .ksplat, "
         ".sog) drawn with them or alone")
      ->check([](const std::string& in) {
        return io::is_url(in) ? std::string() : CLI::ExistingPath(in);
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
  add_point_render_options(cmd, args->scene.render);
  cmd->add_option("--scene-points", args->scene.scene_points, "Built-in scene: number of points")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_option("--frames", args->frames, "Exit after this many frames (0: when closed)")
      ->capture_default_str();
  cmd->add_option("--screenshot", args->screenshot,
                  "With --frames: write the last frame (as shown, panel included) to this PNG");
  cmd->add_flag("--no-vsync", args->no_vsync, "Start with vsync off (Immediate or Mailbox)");
  cmd->add_flag("--no-ui", args->no_ui, "Leave out the ImGui panel (UiPlugin)");
  add_scene_options(cmd, args->scene);
  cmd->add_option("--camera", args->camera,
                  "Start camera 'eye_x,eye_y,eye_z,target_x,target_y,target_z' in the data's "
                  "coordinates (Z up); default frames the data");
  cmd->add_option("--fov", args->fov, "Vertical field of view in degrees")
      ->check(CLI::Range(1.0, 170.0))
      ->capture_default_str();
  cmd->add_option("--script", args->script,
                  "Replay scripted input (JSON: at frame N move the cursor, press or release "
                  "buttons and keys, scroll; see docs/viewer-and-tools.md)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--measurements", args->measurements,
                  "Load measurements and annotations from GeoJSON (source CRS)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--measurements-out", args->measurements_out,
                  "Write the measurements (and the last inspected point) as GeoJSON on exit");
  cmd->add_option("--progressive-points", args->progressive_points,
                  "Virtualized LAS/LAZ whose pointlet cache has to be built: draw about this "
                  "many points read across the input at once while the cache builds in the "
                  "background, then the cache (keeping the camera); 0: wait for the cache")
      ->capture_default_str();
  cmd->add_flag("--single-thread", args->single_thread,
                "Run the render world on the main thread (no PipelinedRenderingPlugin)");
  cmd->callback([args] { run_view(*args); });
}

}  // namespace stipple::app
