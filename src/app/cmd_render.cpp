// `stipple render`: headless rendering of LAS/LAZ/COPC files (or the built-in scene) to PNG.
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
#include "app/point_options.hpp"
#include "core/error.hpp"
#include "core/log.hpp"
#include "io/fetch.hpp"
#include "math/camera.hpp"
#include "pointcloud/compute_raster.hpp"
#include "pointcloud/point_cloud.hpp"
#include "pointcloud/point_renderer.hpp"
#include "pointcloud/procedural.hpp"
#include "renderer/gpu.hpp"
#include "renderer/png.hpp"
#include "renderer/render_graph.hpp"
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
  std::string renderer = "billboard";
  bool hqs = false;
};

void run_render(const RenderArgs& args) {
  auto start = std::chrono::steady_clock::now();
  pc::PointCloud cloud;
  if (args.inputs.empty()) {
    pc::SceneParams scene;
    scene.point_count = args.scene_points;
    scene.seed = args.seed;
    cloud = pc::generate_scene_cloud(scene);
    STIPPLE_INFO("built-in scene: {} points", cloud.point_count);
  } else if (args.inputs.size() == 1 && tiles3d::is_tileset_input(args.inputs[0])) {
    // 3D Tiles (file or URL): stream what the framing camera selects, then render it.
    tiles3d::RenderLoadOptions options;
    options.width = args.width, options.height = args.height;
    options.azimuth = args.azimuth, options.elevation = args.elevation, options.fov = args.fov;
    auto loaded = tiles3d::load_tileset_for_render(args.inputs[0], options);
    for (const auto& e : loaded.errors) STIPPLE_WARN("tile {}: {}", e.tile, e.message);
    cloud = std::move(loaded.cloud);
  } else {
    std::vector<std::filesystem::path> files(args.inputs.begin(), args.inputs.end());
    cloud = pc::load_point_cloud(files, {});
  }
  if (cloud.point_count == 0) fail("nothing to render: the input holds no points");

  double aspect = double(args.width) / args.height;
  Camera camera;
  if (args.camera.empty()) {
    camera = frame_box(cloud.world_bounds, aspect, args.azimuth, args.elevation, args.fov);
  } else {
    auto v = parse_numbers(args.camera, 6, "--camera");
    camera.fov_y = glm::radians(args.fov);
    glm::dvec3 eye = z_up_to_y_up({v[0], v[1], v[2]});
    glm::dvec3 target = z_up_to_y_up({v[3], v[4], v[5]});
    if (glm::length(target - eye) <= 0.0) fail("--camera: eye and target are the same point");
    camera.look_at(eye, target);
    camera.near_plane = std::max(glm::length(target - eye) * 1e-4, 1e-3);
  }

  gpu::ContextOptions gpu_options;
  gpu_options.backend = args.backend;
  const bool compute = args.renderer == "compute";
  if (compute) gpu_options.optional_features = pc::compute_raster_features();
  auto ctx = gpu::create_context(gpu_options);
  pc::GpuPointCloud gpu_cloud;
  pc::GpuBatchedCloud raster_cloud;
  if (compute) {
    raster_cloud =
        pc::upload_batched_cloud(*ctx, pc::build_batches(cloud, pc::SpatialOrder::Morton));
    gpu_cloud.point_count = raster_cloud.point_count;
  } else {
    gpu_cloud = pc::upload_point_cloud(*ctx, cloud);
  }
  // Only the colour target outlives the frame; depth is a transient of the point pass.
  const WGPUTextureFormat color_format = WGPUTextureFormat_RGBA8Unorm;
  gpu::Texture color = gpu::create_texture_2d(
      *ctx, args.width, args.height, color_format,
      WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc, "render-color");
  gpu::TextureView color_view = gpu::create_view(color);
  auto pipelines = pc::create_point_pipelines(*ctx, color_format);
  pc::PointRenderSettings settings = args.settings;
  if (settings.point_size <= 0)
    settings.point_size = pc::auto_point_size(cloud, camera, args.height);
  const pc::ColorMode color_mode = pc::resolve_color_mode(cloud.attributes, settings.color);
  pc::ComputeRasterPipeline raster;
  if (compute) raster = pc::create_compute_raster_pipeline(*ctx, color_format);
  auto load_end = std::chrono::steady_clock::now();

  // The frame's graph, rebuilt every frame as a real-time loop would; transients come from the
  // pool, so only the first frame allocates them.
  gpu::TransientPool pool;
  gpu::PassTimer timer;
  auto build_graph = [&](gpu::RenderGraph& graph) {
    graph.import_texture("color", color.get(), color_view.get(),
                         {args.width, args.height, color_format,
                          WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc},
                         gpu::Access::Writable);
    if (compute) {
      pc::ComputeRasterOptions raster_options;
      raster_options.hqs = args.hqs;
      raster_options.background = settings.background;
      pc::add_compute_raster_passes(graph, raster, raster_cloud, camera, raster_options, args.width,
                                    args.height);
    } else {
      pc::add_point_cloud_passes(graph, pipelines, gpu_cloud, camera, settings, args.width,
                                 args.height);
    }
    graph.compile();
  };
  // Every frame is waited for, so GPU and wall times are per frame, not pipelined.
  std::map<std::string, std::vector<double>> pass_ms;
  std::vector<double> gpu_ms, wall_ms;
  for (uint32_t frame = 0; frame < args.frames; ++frame) {
    auto t0 = std::chrono::steady_clock::now();
    gpu::RenderGraph graph;
    build_graph(graph);
    if (frame == 0) {
      timer = gpu::create_pass_timer(*ctx, std::max(1u, graph.plan().timed_passes));
      // Every surviving pass has its stats keys, timed or not.
      for (uint32_t p : graph.plan().order) pass_ms[graph.passes()[p].name];
      if (!args.dump_graph.empty()) {
        std::ofstream out(args.dump_graph);
        graph.dump_dot(out);
        if (!out) fail("{}: cannot write the graph", args.dump_graph);
      }
    }
    graph.execute(*ctx, pool, &timer);
    auto times = graph.read_pass_times(*ctx, timer);
    if (times.empty()) {
      ctx->wait_idle();
    } else {
      double total = 0;
      for (const auto& [name, ms] : times) {
        pass_ms[name].push_back(ms);
        total += ms;
      }
      gpu_ms.push_back(total);
    }
    wall_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  gpu::Image image = gpu::read_texture(*ctx, color.get(), args.width, args.height, color_format);
  gpu::write_png(args.output, image);
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  auto median = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  if (!args.stats.empty()) {
    nlohmann::json j;
    j["backend"] = ctx->description.backend;
    j["adapter"] = ctx->description.device;
    j["graphics_api"] = ctx->description.graphics_api;
    j["points"] = gpu_cloud.point_count;
    j["width"] = args.width;
    j["height"] = args.height;
    j["point_size_px"] = settings.point_size;
    j["splat"] = settings.splat == pc::SplatMode::Blend ? "blend" : "naive";
    j["edl"] = settings.edl;
    j["clod_k"] = settings.clod_k;
    j["color"] = pc::color_mode_name(color_mode);
    j["frames"] = args.frames;
    j["load_s"] = std::chrono::duration<double>(load_end - start).count();
    j["passes"] = nlohmann::json::object();
    for (const auto& [name, ms] : pass_ms) {
      j["passes"][name]["gpu_ms"] = ms;
      j["passes"][name]["gpu_ms_median"] = median(ms);
    }
    j["frame_gpu_ms_median"] = median(gpu_ms);
    j["transient_textures_created"] = pool.stats.textures_created;
    j["transient_buffers_created"] = pool.stats.buffers_created;
    j["frame_wall_ms"] = wall_ms;
    j["frame_wall_ms_median"] = median(wall_ms);
    j["gpu_timing"] = !gpu_ms.empty();
    if (!gpu_ms.empty() && median(gpu_ms) > 0)
      j["points_per_second"] = double(gpu_cloud.point_count) / (median(gpu_ms) * 1e-3);
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
                median(gpu_ms), median(wall_ms));
  std::printf("rendered %llu points (%s colour, %.1f px) with %s on %s to %s (%ux%u) in %.2f s\n",
              static_cast<unsigned long long>(gpu_cloud.point_count),
              pc::color_mode_name(color_mode), double(settings.point_size),
              ctx->description.backend.c_str(), ctx->description.device.c_str(),
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
  cmd->add_option("--renderer", args->renderer,
                  "billboard (point quads) or compute (compute rasterizer, 1-pixel points)")
      ->check(CLI::IsMember({"billboard", "compute"}))
      ->capture_default_str();
  cmd->add_flag("--hqs", args->hqs,
                "Compute renderer: high-quality shading (average points within 1% of the "
                "nearest depth)");
  cmd->callback([args] { run_render(*args); });
}

}  // namespace stipple::app
