// `stipple bench points`: the point pipeline's variants on one generated cloud, in one run.
// GPU milliseconds per pass come from the render graph's timestamp queries (medians over
// --frames); every frame is submitted and waited for. Needs no input data.
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/render_graph.hpp"

namespace stipple::app {
namespace {

struct BenchPointsArgs {
  uint64_t points = 100'000'000;
  uint32_t width = 1920, height = 1080;
  uint32_t frames = 10;
  float clod_k = 0.001f;
  std::string backend;
  std::string json;
};

struct Variant {
  std::string name;
  pc::SplatMode splat;
  bool edl;
  bool clod;
};

void run_bench_points(const BenchPointsArgs& args) {
  io::SceneParams scene;
  scene.point_count = args.points;
  pc::PointCloud cloud = pc::generate_scene_cloud(scene);
  const double aspect = double(args.width) / args.height;
  Camera camera = frame_box(cloud.world_bounds, aspect);
  const float point_size = pc::auto_point_size(cloud, camera, args.height);

  gpu::ContextOptions options;
  options.backend = args.backend;
  auto ctx = gpu::create_context(options);
  auto gpu_cloud = pc::upload_point_cloud(*ctx, cloud);
  cloud = {};  // the GPU holds the points now
  const WGPUTextureFormat format = WGPUTextureFormat_RGBA8Unorm;
  auto pipelines = pc::create_point_pipelines(*ctx, format);
  gpu::Texture color = gpu::create_texture_2d(*ctx, args.width, args.height, format,
                                              WGPUTextureUsage_RenderAttachment, "bench-color");
  gpu::TextureView color_view = gpu::create_view(color);
  gpu::TransientPool pool;

  const std::vector<Variant> variants = {
      {"naive", pc::SplatMode::Naive, false, false},
      {"naive + EDL", pc::SplatMode::Naive, true, false},
      {"blend", pc::SplatMode::Blend, false, false},
      {"blend + EDL", pc::SplatMode::Blend, true, false},
      {"CLOD + naive", pc::SplatMode::Naive, false, true},
      {"CLOD + blend + EDL", pc::SplatMode::Blend, true, true},
  };
  const std::vector<std::string> pass_names = {"clod", "points", "splat-depth", "splat-accumulate",
                                               "resolve"};
  nlohmann::json report;
  report["backend"] = ctx->description.backend;
  report["adapter"] = ctx->description.device;
  report["points"] = gpu_cloud.point_count;
  report["width"] = args.width;
  report["height"] = args.height;
  report["frames"] = args.frames;
  report["point_size_px"] = point_size;
  report["clod_k"] = args.clod_k;
  std::string table =
      "| variant | clod | points | splat-depth | splat-accumulate | resolve | frame GPU ms | "
      "drawn points | M points/s |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  bool timed = false;
  for (const Variant& v : variants) {
    pc::PointRenderSettings settings;
    settings.splat = v.splat;
    settings.edl = v.edl;
    settings.point_size = point_size;
    if (v.clod) {
      settings.clod_k = args.clod_k;
      settings.size_mode = pc::PointSizeMode::Adaptive;
    }
    gpu::PassTimer timer;
    std::map<std::string, std::vector<double>> pass_ms;
    std::vector<double> frame_ms;
    // One warm-up frame (pipeline caches, transient allocation), then the timed frames.
    for (uint32_t frame = 0; frame <= args.frames; ++frame) {
      gpu::RenderGraph graph;
      graph.import_texture("color", color.get(), color_view.get(),
                           {args.width, args.height, format, WGPUTextureUsage_RenderAttachment},
                           gpu::Access::Writable);
      pc::add_point_cloud_passes(graph, pipelines, gpu_cloud, camera, settings, args.width,
                                 args.height);
      graph.compile();
      if (frame == 0) timer = gpu::create_pass_timer(*ctx, graph.plan().timed_passes);
      graph.execute(*ctx, pool, &timer);
      auto times = graph.read_pass_times(*ctx, timer);
      if (times.empty()) ctx->wait_idle();
      gpu::pool_end_frame(pool);
      if (frame == 0) continue;
      double total = 0;
      for (const auto& [name, ms] : times) {
        pass_ms[name].push_back(ms);
        total += ms;
      }
      if (!times.empty()) frame_ms.push_back(total);
    }
    ctx->check("bench points");
    timed = timed || !frame_ms.empty();
    uint64_t drawn = v.clod ? pc::read_clod_survivors(*ctx, gpu_cloud) : gpu_cloud.point_count;
    double frame = median(frame_ms);
    nlohmann::json j;
    j["variant"] = v.name;
    j["frame_gpu_ms_median"] = frame;
    j["drawn_points"] = drawn;
    std::string row = "| " + v.name;
    for (const std::string& name : pass_names) {
      auto it = pass_ms.find(name);
      if (it == pass_ms.end()) {
        row += " | -";
        continue;
      }
      j["passes"][name] = median(it->second);
      char cell[32];
      std::snprintf(cell, sizeof(cell), " | %.3f", median(it->second));
      row += cell;
    }
    double rate = frame > 0 ? double(gpu_cloud.point_count) / (frame * 1e-3) * 1e-6 : 0.0;
    j["points_per_second"] = rate * 1e6;
    char tail[128];
    std::snprintf(tail, sizeof(tail), " | %.3f | %llu | %.1f |\n", frame,
                  static_cast<unsigned long long>(drawn), rate);
    table += row + tail;
    report["variants"].push_back(j);
  }
  std::printf(
      "%s on %s (%s), %llu points, %ux%u, %.1f px points, CLOD k = %g, median of %u "
      "frames (GPU ms per pass from timestamp queries; M points/s = input points / "
      "frame GPU time)\n\n%s",
      ctx->description.backend.c_str(), ctx->description.device.c_str(),
      ctx->description.graphics_api.c_str(), static_cast<unsigned long long>(gpu_cloud.point_count),
      args.width, args.height, double(point_size), double(args.clod_k), args.frames, table.c_str());
  if (!timed) std::printf("\n(no timestamp queries on this adapter: GPU times are 0)\n");
  if (!args.json.empty()) {
    write_file_atomically(args.json, report.dump(2) + "\n");
  }
}

}  // namespace

void add_bench_points_command(CLI::App* bench) {
  auto args = std::make_shared<BenchPointsArgs>();
  auto* cmd = bench->add_subcommand(
      "points",
      "Point pipeline variants (naive, blend, EDL, CLOD) on the built-in scene: GPU ms per pass");
  cmd->add_option("-n,--points", args->points, "Points in the generated scene")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))
      ->capture_default_str();
  cmd->add_option("--width", args->width, "Image width")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  cmd->add_option("--height", args->height, "Image height")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  cmd->add_option("--frames", args->frames, "Timed frames per variant (after one warm-up)")
      ->check(CLI::Range(1u, 10000u))
      ->capture_default_str();
  cmd->add_option("--clod-k", args->clod_k, "CLOD quality factor of the CLOD variants")
      ->check(CLI::Range(0.00001f, 10.0f))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend, "WebGPU implementation: dawn or wgpu")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->add_option("--json", args->json, "Write the results as JSON");
  cmd->callback([args] { run_bench_points(*args); });
}

}  // namespace stipple::app
