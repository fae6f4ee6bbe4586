// `stipple bench batches`: how fast a loaded cloud becomes the compute rasterizer's batches, the
// work the first frame of `render --renderer compute` waits for (seed 001, section 3.1: Morton
// order, batches of 10,240 points, quantized per batch box). The cloud is a file loaded whole or
// the built-in scene; each repetition sorts and batches it on every core (phases timed apart),
// then copies the arrays to the GPU.
#include <chrono>
#include <cstdio>
#include <thread>

#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/core/thread_pool.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/renderer/gpu.hpp"

namespace stipple::app {
namespace {

using Clock = std::chrono::steady_clock;

struct BatchesArgs {
  std::vector<std::string> files;
  uint64_t points = 100'000'000;
  uint32_t seed = 1;
  uint32_t reps = 3;
  std::string order = "morton";
  std::string backend;
  bool upload = true;
  std::string json;
};

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

void run_batches_bench(const BatchesArgs& args) {
  auto t = Clock::now();
  pc::PointCloud cloud;
  if (!args.files.empty()) {
    std::vector<std::filesystem::path> paths(args.files.begin(), args.files.end());
    cloud = pc::load_point_cloud(paths, {});
  } else {
    io::SceneParams scene;
    scene.point_count = args.points;
    scene.seed = args.seed;
    cloud = pc::generate_scene_cloud(scene);
  }
  const double load_s = seconds_since(t);
  const uint64_t n = cloud.point_count;
  if (n == 0) fail("nothing to batch: the input holds no points");
  std::printf("%llu points in %zu chunks (%s in %.1f s), %u threads\n",
              static_cast<unsigned long long>(n), cloud.chunks.size(),
              args.files.empty() ? "generated" : "loaded", load_s, pc::batching_pool().size());

  std::unique_ptr<gpu::Context> ctx;
  if (args.upload) {
    gpu::ContextOptions options;
    options.backend = args.backend;
    ctx = gpu::create_context(options);
    std::printf("upload to %s on %s\n", ctx->description.backend.c_str(),
                ctx->description.device.c_str());
  }
  nlohmann::json out;
  out["points"] = n;
  out["threads"] = pc::batching_pool().size();
  out["runs"] = nlohmann::json::array();
  std::printf("\n%4s %8s %8s %8s %8s %8s %8s %9s %9s %11s\n", "rep", "bounds", "keys", "sort",
              "refine", "write", "batch s", "upload s", "total s", "M points/s");
  std::vector<double> totals, batch_rates;
  for (uint32_t rep = 0; rep < args.reps; ++rep) {
    pc::BatchBuildStats stats;
    pc::BatchingOptions options;
    options.order = pc::parse_spatial_order(args.order);
    options.stats = &stats;
    t = Clock::now();
    pc::BatchedCloud batched = pc::build_batches(cloud, options);
    const double batch_s = seconds_since(t);
    double upload_s = 0;
    if (ctx) {
      t = Clock::now();
      pc::GpuBatchedCloud gpu_cloud = pc::upload_batched_cloud(*ctx, batched);
      upload_s = seconds_since(t);
    }
    const double total = batch_s + upload_s;
    totals.push_back(total);
    batch_rates.push_back(double(n) / batch_s * 1e-6);
    std::printf("%4u %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %9.3f %9.3f %11.1f\n", rep, stats.bounds_s,
                stats.keys_s, stats.sort_s, stats.refine_s, stats.write_s, batch_s, upload_s, total,
                double(n) / total * 1e-6);
    out["runs"].push_back({{"bounds_s", stats.bounds_s},
                           {"keys_s", stats.keys_s},
                           {"sort_s", stats.sort_s},
                           {"refine_s", stats.refine_s},
                           {"refined_cells", stats.refined_cells},
                           {"write_s", stats.write_s},
                           {"batch_s", batch_s},
                           {"upload_s", upload_s},
                           {"total_s", total}});
  }
  const double median_total = median(totals);
  std::printf(
      "\nmedian: %.3f s for %llu points, %.1f M points/s batched and uploaded (%.1f M points/s "
      "batching alone)\n",
      median_total, static_cast<unsigned long long>(n), double(n) / median_total * 1e-6,
      median(batch_rates));
  out["median_total_s"] = median_total;
  out["points_per_second"] = double(n) / median_total;
  if (!args.json.empty()) write_file_atomically(args.json, out.dump(2) + "\n");
}

}  // namespace

void add_bench_batches_command(CLI::App& bench) {
  auto args = std::make_shared<BatchesArgs>();
  auto* cmd = bench.add_subcommand(
      "batches",
      "Batch building for the compute rasterizer: sort, quantize and upload a whole cloud");
  cmd->add_option("files", args->files, "LAS/LAZ files loaded whole (default: the built-in scene)");
  cmd->add_option("--points", args->points, "Points of the built-in scene")
      ->check(CLI::Range(uint64_t(1), uint64_t(4'000'000'000)))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Scene seed")->capture_default_str();
  cmd->add_option("--reps", args->reps, "Repetitions (the median is reported)")
      ->check(CLI::Range(1u, 100u))
      ->capture_default_str();
  cmd->add_option("--order", args->order, "Point order: morton, hilbert or none")
      ->check(CLI::IsMember({"morton", "hilbert", "none"}))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend,
                  "WebGPU implementation: dawn or wgpu (default: $STIPPLE_BACKEND, else wgpu)")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->add_flag("!--no-upload", args->upload, "Batch only; no GPU");
  cmd->add_option("--json", args->json, "Write the results as JSON");
  cmd->callback([args] { run_batches_bench(*args); });
}

}  // namespace stipple::app
