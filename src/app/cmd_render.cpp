// `stipple render`: headless rendering of LAS/LAZ/COPC files (or the built-in scene) to PNG,
// composed from engine plugins.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/commands.hpp"
#include "app/point_cloud_plugin.hpp"
#include "app/point_options.hpp"
#include "app/tileset_plugin.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "engine/plugins.hpp"
#include "engine/render_plugins.hpp"
#include "io/fetch.hpp"
#include "math/camera.hpp"
#include "pointcloud/compute_raster.hpp"
#include "pointcloud/point_cloud.hpp"
#include "pointcloud/point_renderer.hpp"
#include "renderer/gpu.hpp"
#include "tiles3d/render_load.hpp"

namespace stipple::app {
namespace {

struct RenderArgs {
  std::vector<std::string> inputs;
  std::string output = "stipple.png";
  uint32_t width = 1280, height = 720;
  std::string camera;
  double azimuth = 30.0, elevation = 40.0, fov = 50.0;
  std::string backend;
  pc::PointRenderSettings settings;
  uint64_t scene_points = 1'000'000;
  uint32_t seed = 1;
  uint32_t frames = 1;
  std::string stats;
  std::string dump_graph;
  bool pipelined = false;
  std::string renderer = "billboard";
  bool hqs = false;
  double max_sse = 16.0;
  uint64_t memory_mb = 512;
  uint64_t max_frames = 10000;
};

// `render` is a plugin list: the engine's core plugins, the device and frame graph, the point
// cloud, and an offscreen target that writes the last frame. The app only configures the scene
// (the camera and the point size, which depend on what was loaded).
void run_render(const RenderArgs& args) {
  auto start = std::chrono::steady_clock::now();
  Engine engine;
  engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{});
  if (args.pipelined) engine.add_plugin(PipelinedRenderingPlugin{});
  const bool compute = args.renderer == "compute";
  GpuPlugin gpu;
  gpu.options.backend = args.backend;
  if (compute) gpu.options.optional_features = pc::compute_raster_features();
  engine.add_plugin(std::move(gpu));
  RenderGraphPlugin graph;
  graph.keep_history = true;
  graph.dump_graph = args.dump_graph;
  engine.add_plugin(std::move(graph));
  const bool tileset = args.inputs.size() == 1 && tiles3d::is_tileset_input(args.inputs[0]);
  if (tileset) {
    // 3D Tiles: streamed frame by frame with the camera; the PNG is written once the streamer
    // is idle (everything the view selects is resident), or at --max-frames.
    if (compute) fail("--renderer compute does not draw tilesets yet");
    TilesetPlugin tiles;
    tiles.uri = args.inputs[0];
    tiles.streamer.traversal.max_sse = args.max_sse;
    tiles.streamer.traversal.memory_budget = args.memory_mb << 20;
    tiles.width = args.width;
    tiles.height = args.height;
    tiles.render = args.settings;
    engine.add_plugin(std::move(tiles));
    engine.add_plugin(HeadlessTargetPlugin{args.width, args.height, "", 0});
  } else {
    PointCloudPlugin points;
    points.inputs.files.assign(args.inputs.begin(), args.inputs.end());
    points.inputs.scene.point_count = args.scene_points;
    points.inputs.scene.seed = args.seed;
    points.settings.render = args.settings;
    points.settings.compute = compute;
    points.settings.hqs = args.hqs;
    engine.add_plugin(std::move(points));
    engine.add_plugin(HeadlessTargetPlugin{args.width, args.height, args.output, args.frames});
  }

  Registry& main = engine.main();
  const SceneInfo& scene = main.resource<SceneInfo>();
  double aspect = double(args.width) / args.height;
  Camera camera;
  if (args.camera.empty()) {
    camera = frame_box(scene.world_bounds, aspect, args.azimuth, args.elevation, args.fov);
  } else {
    auto v = parse_numbers(args.camera, 6, "--camera");
    camera.fov_y = glm::radians(args.fov);
    glm::dvec3 eye = z_up_to_y_up({v[0], v[1], v[2]});
    glm::dvec3 target = z_up_to_y_up({v[3], v[4], v[5]});
    if (glm::length(target - eye) <= 0.0) fail("--camera: eye and target are the same point");
    camera.look_at(eye, target);
    camera.near_plane = std::max(glm::length(target - eye) * 1e-4, 1e-3);
  }
  main.emplace<Camera>(main.create(), camera);
  auto& settings = main.resource<PointDrawSettings>();
  main.view<PointCloudData>().each([&](const PointCloudData& data) {
    if (settings.render.point_size <= 0)
      settings.render.point_size = pc::auto_point_size(*data.cloud, camera, args.height);
  });
  if (tileset) {
    // Frames run while tiles stream in (waiting for a load between frames); once idle, the point
    // size is fitted to what is drawn (unless given), `--frames` more frames run and the last is
    // written.
    const bool auto_size = settings.render.point_size <= 0;
    if (auto_size) settings.render.point_size = 2.0f;
    engine.add_system(
        MainStage::Update,
        [settled = uint64_t(0), frames = uint64_t(args.frames), max_frames = args.max_frames,
         output = args.output, height = args.height, memory_mb = args.memory_mb,
         max_sse = args.max_sse, auto_size](Registry& r) mutable {
          auto& s = r.resource<TilesetStream>();
          const auto& stats = r.resource<TilesetStats>();
          bool capped = stats.frames >= max_frames;
          // The traversal keeps the selection within the memory budget (coarser tiles where the
          // view wants more), so the streamer goes idle in every case.
          if (!stats.idle && !capped) {
            s.streamer->wait_for_progress();
            return;
          }
          if (settled == 0 && !stats.idle)
            STIPPLE_WARN("--max-frames {} reached before the tileset was streamed", max_frames);
          if (settled == 0 && stats.budget_limited && stats.drawn_tiles == 0)
            STIPPLE_WARN(
                "--memory-mb {} is smaller than the coarsest tiles this view needs: "
                "nothing is drawn (raise --memory-mb)",
                memory_mb);
          else if (settled == 0 && stats.budget_limited)
            STIPPLE_WARN(
                "the view wants more than --memory-mb {}: drawn at a screen-space error of {:.1f} "
                "px instead of --max-sse {} (raise --memory-mb for more detail)",
                memory_mb, stats.sse_threshold, max_sse);
          if (settled++ == 0 && auto_size && stats.drawn_points > 0) {
            Aabb drawn;
            for (uint32_t t : s.draw)
              for (const auto& chunk : s.chunks[t]->chunks) drawn.extend(chunk.bounds);
            const Camera* camera = nullptr;
            r.view<Camera>().each([&](const Camera& c) {
              if (!camera) camera = &c;
            });
            if (camera)
              r.resource<PointDrawSettings>().render.point_size =
                  pc::auto_point_size(drawn, stats.drawn_points, *camera, height);
          }
          if (settled < frames) return;
          r.resource<ScreenshotRequests>().paths.push_back(output);
          r.resource<AppExit>().requested = true;
        },
        "render_when_streamed");
  }
  float point_size = compute ? 1.0f : settings.render.point_size;
  const std::string color_source =
      compute
          ? "rgb"
          : pc::color_mode_name(pc::resolve_color_mode(scene.attributes, settings.render.color));
  auto load_end = std::chrono::steady_clock::now();

  engine.run();
  engine.shutdown();
  if (tileset) point_size = engine.main().resource<PointDrawSettings>().render.point_size;
  const auto& stats = engine.render().resource<RenderStats>();
  const auto& description = engine.main().resource<GpuContext>()->description;
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  auto median = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  if (!args.stats.empty()) {
    nlohmann::json j;
    j["backend"] = description.backend;
    j["adapter"] = description.device;
    j["graphics_api"] = description.graphics_api;
    j["points"] = stats.points_total;
    j["width"] = args.width;
    j["height"] = args.height;
    j["point_size_px"] = point_size;
    j["frames"] = args.frames;
    j["pipelined"] = args.pipelined;
    j["renderer"] = args.renderer;
    j["load_s"] = std::chrono::duration<double>(load_end - start).count();
    j["passes"] = nlohmann::json::object();
    for (const auto& [name, ms] : stats.history) {
      j["passes"][name]["gpu_ms"] = ms;
      j["passes"][name]["gpu_ms_median"] = median(ms);
    }
    const auto& pool = engine.render().resource<FrameGraph>().pool;
    j["frame_gpu_ms_median"] = median(stats.gpu_ms);
    j["transient_textures_created"] = pool.stats.textures_created;
    j["transient_buffers_created"] = pool.stats.buffers_created;
    j["frame_wall_ms"] = stats.wall_ms;
    j["frame_wall_ms_median"] = median(stats.wall_ms);
    j["gpu_timing"] = !stats.gpu_ms.empty();
    auto points_ms = stats.history.find(compute ? "raster-depth" : "points");
    if (!stats.gpu_ms.empty() && median(stats.gpu_ms) > 0 && points_ms != stats.history.end())
      j["points_per_second"] = double(stats.points_total) / (median(points_ms->second) * 1e-3);
    std::string tmp = args.stats + ".partial";
    {
      std::ofstream out(tmp);
      out << j.dump(2) << "\n";
      if (!out) fail("{}: cannot write stats", args.stats);
    }
    std::filesystem::rename(tmp, args.stats);
  }
  if (args.frames > 1)
    std::printf("%u frames: GPU %.3f ms, wall %.3f ms per frame (median)\n", args.frames,
                median(stats.gpu_ms), median(stats.wall_ms));
  std::printf("rendered %llu points (%s colour, %.1f px) with %s on %s to %s (%ux%u) in %.2f s\n",
              static_cast<unsigned long long>(stats.points_total), color_source.c_str(),
              double(point_size), description.backend.c_str(), description.device.c_str(),
              args.output.c_str(), args.width, args.height, seconds);
}

}  // namespace

void add_render_command(CLI::App& cli) {
  auto args = std::make_shared<RenderArgs>();
  auto* cmd =
      cli.add_subcommand("render",
                         "Render point clouds (LAS/LAZ/COPC) headless to a PNG; with no input, the "
                         "built-in procedural scene");
  cmd->add_option("inputs", args->inputs,
                  "Input files (.las, .laz, .copc.laz), or one 3D Tiles tileset.json path or URL")
      ->check([](const std::string& in) {
        return io::is_url(in) ? std::string() : CLI::ExistingFile(in);
      });
  cmd->add_option("-o,--output", args->output, "Output PNG")->capture_default_str();
  cmd->add_option("--width", args->width, "Image width in pixels")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  cmd->add_option("--height", args->height, "Image height in pixels")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  cmd->add_option("--camera", args->camera,
                  "Camera as 'eye_x,eye_y,eye_z,target_x,target_y,target_z' in the data's "
                  "coordinates (Z up; local ENU metres for lon/lat data); default frames the data");
  cmd->add_option("--azimuth", args->azimuth,
                  "Auto-framing: view azimuth in degrees (0 = from south)")
      ->capture_default_str();
  cmd->add_option("--elevation", args->elevation, "Auto-framing: view elevation in degrees")
      ->check(CLI::Range(-89.0, 89.0))
      ->capture_default_str();
  cmd->add_option("--fov", args->fov, "Vertical field of view in degrees")
      ->check(CLI::Range(1.0, 170.0))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "WebGPU implementation: dawn or wgpu "
                  "(default: $STIPPLE_BACKEND, else wgpu)")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  add_point_render_options(cmd, args->settings);
  cmd->add_option("--scene-points", args->scene_points, "Built-in scene: number of points")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Built-in scene: random seed")->capture_default_str();
  cmd->add_option("--frames", args->frames, "Render this many frames (timing; the last is saved)")
      ->check(CLI::Range(1u, 100000u))
      ->capture_default_str();
  cmd->add_option("--stats", args->stats,
                  "Write timings (GPU ms per pass from timestamp queries, "
                  "wall ms per frame) as JSON");
  cmd->add_option("--dump-graph", args->dump_graph,
                  "Write the frame's render graph as Graphviz DOT (culled passes dashed)");
  cmd->add_flag("--pipelined", args->pipelined,
                "Run the render world on its own thread (the same images as without)");
  cmd->add_option("--renderer", args->renderer,
                  "billboard (the point pipeline) or compute (compute rasterizer, 1-pixel points)")
      ->check(CLI::IsMember({"billboard", "compute"}))
      ->capture_default_str();
  add_tileset_options(cmd, args->max_sse, args->memory_mb);
  cmd->add_option("--max-frames", args->max_frames,
                  "Tilesets: write the image after this many frames even if tiles are still "
                  "streaming")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_flag("--hqs", args->hqs,
                "Compute renderer: high-quality shading (average points within 1% of the "
                "nearest depth)");
  cmd->callback([args] { run_render(*args); });
}

}  // namespace stipple::app
