// The virtual memory system's GPU buffers (seed 002, III-C) after a random camera sequence: the
// LoD on the GPU says what each pointlet draws, the store compacts the previous frame's buffers
// and the new points on the GPU, and what the buffers hold is compared word for word with a CPU
// model: every drawn pointlet's prefix, quantized in its box, pointlets in index order. A small
// staging buffer makes transfers span several frames.
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <numeric>
#include <random>

#include <gtest/gtest.h>

#include "scene_pointlets.hpp"

#include "stipple/core/thread_pool.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_store.hpp"
#include "stipple/pointcloud/pointlet_lod.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/gpu_timer.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

class PointStore : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() { dir_ = test::make_scene_pointlets("point-store"); }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static fs::path dir_;
};
fs::path PointStore::dir_;

std::vector<uint32_t> read_words(gpu::Context& ctx, const gpu::Buffer& buffer, uint64_t count) {
  std::vector<uint32_t> words(count);
  if (count == 0) return words;
  auto bytes = gpu::read_buffer(ctx, buffer.get(), 0, count * 4);
  std::memcpy(words.data(), bytes.data(), count * 4);
  return words;
}

}  // namespace

TEST_P(PointStore, BuffersEqualTheCpuModelAfterACameraSequence) {
  gpu::ContextOptions options;
  options.backend = GetParam();
  auto ctx = gpu::create_context(options);
  const pc::PointletCache cache = pc::PointletCache::open(dir_ / "scene.pointlets");
  const auto& table = cache.pointlets();
  pc::GpuPointlets gpu_pointlets = pc::upload_pointlets(*ctx, cache);
  pc::PointletLodPipeline lod = pc::create_pointlet_lod_pipeline(*ctx);
  const std::vector<Aabb> boxes = pc::pointlet_world_boxes(cache);

  const uint64_t bucket = 30000;
  // Staging for the compaction info (3125 pointlets, two jobs each) and 4,000 new points.
  const uint64_t staging = 3125 * 2 * 16 + 256 + 4000 * pc::kStoreWords * 4;
  pc::GpuPointStore store = pc::create_point_store(*ctx, bucket, boxes, staging);
  ASSERT_LE(pc::max_fresh_points(store), 4016u);  // the info is padded to 256 bytes
  ASSERT_GE(pc::max_fresh_points(store), 3900u);
  // The writer under test is the library's; the model below quantizes on its own.
  pc::FreshWriter writer = [&](std::span<const pc::FreshRange> ranges, uint32_t* words) {
    std::vector<pc::PointletRecord> records;
    for (const pc::FreshRange& r : ranges) {
      records.clear();
      cache.read(r.pointlet, r.first, r.count, records);
      pc::pointlet_words(cache, table[r.pointlet], boxes[r.pointlet], records,
                         words + uint64_t(r.at) * pc::kStoreWords);
    }
  };

  Aabb box;
  box.extend(z_up_to_y_up(cache.info().source_bounds.min));
  box.extend(z_up_to_y_up(cache.info().source_bounds.max));
  const uint32_t width = 320, height = 200;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  uint64_t limited_steps = 0, kept_total = 0;
  ThreadPool workers(2);
  for (int step = 0; step < 12; ++step) {
    SCOPED_TRACE(step);
    Camera camera;
    if (step % 4 == 0) {
      camera = frame_box(box, double(width) / height);
    } else {
      const glm::dvec3 c = box.center(), s = box.size();
      camera.look_at(
          c + glm::dvec3(u(rng) * s.x, 0.05 * s.x + 0.2 * std::abs(u(rng)) * s.x, u(rng) * s.z),
          c + glm::dvec3(u(rng) * s.x * 0.5, -0.02 * s.x, u(rng) * s.z * 0.5));
      camera.near_plane = 0.1;
    }
    const auto wanted =
        pc::compute_pointlet_lod(*ctx, lod, gpu_pointlets, camera, width, height, bucket);
    // Frames with this camera until the transfer is complete (at most a handful).
    for (int frame = 0; frame < 20; ++frame) {
      // Odd steps plan on a pool (the same result).
      pc::StoreUpdate update =
          pc::update_point_store(*ctx, store, wanted, writer, step % 2 ? &workers : nullptr);
      gpu::RenderGraph graph;
      pc::add_point_store_pass(graph, store);
      gpu::TransientPool pool;
      graph.execute(*ctx, pool);
      ctx->check("compaction");
      for (size_t i = 0; i < wanted.size(); ++i) ASSERT_LE(store.layout.count[i], wanted[i]);
      kept_total += update.kept;
      if (!update.limited) {
        ASSERT_EQ(store.layout.count, wanted);
        break;
      }
      ++limited_steps;
    }
    // The model: each drawn pointlet's prefix, in index order.
    const pc::StoreLayout& layout = store.layout;
    ASSERT_EQ(layout.count, wanted);
    const uint64_t total = std::accumulate(wanted.begin(), wanted.end(), uint64_t(0));
    ASSERT_EQ(layout.total, total);
    constexpr int kWords = pc::kStoreWords;
    std::vector<uint32_t> model(total * kWords);
    uint64_t at = 0;
    std::vector<pc::PointletRecord> records;
    for (uint32_t i = 0; i < wanted.size(); ++i) {
      if (wanted[i] == 0) continue;
      ASSERT_EQ(layout.first[i], at);
      records.clear();
      cache.read(i, 0, wanted[i], records);
      const glm::dvec3 min = boxes[i].min, size = boxes[i].max - boxes[i].min;
      for (uint32_t k = 0; k < wanted[i]; ++k, ++at) {
        const pc::QuantizedPoint q =
            pc::quantize(z_up_to_y_up(cache.position(table[i], records[k])), min, size);
        model[at * kWords + 0] = q.coarse;
        model[at * kWords + 1] = q.medium;
        model[at * kWords + 2] = q.fine;
        model[at * kWords + 3] = records[k].rgba;
        model[at * kWords + 4] = records[k].attributes;
      }
    }
    const pc::GpuBatchedCloud& drawn = pc::drawn_points(store);
    ASSERT_EQ(drawn.point_count, total);
    const auto& seg = drawn.segments.front();
    const std::vector<uint32_t> words[kWords] = {
        read_words(*ctx, seg.coarse, total), read_words(*ctx, seg.medium, total),
        read_words(*ctx, seg.fine, total), read_words(*ctx, seg.color, total),
        read_words(*ctx, seg.attributes, total)};
    for (uint64_t p = 0; p < total; ++p)
      for (int w = 0; w < kWords; ++w)
        ASSERT_EQ(words[w][p], model[p * kWords + w]) << "point " << p << " word " << w;
    // The batches cover the points in order, within their pointlet's range.
    uint64_t covered = 0;
    for (const pc::Batch& b : drawn.batches) {
      ASSERT_EQ(b.first, covered);
      covered += b.count;
    }
    ASSERT_EQ(covered, total);
    ASSERT_EQ(seg.batch_count, drawn.batches.size());
  }
  EXPECT_GT(limited_steps, 0u) << "the staging limit was never reached";
  EXPECT_GT(kept_total, 0u) << "no points were ever kept from a previous frame";
}

INSTANTIATE_TEST_SUITE_P(Backends, PointStore, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
