// The WGSL radix sort (shaders/splat_sort.wgsl) against std::stable_sort on both WebGPU
// implementations: random keys over the whole range, keys with many ties (stability shows in
// the values, which are the input positions), the largest key (which the padding of a partial
// block also uses), a count written on the GPU below the capacity, and 16-bit keys.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>

#include "stipple/renderer/gpu.hpp"
#include "stipple/splats/radix_sort.hpp"

using namespace stipple;

namespace {

class RadixSort : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    gpu::ContextOptions options;
    options.backend = GetParam();
    ctx = gpu::create_context(options);
    pipelines = splats::create_radix_sort_pipelines(*ctx);
  }
  std::unique_ptr<gpu::Context> ctx;
  splats::RadixSortPipelines pipelines;
};

// Pairs (key, position) sorted by the low `bits` bits of the key, stably: the reference.
void reference_sort(std::vector<uint32_t>& keys, std::vector<uint32_t>& values, uint32_t bits) {
  const uint32_t mask = bits >= 32 ? 0xffffffffu : (1u << bits) - 1u;
  std::vector<uint32_t> order(keys.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return (keys[a] & mask) < (keys[b] & mask); });
  std::vector<uint32_t> k(keys.size()), v(keys.size());
  for (size_t i = 0; i < order.size(); ++i) {
    k[i] = keys[order[i]];
    v[i] = values[order[i]];
  }
  keys = std::move(k);
  values = std::move(v);
}

void expect_sorted_like_reference(gpu::Context& ctx, const splats::RadixSortPipelines& p,
                                  std::vector<uint32_t> keys, uint32_t bits = 32) {
  std::vector<uint32_t> values(keys.size());
  std::iota(values.begin(), values.end(), 0u);
  std::vector<uint32_t> ref_keys = keys, ref_values = values;
  reference_sort(ref_keys, ref_values, bits);
  splats::radix_sort(ctx, p, keys, values, bits);
  ASSERT_EQ(keys.size(), ref_keys.size());
  size_t key_mismatch = 0, value_mismatch = 0;
  for (size_t i = 0; i < keys.size(); ++i) {
    key_mismatch += keys[i] != ref_keys[i];
    value_mismatch += values[i] != ref_values[i];
  }
  EXPECT_EQ(key_mismatch, 0u) << "of " << keys.size();
  EXPECT_EQ(value_mismatch, 0u) << "of " << keys.size() << " (stability)";
}

std::vector<uint32_t> random_keys(size_t n, uint32_t range, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint32_t> keys(n);
  if (range == 0) {
    for (auto& k : keys) k = rng();
  } else {
    std::uniform_int_distribution<uint32_t> d(0, range - 1);
    for (auto& k : keys) k = d(rng);
  }
  return keys;
}

TEST_P(RadixSort, FullRangeKeys) {
  // 600,011 pairs: 293 blocks of 2,048 (the digit scan's invocations take two each, the last
  // ones fewer or none), the last block partial.
  expect_sorted_like_reference(*ctx, pipelines, random_keys(600011, 0, 1));
}

TEST_P(RadixSort, ManyTiesAreStable) {
  expect_sorted_like_reference(*ctx, pipelines, random_keys(100003, 37, 2));
  // Ties within every digit but the top one, and runs longer than a block.
  std::vector<uint32_t> keys = random_keys(70001, 5, 3);
  for (auto& k : keys) k = k << 24 | 0x00a5a5a5u;
  expect_sorted_like_reference(*ctx, pipelines, keys);
}

TEST_P(RadixSort, LargestKeyAndSmallInputs) {
  std::vector<uint32_t> keys = random_keys(1500, 3, 4);
  for (auto& k : keys) k = k == 0 ? 0xffffffffu : k;
  expect_sorted_like_reference(*ctx, pipelines, keys);
  expect_sorted_like_reference(*ctx, pipelines, {7u});
  expect_sorted_like_reference(*ctx, pipelines, {3u, 1u, 2u, 1u, 0xffffffffu, 0u});
}

TEST_P(RadixSort, SixteenBitKeysIgnoreHigherBits) {
  // Only the low 16 bits order the pairs; the high ones must not (two rounds, not four).
  expect_sorted_like_reference(*ctx, pipelines, random_keys(50000, 0, 5), 16);
}

TEST_P(RadixSort, CountFromTheGpuBelowCapacity) {
  // The sort is recorded for 4,096 pairs but the count buffer says 1,000: the first 1,000 are
  // sorted and nothing is written past them.
  const uint32_t capacity = 4096, n = 1000;
  auto b = splats::create_radix_sort_buffers(*ctx, pipelines, capacity);
  std::vector<uint32_t> keys = random_keys(capacity, 50, 6), values(capacity);
  std::iota(values.begin(), values.end(), 0u);
  gpu::write_buffer(*ctx, b.count.get(), 0, n);
  gpu::write_buffer(*ctx, b.keys[0].get(), 0, keys.data(), capacity * 4);
  gpu::write_buffer(*ctx, b.values[0].get(), 0, values.data(), capacity * 4);
  const std::vector<uint32_t> sentinel(capacity, 0xdeadbeefu);
  gpu::write_buffer(*ctx, b.keys[1].get(), 0, sentinel.data(), capacity * 4);
  WGPUCommandEncoderDescriptor edesc = WGPU_COMMAND_ENCODER_DESCRIPTOR_INIT;
  gpu::CommandEncoder encoder(wgpuDeviceCreateCommandEncoder(ctx->device.get(), &edesc));
  WGPUComputePassDescriptor cdesc = WGPU_COMPUTE_PASS_DESCRIPTOR_INIT;
  gpu::ComputePassEncoder pass(wgpuCommandEncoderBeginComputePass(encoder.get(), &cdesc));
  splats::encode_radix_sort(pass.get(), pipelines, b, 8);  // one round: the result in keys[1]
  wgpuComputePassEncoderEnd(pass.get());
  WGPUCommandBufferDescriptor bdesc = WGPU_COMMAND_BUFFER_DESCRIPTOR_INIT;
  gpu::CommandBuffer commands(wgpuCommandEncoderFinish(encoder.get(), &bdesc));
  WGPUCommandBuffer raw = commands.get();
  wgpuQueueSubmit(ctx->queue.get(), 1, &raw);
  ASSERT_EQ(splats::radix_sort_result(8), 1u);
  auto bytes = gpu::read_buffer(*ctx, b.keys[1].get(), 0, capacity * 4);
  auto vbytes = gpu::read_buffer(*ctx, b.values[1].get(), 0, capacity * 4);
  std::vector<uint32_t> got(capacity), got_values(capacity);
  std::memcpy(got.data(), bytes.data(), bytes.size());
  std::memcpy(got_values.data(), vbytes.data(), vbytes.size());
  std::vector<uint32_t> ref_keys(keys.begin(), keys.begin() + n),
      ref_values(values.begin(), values.begin() + n);
  reference_sort(ref_keys, ref_values, 8);
  for (uint32_t i = 0; i < n; ++i) {
    ASSERT_EQ(got[i], ref_keys[i]) << i;
    ASSERT_EQ(got_values[i], ref_values[i]) << i;
  }
  for (uint32_t i = n; i < capacity; ++i) ASSERT_EQ(got[i], 0xdeadbeefu) << i;
}

INSTANTIATE_TEST_SUITE_P(Backends, RadixSort, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });

}  // namespace
