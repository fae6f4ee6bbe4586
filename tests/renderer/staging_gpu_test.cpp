// Uploads through mapped staging slots: every byte lands where it belongs, across slot
// boundaries, several buffers and offsets, with the copies into the slots on a thread pool.
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "stipple/core/thread_pool.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/staging.hpp"

using namespace stipple;

namespace {

class StagingGpu : public ::testing::TestWithParam<std::string> {};

std::vector<uint32_t> words(uint32_t id, size_t count) {
  std::vector<uint32_t> w(count);
  for (size_t i = 0; i < count; ++i) w[i] = id << 24 ^ uint32_t(i * 2654435761u);
  return w;
}

}  // namespace

TEST_P(StagingGpu, UploadsLandWhereTheyBelong) {
  gpu::ContextOptions options;
  options.backend = GetParam();
  auto ctx = gpu::create_context(options);
  const auto usage = WGPUBufferUsage_Storage | WGPUBufferUsage_CopyDst | WGPUBufferUsage_CopySrc;
  // Three buffers; the second filled by two uploads at offsets. Slots of 40 KiB, so every
  // upload spans several slots and the ring of four wraps many times.
  const auto a = words(1, 100'003), b0 = words(2, 5'000), b1 = words(3, 70'001), c = words(4, 7);
  gpu::Buffer ba = gpu::create_buffer(*ctx, a.size() * 4, usage, "a");
  gpu::Buffer bb = gpu::create_buffer(*ctx, (b0.size() + b1.size()) * 4 + 64, usage, "b");
  gpu::Buffer bc = gpu::create_buffer(*ctx, c.size() * 4, usage, "c");
  const std::vector<gpu::BufferUpload> uploads = {
      {ba.get(), 0, a.data(), a.size() * 4},
      {bb.get(), 64, b0.data(), b0.size() * 4},
      {bb.get(), 64 + b0.size() * 4, b1.data(), b1.size() * 4},
      {bc.get(), 0, c.data(), c.size() * 4}};
  ThreadPool pool(3);
  gpu::upload_through_staging(*ctx, uploads, &pool, 40 << 10, 4);
  auto read = [&](const gpu::Buffer& buffer, uint64_t offset, size_t count) {
    const auto bytes = gpu::read_buffer(*ctx, buffer.get(), offset, count * 4);
    std::vector<uint32_t> out(count);
    std::memcpy(out.data(), bytes.data(), count * 4);
    return out;
  };
  EXPECT_EQ(read(ba, 0, a.size()), a);
  EXPECT_EQ(read(bb, 64, b0.size()), b0);
  EXPECT_EQ(read(bb, 64 + b0.size() * 4, b1.size()), b1);
  EXPECT_EQ(read(bc, 0, c.size()), c);
}

INSTANTIATE_TEST_SUITE_P(Backends, StagingGpu, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
