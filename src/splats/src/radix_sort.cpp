#include "stipple/splats/radix_sort.hpp"

#include <algorithm>
#include <cstring>

#include "stipple/core/error.hpp"
#include "stipple/renderer/shader_preprocessor.hpp"

namespace stipple::splats {
namespace {

constexpr uint32_t kBlock = 2048;        // pairs a workgroup (splat_sort.wgsl's BLOCK)
constexpr uint32_t kMaxGroupsX = 65535;  // WebGPU's maxComputeWorkgroupsPerDimension default
constexpr uint32_t kParamsStride = 256;  // uniform offsets' alignment

struct SortParams {
  uint32_t shift, blocks, groups_x, count_index, capacity, pad[3];
};

}  // namespace

RadixSortPipelines create_radix_sort_pipelines(gpu::Context& ctx) {
  using B = gpu::BufferBinding;
  RadixSortPipelines p;
  p.layout = gpu::create_compute_layout(
      ctx,
      {B::Uniform, B::ReadOnlyStorage, B::ReadOnlyStorage, B::ReadOnlyStorage, B::Storage,
       B::Storage, B::Storage, B::Storage},
      "radix-sort");
  p.pipeline_layout = gpu::create_pipeline_layout(ctx, {p.layout.get()});
  gpu::ShaderModule module = gpu::create_shader_from_file(ctx, "splat_sort.wgsl");
  auto make = [&](const char* entry) {
    return gpu::create_compute_pipeline(ctx, module.get(), entry, p.pipeline_layout.get(), entry);
  };
  p.histogram = make("cs_histogram");
  p.scan_digits = make("cs_scan_digits");
  p.scan_totals = make("cs_scan_totals");
  p.scatter = make("cs_scatter");
  ctx.check("creating the radix sort's pipelines");
  return p;
}

RadixSortBuffers create_radix_sort_buffers(gpu::Context& ctx, const RadixSortPipelines& pipelines,
                                           uint32_t capacity, WGPUBuffer count_buffer,
                                           uint32_t count_index) {
  RadixSortBuffers b;
  b.capacity = std::max<uint32_t>(1, capacity);
  b.blocks = (b.capacity + kBlock - 1) / kBlock;
  const uint64_t bytes = uint64_t(b.capacity) * 4;
  if (bytes > ctx.limits.maxStorageBufferBindingSize)
    fail(
        "radix sort: {} pairs need {} bytes a key buffer, over the device's storage binding "
        "limit of {}",
        capacity, bytes, ctx.limits.maxStorageBufferBindingSize);
  const WGPUBufferUsage usage =
      WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc;
  for (int i = 0; i < 2; ++i) {
    b.keys[i] = gpu::create_buffer(ctx, bytes, usage, "sort-keys");
    b.values[i] = gpu::create_buffer(ctx, bytes, usage, "sort-values");
  }
  b.histogram =
      gpu::create_buffer(ctx, uint64_t(b.blocks) * 256 * 4, WGPUBufferUsage_Storage, "sort-hist");
  b.digit_offsets = gpu::create_buffer(ctx, 256 * 4, WGPUBufferUsage_Storage, "sort-offsets");
  if (!count_buffer) {
    b.count = gpu::create_buffer(ctx, 16, WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst,
                                 "sort-count");
    count_buffer = b.count.get();
    count_index = 0;
  }
  const uint32_t groups_x = std::min(b.blocks, kMaxGroupsX);
  std::vector<uint8_t> params(4 * kParamsStride, 0);
  for (uint32_t r = 0; r < 4; ++r) {
    SortParams sp{8 * r, b.blocks, groups_x, count_index, b.capacity, {0, 0, 0}};
    std::memcpy(params.data() + r * kParamsStride, &sp, sizeof sp);
  }
  b.params =
      gpu::create_buffer(ctx, params.size(), WGPUBufferUsage_Uniform | WGPUBufferUsage_CopyDst,
                         "sort-params", params.data());
  for (uint32_t r = 0; r < 4; ++r) {
    const uint32_t in = r % 2, out = 1 - in;
    b.rounds[r] = gpu::create_bind_group(
        ctx, pipelines.layout.get(),
        {gpu::bind_buffer(0, b.params.get(), r * kParamsStride, sizeof(SortParams)),
         gpu::bind_buffer(1, count_buffer), gpu::bind_buffer(2, b.keys[in].get()),
         gpu::bind_buffer(3, b.values[in].get()), gpu::bind_buffer(4, b.keys[out].get()),
         gpu::bind_buffer(5, b.values[out].get()), gpu::bind_buffer(6, b.histogram.get()),
         gpu::bind_buffer(7, b.digit_offsets.get())},
        "sort-round");
  }
  return b;
}

uint32_t radix_sort_result(uint32_t key_bits) {
  return ((std::clamp<uint32_t>(key_bits, 8, 32) + 7) / 8) % 2;
}

void encode_radix_sort(WGPUComputePassEncoder pass, const RadixSortPipelines& p,
                       const RadixSortBuffers& b, uint32_t key_bits) {
  const uint32_t rounds = (std::clamp<uint32_t>(key_bits, 8, 32) + 7) / 8;
  const uint32_t x = std::min(b.blocks, kMaxGroupsX);
  const uint32_t y = (b.blocks + x - 1) / x;
  for (uint32_t r = 0; r < rounds; ++r) {
    WGPUBindGroup group = b.rounds[r].get();
    gpu::dispatch(pass, p.histogram.get(), {group}, x, y);
    gpu::dispatch(pass, p.scan_digits.get(), {group}, 256);
    gpu::dispatch(pass, p.scan_totals.get(), {group}, 1);
    gpu::dispatch(pass, p.scatter.get(), {group}, x, y);
  }
}

void radix_sort(gpu::Context& ctx, const RadixSortPipelines& p, std::vector<uint32_t>& keys,
                std::vector<uint32_t>& values, uint32_t key_bits) {
  if (keys.size() != values.size())
    fail("radix_sort: {} keys but {} values", keys.size(), values.size());
  if (keys.empty()) return;
  RadixSortBuffers b = create_radix_sort_buffers(ctx, p, uint32_t(keys.size()));
  const uint32_t n = uint32_t(keys.size());
  gpu::write_buffer(ctx, b.count.get(), 0, n);
  gpu::write_buffer(ctx, b.keys[0].get(), 0, keys.data(), uint64_t(n) * 4);
  gpu::write_buffer(ctx, b.values[0].get(), 0, values.data(), uint64_t(n) * 4);
  WGPUCommandEncoderDescriptor edesc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
  gpu::CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx.device.get(), &edesc));
  WGPUComputePassDescriptor cdesc = WGPU_COMPUTE_PASS_DESCRIPTOR_INIT;
  gpu::ComputePassEncoder pass(wgpuCommandEncoderBeginComputePass(encoder.get(), &cdesc));
  encode_radix_sort(pass.get(), p, b, key_bits);
  wgpuComputePassEncoderEnd(pass.get());
  WGPUCommandBufferDescriptor bdesc = WGPU_COMMAND_BUFFER_DESCRIPTOR_INIT;
  gpu::CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), &bdesc));
  WGPUCommandBuffer raw = commands.get();
  wgpuQueueSubmit(ctx.queue.get(), 1, &raw);
  ctx.check("radix sort");
  const uint32_t r = radix_sort_result(key_bits);
  auto k = gpu::read_buffer(ctx, b.keys[r].get(), 0, uint64_t(n) * 4);
  auto v = gpu::read_buffer(ctx, b.values[r].get(), 0, uint64_t(n) * 4);
  std::memcpy(keys.data(), k.data(), k.size());
  std::memcpy(values.data(), v.data(), v.size());
}

}  // namespace stipple::splats
