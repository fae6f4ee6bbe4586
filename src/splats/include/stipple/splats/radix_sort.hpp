#pragma once
// A stable GPU radix sort of (u32 key, u32 value) pairs in plain WGSL (shaders/splat_sort.wgsl):
// 8 bits a round, per-block histograms, a prefix sum over blocks and digits, and a stable
// scatter. No subgroups and at most 256 invocations and 16 KB of workgroup memory, so it runs
// on Dawn, wgpu-native and in browsers alike. The splat passes sort their depth keys with it;
// tests and benchmarks call it directly.
//
// The number of pairs is read on the GPU from a u32 of a storage buffer (the splats' indirect
// draw arguments, say), so a sort recorded for the capacity sorts only what an earlier pass
// produced.
#include <cstdint>
#include <vector>

#include "stipple/renderer/gpu.hpp"

namespace stipple::splats {

struct RadixSortPipelines {
  gpu::BindGroupLayout layout;
  gpu::PipelineLayout pipeline_layout;
  gpu::ComputePipeline histogram, scan_digits, scan_totals, scatter;
};
RadixSortPipelines create_radix_sort_pipelines(gpu::Context& ctx);

// Room for `capacity` pairs: keys[0]/values[0] hold the input (Storage | CopyDst | CopySrc),
// keys[1]/values[1] the other half of the ping-pong. The count is `count_buffer`'s u32 at
// `count_index`; with a null count_buffer the sort has its own (`count`, written by the caller).
struct RadixSortBuffers {
  uint32_t capacity = 0, blocks = 0;
  gpu::Buffer keys[2], values[2];
  gpu::Buffer histogram, digit_offsets, params, count;
  gpu::BindGroup rounds[4];  // round r reads keys[r % 2] and writes keys[(r + 1) % 2]
};
RadixSortBuffers create_radix_sort_buffers(gpu::Context& ctx, const RadixSortPipelines& pipelines,
                                           uint32_t capacity, WGPUBuffer count_buffer = nullptr,
                                           uint32_t count_index = 0);

// Records the sort by the low `key_bits` bits (8, 16, 24 or 32; higher bits are ignored) into
// `pass`: four dispatches a round. The result is in keys/values[radix_sort_result(key_bits)].
void encode_radix_sort(WGPUComputePassEncoder pass, const RadixSortPipelines& pipelines,
                       const RadixSortBuffers& buffers, uint32_t key_bits = 32);
uint32_t radix_sort_result(uint32_t key_bits);

// Sorts `keys` with `values` on the GPU and reads both back (blocks): for tests and tools.
void radix_sort(gpu::Context& ctx, const RadixSortPipelines& pipelines, std::vector<uint32_t>& keys,
                std::vector<uint32_t>& values, uint32_t key_bits = 32);

}  // namespace stipple::splats
