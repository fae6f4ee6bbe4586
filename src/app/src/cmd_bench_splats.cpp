// `stipple bench splats`: the splat passes (stipple/splats/splats.hpp) on N generated splats of a
// chosen SH degree: GPU milliseconds per pass (project, sort, draw) from the render graph's
// timestamp queries, medians over --frames after one warm-up frame, every frame waited for; the
// sort's keys per second (visible splats / sort time), for the sorted quads and the tile
// rasterizer (--rasterizer, both by default) in one run. Also a sort of N random full-range keys
// alone (`sort-only` row), which does not depend on what the camera sees. Needs no input data.
//
// The scene: splats uniform in a 20 x 10 x 20 box, scales log-uniform in [0.005, 0.05] (a few
// pixels each at 1080p, as in captured scenes), random rotations, opacities and SH, seen from
// outside the box so most are in view (--view far), or from inside it (--view close: a close-up
// whose nearest splats cover many 16x16 tiles each).
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/splats/radix_sort.hpp"
#include "stipple/splats/splats.hpp"

namespace stipple::app {
namespace {

struct BenchSplatsArgs {
  uint32_t count = 6'000'000;
  int sh = 3;
  std::string size = "1920x1080";
  uint32_t frames = 50;
  std::string backend;
  std::string json;
  uint32_t seed = 1;
  std::string rasterizer = "both";
  std::string view = "far";
};

io::SplatSet generate_splats(uint32_t n, int sh_degree, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  io::SplatSet set;
  set.sh_degree = sh_degree;
  set.positions.resize(n);
  set.scales.resize(n);
  set.rotations.resize(n);
  set.opacities.resize(n);
  set.sh_dc.resize(n);
  set.sh_rest.resize(size_t(n) * set.rest_count());
  for (uint32_t i = 0; i < n; ++i) {
    set.positions[i] = {u(rng) * 20 - 10, u(rng) * 10 - 5, u(rng) * 20 - 10};
    for (int k = 0; k < 3; ++k) set.scales[i][k] = 0.005f * std::pow(10.0f, u(rng));
    glm::vec4 q(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f);
    set.rotations[i] = glm::length(q) > 1e-6f ? q / glm::length(q) : glm::vec4(0, 0, 0, 1);
    set.opacities[i] = 0.05f + 0.95f * u(rng);
    set.sh_dc[i] = {u(rng) * 3 - 1.5f, u(rng) * 3 - 1.5f, u(rng) * 3 - 1.5f};
    for (size_t k = 0; k < set.rest_count(); ++k)
      set.sh_rest[i * set.rest_count() + k] = {u(rng) * 0.4f - 0.2f, u(rng) * 0.4f - 0.2f,
                                               u(rng) * 0.4f - 0.2f};
  }
  return set;
}

void run_bench_splats(const BenchSplatsArgs& args) {
  uint32_t width = 0, height = 0;
  if (std::sscanf(args.size.c_str(), "%ux%u", &width, &height) != 2 || width == 0 || height == 0)
    fail("bench splats: --size {} is not WIDTHxHEIGHT", args.size);
  gpu::ContextOptions options;
  options.backend = args.backend;
  auto ctx = gpu::create_context(options);
  auto pipelines = splats::create_splat_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);
  splats::GpuSplats gpu_splats;
  {
    io::SplatSet set = generate_splats(args.count, args.sh, args.seed);
    gpu_splats = splats::upload_splats(*ctx, set);
  }
  Camera camera;
  camera.fov_y = glm::radians(60.0);
  if (args.view == "close")
    camera.look_at({0.0, 0.5, 2.0}, {0.0, 0.0, 0.0});  // inside the box: near splats are large
  else
    camera.look_at({0.0, 6.0, 24.0}, {0.0, 0.0, 0.0});
  const WGPUTextureFormat format = WGPUTextureFormat_RGBA8Unorm;
  gpu::Texture color = gpu::create_texture_2d(*ctx, width, height, format,
                                              WGPUTextureUsage_RenderAttachment, "bench-color");
  gpu::TextureView color_view = gpu::create_view(color);

  // Per rasterizer: per pass its times, and the frames' sums.
  struct Variant {
    std::string name;
    splats::SplatRasterizer rasterizer;
    std::map<std::string, std::vector<double>> pass_ms;
    std::vector<double> frame_ms;
  };
  std::vector<Variant> variants;
  if (args.rasterizer != "tiles")
    variants.push_back({"quads", splats::SplatRasterizer::Quads, {}, {}});
  if (args.rasterizer != "quads")
    variants.push_back({"tiles", splats::SplatRasterizer::Tiles, {}, {}});
  for (Variant& v : variants) {
    for (uint32_t frame = 0; frame <= args.frames; ++frame) {
      auto times =
          splats::draw_splats(*ctx, pipelines, gpu_splats, camera, color.get(), color_view.get(),
                              width, height, nullptr, nullptr, true, v.rasterizer);
      if (frame == 0 || times.empty()) continue;
      double total = 0;
      for (const auto& [name, ms] : times) {
        v.pass_ms[name].push_back(ms);
        total += ms;
      }
      v.frame_ms.push_back(total);
    }
  }
  const uint32_t visible = splats::read_visible_count(*ctx, gpu_splats);

  // The sort alone on random full-range keys of the same count.
  std::vector<double> sort_ms;
  {
    auto b = splats::create_radix_sort_buffers(*ctx, pipelines.sort, args.count);
    std::mt19937 rng(args.seed + 1);
    std::vector<uint32_t> keys(args.count), values(args.count);
    for (auto& k : keys) k = rng();
    std::iota(values.begin(), values.end(), 0u);
    gpu::write_buffer(*ctx, b.count.get(), 0, args.count);
    gpu::PassTimer timer = gpu::create_pass_timer(*ctx, 1);
    for (uint32_t frame = 0; frame <= args.frames && timer.enabled; ++frame) {
      gpu::write_buffer(*ctx, b.keys[0].get(), 0, keys.data(), uint64_t(args.count) * 4);
      gpu::write_buffer(*ctx, b.values[0].get(), 0, values.data(), uint64_t(args.count) * 4);
      WGPUCommandEncoderDescriptor edesc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
      gpu::CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx->device.get(), &edesc));
      WGPUPassTimestampWrites storage;
      WGPUComputePassDescriptor cdesc = WGPU_COMPUTE_PASS_DESCRIPTOR_INIT;
      cdesc.timestampWrites = gpu::pass_timestamps(timer, 0, storage);
      gpu::ComputePassEncoder pass(wgpuCommandEncoderBeginComputePass(encoder.get(), &cdesc));
      splats::encode_radix_sort(pass.get(), pipelines.sort, b, 32);
      wgpuComputePassEncoderEnd(pass.get());
      gpu::resolve_pass_timer(timer, encoder.get(), 1);
      WGPUCommandBufferDescriptor bdesc = WGPU_COMMAND_BUFFER_DESCRIPTOR_INIT;
      gpu::CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), &bdesc));
      WGPUCommandBuffer raw = commands.get();
      wgpuQueueSubmit(ctx->queue.get(), 1, &raw);
      auto t = gpu::read_pass_times(*ctx, timer);
      if (frame > 0 && !t.empty()) sort_ms.push_back(t[0]);
    }
  }
  ctx->check("bench splats");

  nlohmann::json report;
  report["benchmark"] = "splats";
  report["backend"] = ctx->description.backend;
  report["adapter"] = ctx->description.device;
  report["splats"] = args.count;
  report["sh_degree"] = args.sh;
  report["width"] = width;
  report["height"] = height;
  report["frames"] = args.frames;
  report["visible"] = visible;
  report["view"] = args.view;
  // The tile rasterizer's (tile, splat) pair capacity after the frames (grown from 4 a splat to
  // 1.5 times the most a frame wanted).
  const uint32_t pair_capacity = splats::tile_pair_capacity(gpu_splats);
  const uint32_t most_pairs = gpu_splats.pair_counts.most;
  if (pair_capacity) {
    report["tile_pair_capacity"] = pair_capacity;
    report["tile_pairs_most"] = most_pairs;
  }
  std::string table;
  double frame = 0, sort_frame = 0;
  for (Variant& v : variants) {
    table += "| " + v.name + " pass | GPU ms (median) |\n|---|---:|\n";
    nlohmann::json j;
    for (const auto& [name, ms] : v.pass_ms) {
      j["passes"][name] = median(ms);
      char row[96];
      std::snprintf(row, sizeof row, "| %s | %.3f |\n", name.c_str(), median(ms));
      table += row;
    }
    const double f = median(v.frame_ms);
    j["frame_gpu_ms"] = f;
    char row[96];
    std::snprintf(row, sizeof row, "| frame (sum) | %.3f |\n\n", f);
    table += row;
    report["variants"][v.name] = j;
    if (&v == &variants.front()) {  // the first variant's also at the top level
      report["passes"] = j["passes"];
      frame = f;
      sort_frame = v.pass_ms.count("splat-sort") ? median(v.pass_ms["splat-sort"]) : 0.0;
    }
  }
  const double sort_alone = median(sort_ms);
  report["frame_gpu_ms"] = frame;
  report["sort_only_ms"] = sort_alone;
  report["sort_keys_per_second"] = sort_alone > 0 ? args.count / (sort_alone * 1e-3) : 0.0;
  char tail[256];
  std::snprintf(tail, sizeof tail, "| sort-only (%u random keys) | %.3f |\n", args.count,
                sort_alone);
  table += "| sort | GPU ms (median) |\n|---|---:|\n";
  table += tail;
  std::printf(
      "%s on %s (%s), %u splats, SH degree %d, %ux%u, %u visible, median of %u frames (GPU ms "
      "from timestamp queries)\n\n%s\nsort in the frame: %.2f M keys/s; sort alone: %.2f M "
      "keys/s\n",
      ctx->description.backend.c_str(), ctx->description.device.c_str(),
      ctx->description.graphics_api.c_str(), args.count, args.sh, width, height, visible,
      args.frames, table.c_str(), sort_frame > 0 ? visible / (sort_frame * 1e-3) * 1e-6 : 0.0,
      sort_alone > 0 ? args.count / (sort_alone * 1e-3) * 1e-6 : 0.0);
  if (pair_capacity)
    std::printf("tile pairs: at most %u a frame (%.1f a visible splat), capacity %u\n", most_pairs,
                double(most_pairs) / std::max(1u, visible), pair_capacity);
  if (frame == 0) std::printf("\n(no timestamp queries on this adapter: no GPU times)\n");
  if (!args.json.empty()) write_file_atomically(args.json, report.dump(2) + "\n");
}

}  // namespace

void add_bench_splats_command(CLI::App& bench) {
  auto args = std::make_shared<BenchSplatsArgs>();
  auto* cmd = bench.add_subcommand(
      "splats", "3D Gaussian splats: project, GPU radix sort and draw, GPU ms per pass");
  cmd->add_option("-n,--count", args->count, "Generated splats")
      ->check(CLI::Range(1u, 1u << 30))
      ->capture_default_str();
  cmd->add_option("--sh", args->sh, "SH degree of the splats (0-3)")
      ->check(CLI::Range(0, 3))
      ->capture_default_str();
  cmd->add_option("--size", args->size, "Image size, WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--frames", args->frames, "Timed frames (after one warm-up)")
      ->check(CLI::Range(1u, 10000u))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Random seed of the generated splats")
      ->capture_default_str();
  cmd->add_option("--backend", args->backend, "WebGPU implementation: dawn or wgpu")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->add_option("--rasterizer,--splat-rasterizer", args->rasterizer,
                  "quads (sorted instanced quads), tiles (16x16 tiles in compute) or both")
      ->check(CLI::IsMember({"quads", "tiles", "both"}))
      ->capture_default_str();
  cmd->add_option("--view", args->view,
                  "far (the box from outside: splats a few pixels each) or close (the camera "
                  "inside the box: near splats cover many tiles)")
      ->check(CLI::IsMember({"far", "close"}))
      ->capture_default_str();
  cmd->add_option("--json", args->json, "Write the results as JSON");
  cmd->callback([args] { run_bench_splats(*args); });
}

}  // namespace stipple::app
