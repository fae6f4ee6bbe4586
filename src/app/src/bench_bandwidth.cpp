// `stipple bench bandwidth` and the bounds `bench raster` prints: the read bandwidth a WGSL
// kernel reaches (shaders/bench/read_bandwidth.wgsl: 16-byte loads, grid-stride loop, XOR
// reduction) and the copy bandwidth of copyBufferToBuffer, both timed with timestamp queries.
#include "bench_bandwidth.hpp"

#include <algorithm>
#include <cstdio>
#include <vector>

#include <nlohmann/json.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/stats.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::app {
namespace {

// GPU ms of `record` (one compute pass it begins itself from the descriptor it is given), the
// median of `reps` runs after one untimed.
template <typename Record>
double time_compute_pass(gpu::Context& ctx, int reps, Record record) {
  gpu::PassTimer timer = gpu::create_pass_timer(ctx, 1);
  if (!timer.enabled) return 0.0;
  std::vector<double> ms;
  for (int rep = 0; rep <= reps; ++rep) {
    WGPUCommandEncoderDescriptor enc_desc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
    gpu::CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &enc_desc));
    WGPUPassTimestampWrites storage;
    WGPUComputePassDescriptor desc = WGPU_COMPUTE_PASS_DESCRIPTOR_INIT;
    desc.timestampWrites = gpu::pass_timestamps(timer, 0, storage);
    gpu::ComputePassEncoder pass(wgpuCommandEncoderBeginComputePass(encoder.get(), &desc));
    record(pass.get());
    wgpuComputePassEncoderEnd(pass.get());
    gpu::resolve_pass_timer(timer, encoder.get());
    WGPUCommandBufferDescriptor cb_desc = WGPU_COMMAND_BUFFER_DESCRIPTOR_INIT;
    gpu::CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), &cb_desc));
    WGPUCommandBuffer raw = commands.get();
    wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
    auto t = gpu::read_pass_times(ctx, timer);
    if (rep > 0 && !t.empty()) ms.push_back(t[0]);
  }
  return median(ms);
}

}  // namespace

ReadBandwidth read_bandwidth(gpu::Context& ctx, uint64_t bytes) {
  ReadBandwidth out;
  if (!ctx.has_feature(WGPUFeatureName_TimestampQuery)) return out;
  bytes = std::min<uint64_t>(
      {bytes, ctx.limits.maxBufferSize, ctx.limits.maxStorageBufferBindingSize, uint64_t(1) << 31});
  bytes &= ~uint64_t(255);
  out.bytes = bytes;
  auto data = gpu::create_buffer(ctx, bytes, WGPUBufferUsage_Storage, "read-bandwidth-data");
  auto sink = gpu::create_buffer(ctx, 4096, WGPUBufferUsage_Storage, "read-bandwidth-sink");
  gpu::ShaderModule shader = gpu::create_shader_from_file(ctx, "bench/read_bandwidth.wgsl");
  auto fill = gpu::create_compute_pipeline(ctx, shader.get(), "fill_main", nullptr, "fill");
  auto read = gpu::create_compute_pipeline(ctx, shader.get(), "read_main", nullptr, "read");
  ctx.check("read bandwidth pipelines");
  auto layout = gpu::bind_group_layout_of(fill);  // the fill writes no sink
  auto group = gpu::create_bind_group(ctx, layout.get(), {gpu::bind_buffer(0, data.get())});
  auto read_layout = gpu::bind_group_layout_of(read);
  auto read_group = gpu::create_bind_group(
      ctx, read_layout.get(), {gpu::bind_buffer(0, data.get()), gpu::bind_buffer(1, sink.get())});
  time_compute_pass(ctx, 0, [&](WGPUComputePassEncoder pass) {
    gpu::dispatch(pass, fill.get(), {group.get()}, 4096, 1);
  });
  // Enough threads to keep every memory channel busy, more than enough, and far more.
  for (uint32_t workgroups : {1024u, 4096u, 16384u, 65535u}) {
    const double ms = time_compute_pass(ctx, 8, [&](WGPUComputePassEncoder pass) {
      gpu::dispatch(pass, read.get(), {read_group.get()}, workgroups, 1);
    });
    const double gbs = ms > 0 ? double(bytes) / (ms * 1e-3) * 1e-9 : 0.0;
    if (gbs > out.gb_per_s) {
      out.gb_per_s = gbs;
      out.workgroups = workgroups;
    }
  }
  ctx.check("read bandwidth");
  return out;
}

// A buffer-to-buffer copy between two empty compute passes whose timestamps bracket it.
double copy_bandwidth_gbs(gpu::Context& ctx, uint64_t bytes) {
  bytes = std::min<uint64_t>(bytes, ctx.limits.maxBufferSize) & ~uint64_t(255);
  auto src = gpu::create_buffer(ctx, bytes, WGPUBufferUsage_CopySrc, "copy-src");
  auto dst = gpu::create_buffer(ctx, bytes, WGPUBufferUsage_CopyDst, "copy-dst");
  gpu::PassTimer timer = gpu::create_pass_timer(ctx, 1);
  if (!timer.enabled) return 0.0;
  std::vector<double> ms;
  for (int rep = 0; rep < 6; ++rep) {
    WGPUCommandEncoderDescriptor enc_desc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
    gpu::CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &enc_desc));
    WGPUPassTimestampWrites storage;
    for (int half = 0; half < 2; ++half) {
      if (half == 1)
        wgpuCommandEncoderCopyBufferToBuffer(encoder.get(), src.get(), 0, dst.get(), 0, bytes);
      WGPUPassTimestampWrites writes = *gpu::pass_timestamps(timer, 0, storage);
      // The first pass writes the begin stamp, the second the end stamp: the copy between.
      if (half == 0) writes.endOfPassWriteIndex = WGPU_QUERY_SET_INDEX_UNDEFINED;
      if (half == 1) writes.beginningOfPassWriteIndex = WGPU_QUERY_SET_INDEX_UNDEFINED;
      WGPUComputePassDescriptor desc = WGPU_COMPUTE_PASS_DESCRIPTOR_INIT;
      desc.timestampWrites = &writes;
      gpu::ComputePassEncoder pass(wgpuCommandEncoderBeginComputePass(encoder.get(), &desc));
      wgpuComputePassEncoderEnd(pass.get());
    }
    gpu::resolve_pass_timer(timer, encoder.get());
    WGPUCommandBufferDescriptor cb_desc = WGPU_COMMAND_BUFFER_DESCRIPTOR_INIT;
    gpu::CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), &cb_desc));
    WGPUCommandBuffer raw = commands.get();
    wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
    auto t = gpu::read_pass_times(ctx, timer);
    if (rep > 0 && !t.empty()) ms.push_back(t[0]);  // the first run warms up
  }
  ctx.check("copy bandwidth");
  double m = median(ms);
  return m > 0 ? double(bytes) / (m * 1e-3) * 1e-9 : 0.0;
}

namespace {

struct BandwidthArgs {
  std::string backend;
  uint32_t mb = 2048;
  std::string json;
};

void run_bandwidth_bench(const BandwidthArgs& args) {
  gpu::ContextOptions options;
  options.backend = args.backend;
  auto ctx = gpu::create_context(options);
  if (!ctx->has_feature(WGPUFeatureName_TimestampQuery))
    fail("bench bandwidth needs timestamp queries, which this adapter lacks");
  std::printf("%s on %s (%s)\n", ctx->description.backend.c_str(), ctx->description.device.c_str(),
              ctx->description.graphics_api.c_str());
  const ReadBandwidth read = read_bandwidth(*ctx, uint64_t(args.mb) << 20);
  const double copy = copy_bandwidth_gbs(*ctx, uint64_t(args.mb) << 20);
  std::printf("read kernel: %.1f GB/s (%.0f MiB, %u workgroups of 256)\n", read.gb_per_s,
              double(read.bytes) / (1 << 20), read.workgroups);
  std::printf("buffer copy: %.1f GB/s copied (%.1f GB/s read + write)\n", copy, 2 * copy);
  if (!args.json.empty())
    write_file_atomically(args.json, nlohmann::json{{"backend", ctx->description.backend},
                                                    {"adapter", ctx->description.device},
                                                    {"read_gb_per_s", read.gb_per_s},
                                                    {"read_bytes", read.bytes},
                                                    {"read_workgroups", read.workgroups},
                                                    {"copy_gb_per_s", copy}}
                                             .dump(2) +
                                         "\n");
}

}  // namespace

void add_bench_bandwidth_command(CLI::App& bench) {
  auto args = std::make_shared<BandwidthArgs>();
  auto* cmd = bench.add_subcommand(
      "bandwidth",
      "Memory bandwidth of the GPU: a read kernel (the rasterizer's bound) and a copy");
  cmd->add_option("--mb", args->mb, "Buffer size in MiB (capped by the device's limits)")
      ->check(CLI::Range(1u, 1u << 20))
      ->capture_default_str();
  cmd->add_option("--backend", args->backend, "WebGPU implementation: dawn or wgpu")
      ->check(CLI::IsMember({"dawn", "wgpu", "wgpu-native"}));
  cmd->add_option("--json", args->json, "Write the results as JSON");
  cmd->callback([args] { run_bandwidth_bench(*args); });
}

}  // namespace stipple::app
