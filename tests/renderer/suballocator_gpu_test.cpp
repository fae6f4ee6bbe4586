// The suballocator on a real device: ranges of shared pages never clobber each other.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/suballocator.hpp"

using namespace stipple;

namespace {

class SuballocatorGpu : public ::testing::TestWithParam<std::string> {
 protected:
  std::unique_ptr<gpu::Context> context() {
    gpu::ContextOptions options;
    options.backend = GetParam();
    return gpu::create_context(options);
  }
};

// Distinct words per allocation: a clobbered range shows another allocation's id.
std::vector<uint32_t> pattern(uint32_t id, uint64_t bytes) {
  std::vector<uint32_t> words((bytes + 3) / 4);
  for (uint32_t i = 0; i < words.size(); ++i) words[i] = (id << 20) ^ (i * 2654435761u);
  return words;
}

}  // namespace

TEST_P(SuballocatorGpu, RangesHoldTheirOwnData) {
  auto ctx = context();
  ASSERT_EQ(ctx->description.backend, GetParam());
  const uint64_t page = 1 << 20;
  gpu::Suballocator sub(*ctx, page);
  const WGPUBufferUsage usages[] = {
      WGPUBufferUsage_Vertex | WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc,
      WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc};
  std::mt19937 rng(5);
  struct Live {
    gpu::SubAllocation a;
    uint32_t id;
  };
  std::vector<Live> live;
  uint32_t next_id = 1;
  auto allocate = [&](uint64_t size, WGPUBufferUsage usage) {
    auto a = sub.allocate(size, usage);
    // Write the whole reservation (a multiple of 4, as writeBuffer needs).
    auto words = pattern(next_id, a.reserved);
    wgpuQueueWriteBuffer(ctx->queue.get(), a.buffer, a.offset, words.data(), a.reserved);
    live.push_back({a, next_id++});
  };
  for (int i = 0; i < 40; ++i) allocate(1 + rng() % (page / 6), usages[i % 2]);
  allocate(page, usages[0]);          // a whole page
  allocate(page + 12345, usages[1]);  // a dedicated buffer
  // Free every third one and fill the holes with new data.
  for (size_t i = 0; i < live.size(); i += 3) sub.free(live[i].a);
  std::vector<Live> kept;
  for (size_t i = 0; i < live.size(); ++i)
    if (i % 3 != 0) kept.push_back(live[i]);
  live = kept;
  for (int i = 0; i < 20; ++i) allocate(1 + rng() % (page / 8), usages[i % 2]);
  auto stats = sub.stats();
  EXPECT_GT(stats.pages, 2u);
  EXPECT_EQ(stats.dedicated_buffers, 1u);
  for (const auto& l : live) {
    auto bytes = gpu::read_buffer(*ctx, l.a.buffer, l.a.offset, l.a.reserved);
    auto expected = pattern(l.id, l.a.reserved);
    ASSERT_EQ(bytes.size(), l.a.reserved);
    EXPECT_EQ(std::memcmp(bytes.data(), expected.data(), bytes.size()), 0)
        << "allocation " << l.id << " at offset " << l.a.offset << " was clobbered";
  }
  for (const auto& l : live) sub.free(l.a);
  EXPECT_EQ(sub.stats().bytes_used, 0u);
  EXPECT_EQ(sub.release_empty_pages(), stats.pages);
  ctx->check("suballocator test");
}

INSTANTIATE_TEST_SUITE_P(Backends, SuballocatorGpu, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
