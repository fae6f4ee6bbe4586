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

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/app/point_options.hpp"
#include "stipple/app/scene.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"

namespace stipple::app {
namespace {

struct RenderArgs {
  SceneOptions scene;  // inputs, point settings, renderer, tileset streaming
  std::string output = "stipple.png";
  uint32_t width = 1280, height = 720;
  std::string camera;
  double azimuth = 30.0, elevation = 40.0, fov = 50.0;
  std::string backend;
  uint32_t frames = 1;
  std::string stats;
  std::string dump_graph;
  bool pipelined = false;
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
  SceneOptions scene_options = args.scene;
  apply_filters(scene_options);
  // The virtualized path (inputs over the host budget, or --virtual) draws with the compute
  // rasterizer too.
  const bool virtualized = use_virtual_path(scene_options);
  GpuPlugin gpu;
  gpu.options.backend = args.backend;
  // Requested always: --renderer auto decides once the adapter is known.
  gpu.options.optional_features = pc::compute_raster_features();
  engine.add_plugin(std::move(gpu));
  std::string renderer_reason;
  scene_options.renderer =
      resolve_renderer(scene_options, *engine.render().resource<GpuContext>(), &renderer_reason);
  bool compute = scene_options.renderer == Renderer::Compute || virtualized;
  // Blending's form on the compute rasterizer is HQS: a tileset auto-drawn there keeps it.
  if (args.scene.renderer == Renderer::Auto && compute && is_tileset_scene(scene_options))
    scene_options.hqs = scene_options.hqs || scene_options.render.splat == pc::SplatMode::Blend;
  RenderGraphPlugin graph;
  graph.keep_history = true;
  graph.dump_graph = args.dump_graph;
  engine.add_plugin(std::move(graph));
  // 3D Tiles are streamed frame by frame with the camera; the PNG is written once the streamer
  // is idle (everything the view selects is resident), or at --max-frames.
  const bool tileset = is_tileset_scene(scene_options);
  add_scene_plugin(engine, scene_options);
  // The virtualized path loads what the view needs while frames run; the PNG is written once
  // nothing is loading any more (or at --max-frames).
  engine.add_plugin(tileset || virtualized
                        ? HeadlessTargetPlugin{args.width, args.height, "", 0}
                        : HeadlessTargetPlugin{args.width, args.height, args.output, args.frames});

  Registry& main = engine.main();
  const Camera camera = scene_camera(main, args.camera, args.width, args.height, args.azimuth,
                                     args.elevation, args.fov);
  main.emplace<Camera>(main.create(), camera);
  auto& settings = main.resource<pc::PointDrawSettings>();
  const bool sized_by_data = settings.render.point_size <= 0;
  size_t clouds = 0;
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& data) {
    ++clouds;
    if (settings.render.point_size <= 0)
      settings.render.point_size = pc::auto_point_size(*data.cloud, camera, args.height);
  });
  // Auto: where the data's density gives 1-pixel points, the compute rasterizer draws the same
  // image (blending as HQS does) far faster (measured on lavapipe, 12M points: 134 ms against
  // 6953 ms a frame), on any adapter.
  if (args.scene.renderer == Renderer::Auto && !compute && !tileset && sized_by_data &&
      settings.render.point_size <= 1.0f && clouds > 0 &&
      !scene_options.render.filter.needs_extras()) {
    compute = true;
    settings.compute = true;
    settings.hqs = settings.render.splat == pc::SplatMode::Blend;
    renderer_reason = "auto: 1-pixel points";
  }
  std::printf("renderer: %s (%s)\n", compute ? "compute" : "billboard", renderer_reason.c_str());
  if (tileset) {
    // Frames run while tiles stream in (waiting for a load between frames); once idle, the point
    // size is fitted to what is drawn (unless given), `--frames` more frames run and the last is
    // written.
    const bool auto_size = settings.render.point_size <= 0;
    if (auto_size) settings.render.point_size = 2.0f;
    engine.add_system(
        MainStage::Update,
        [settled = uint64_t(0), frames = uint64_t(args.frames), max_frames = args.max_frames,
         output = args.output, height = args.height, memory_mb = args.scene.memory_mb,
         max_sse = max_sse_for(args.scene), point_budget = args.scene.budget, auto_size,
         uri = scene_options.inputs[0], reframe = args.camera.empty(), args](Registry& r) mutable {
          auto& s = r.resource<tiles3d::TilesetStream>();
          const auto& stats = r.resource<tiles3d::TilesetStats>();
          bool capped = stats.frames >= max_frames;
          // The traversal keeps the selection within the memory budget (coarser tiles where the
          // view wants more), so the streamer goes idle in every case.
          if (!stats.idle && !capped) {
            s.streamer->wait_for_progress();
            return;
          }
          // Framed from the tileset's volume (which may be far larger than the data) until the
          // first tiles are in: then once from their points, and streamed again for that view.
          if (reframe && !capped && stats.drawn_points > 0) {
            reframe = false;
            ViewFit fit(args.width, args.height, args.azimuth, args.elevation, args.fov);
            tiles3d::fit_drawn_tiles(fit, s);
            r.view<Camera>().each([&](Camera& c) { c = fit.camera(); });
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
                "the view wants more than --memory-mb {}{} allow: drawn at a screen-space error "
                "of {:.1f} px instead of --max-sse {} (raise them for more detail)",
                memory_mb, point_budget ? fmt::format(" and --budget {}", point_budget) : "",
                stats.sse_threshold, max_sse);
          else if (settled == 0 && stats.drawn_points == 0) {
            // Content was read and none of it is points (meshes, an empty pnts): an input with
            // no points is an error, as for LAS. Nothing read: no tile is in view.
            if ((stats.loads_completed > 0 || stats.errors > 0) && stats.resident_points == 0)
              fail("{}: nothing to render: the tiles in view hold no points{}", uri,
                   s.first_problem.empty() ? "" : fmt::format(" ({})", s.first_problem));
            STIPPLE_WARN("{}: no tile with points is in view: the image shows the background only",
                         uri);
          }
          if (settled++ == 0 && auto_size && stats.drawn_points > 0) {
            Aabb drawn;
            for (uint32_t t : s.draw)
              for (const auto& chunk : s.chunks[t]->chunks) drawn.extend(chunk.bounds);
            const Camera* camera = nullptr;
            r.view<Camera>().each([&](const Camera& c) {
              if (!camera) camera = &c;
            });
            if (camera)
              r.resource<pc::PointDrawSettings>().render.point_size =
                  pc::auto_point_size(drawn, stats.drawn_points, *camera, height);
          }
          if (settled < frames) return;
          r.resource<ScreenshotRequests>().paths.push_back(output);
          r.resource<AppExit>().requested = true;
        },
        "render_when_streamed");
  }
  if (virtualized) {
    engine.add_system(
        MainStage::Update,
        [settled = uint64_t(0), frames = uint64_t(args.frames), max_frames = args.max_frames,
         output = args.output, frame = uint64_t(0)](Registry& r) mutable {
          const auto& stats = r.resource<pc::VirtualCloudStats>();
          const bool capped = ++frame >= max_frames;
          if ((!stats.settled || stats.selections == 0) && !capped) {
            pc::wait_for_virtual_loads(r.resource<pc::VirtualCloudHandle>(), 0.1);
            return;
          }
          if (settled == 0 && capped && !stats.settled)
            STIPPLE_WARN("--max-frames {} reached while points were still loading", max_frames);
          if (++settled < frames) return;
          r.resource<ScreenshotRequests>().paths.push_back(output);
          r.resource<AppExit>().requested = true;
        },
        "render_when_loaded");
  }
  float point_size = virtualized ? 1.0f
                     : compute   ? pc::compute_point_size(settings.render)
                                 : settings.render.point_size;
  auto load_end = std::chrono::steady_clock::now();

  engine.run();
  engine.shutdown();
  // After the run: a tileset's attributes are known once its tiles are drawn.
  const std::string color_source =
      virtualized ? "rgb"  // the pointlet cache keeps RGB
                  : pc::color_mode_name(pc::resolve_color_mode(
                        engine.main().resource<pc::SceneInfo>().attributes, settings.render.color));
  if (tileset) {
    point_size = engine.main().resource<pc::PointDrawSettings>().render.point_size;
    if (const uint64_t more =
            tiles3d::unreported_tile_problems(engine.main().resource<tiles3d::TilesetStream>()))
      STIPPLE_WARN("{} more tiles had the problems above (each kind is reported once)", more);
  }
  const auto& stats = engine.render().resource<RenderStats>();
  const auto& description = engine.main().resource<GpuContext>()->description;
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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
    j["renderer"] = compute ? "compute" : "billboard";
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
    write_file_atomically(args.stats, j.dump(2) + "\n");
  }
  if (args.frames > 1)
    std::printf("%u frames: GPU %.3f ms, wall %.3f ms per frame (median)\n", args.frames,
                median(stats.gpu_ms), median(stats.wall_ms));
  const std::string drawn = stats.points_drawn > 0 && stats.points_drawn < stats.points_total
                                ? fmt::format("{} of {}", stats.points_drawn, stats.points_total)
                                : std::to_string(stats.points_total);
  std::printf("rendered %s points (%s colour, %.1f px) with %s on %s to %s (%ux%u) in %.2f s\n",
              drawn.c_str(), color_source.c_str(), double(point_size), description.backend.c_str(),
              description.device.c_str(), args.output.c_str(), args.width, args.height, seconds);
}

}  // namespace

void add_render_command(CLI::App& cli) {
  auto args = std::make_shared<RenderArgs>();
  auto* cmd =
      cli.add_subcommand("render",
                         "Render point clouds (LAS/LAZ/COPC) headless to a PNG; with no input, the "
                         "built-in procedural scene");
  cmd->add_option("inputs", args->scene.inputs,
                  "Input files (.las, .laz, .copc.laz), or one 3D Tiles tileset.json, Potree "
                  "metadata.json or cloud.js, or EPT ept.json path or URL")
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
  add_point_render_options(cmd, args->scene.render);
  cmd->add_option("--scene-points", args->scene.scene_points, "Built-in scene: number of points")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_option("--seed", args->scene.seed, "Built-in scene: random seed")->capture_default_str();
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
  add_scene_options(cmd, args->scene);
  cmd->add_option("--max-frames", args->max_frames,
                  "Tilesets: write the image after this many frames even if tiles are still "
                  "streaming")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->callback([args] { run_render(*args); });
}

}  // namespace stipple::app
