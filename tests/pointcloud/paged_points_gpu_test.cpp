// Point chunks in suballocator pages (pc::PagedPoints) on both implementations: they draw the
// same image as dedicated buffers per chunk, with and without CLOD (survivors at page offsets);
// a freed range is not reused before the frame that drew it has completed; freed ranges are
// reused without creating buffers.
#include <gtest/gtest.h>

#include <algorithm>

#include "stipple/io/procedural.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/paged_points.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/frame_fence.hpp"
#include "stipple/renderer/gpu.hpp"
#include "test_util.hpp"

using namespace stipple;

namespace {

class PagedPointsGpu : public ::testing::TestWithParam<std::string> {
 protected:
  std::unique_ptr<gpu::Context> context() {
    gpu::ContextOptions options;
    options.backend = GetParam();
    return gpu::create_context(options);
  }
};

constexpr uint32_t kWidth = 192, kHeight = 128;

gpu::Image draw(gpu::Context& ctx, pc::PointPipelines& pipelines, pc::GpuPointCloud& cloud,
                const Camera& camera, const pc::PointRenderSettings& settings) {
  auto target = gpu::create_offscreen_target(ctx, kWidth, kHeight);
  pc::draw_points(ctx, pipelines, cloud, camera, settings, target.color.get(),
                  target.color_view.get(), kWidth, kHeight);
  return gpu::read_texture(ctx, target.color.get(), kWidth, kHeight, target.color_format);
}

bool overlaps(const gpu::SubAllocation& a, const gpu::SubAllocation& b) {
  return a.buffer == b.buffer && a.offset < b.offset + b.reserved &&
         b.offset < a.offset + a.reserved;
}

}  // namespace

TEST_P(PagedPointsGpu, DrawsLikeDedicatedBuffersAndFreesAfterTheFrame) {
  auto ctx = context();
  ASSERT_EQ(ctx->description.backend, GetParam());
  io::SceneParams params;
  params.point_count = 60'000;
  // Chunks of at most 7000 points (137 KiB of points, 27 KiB of survivors): seven to a 1 MiB
  // page of points, all in one page of survivors.
  pc::PointCloud cloud = pc::generate_scene_cloud(params, 7000);
  ASSERT_GE(cloud.chunks.size(), 8u);
  const Camera camera = frame_box(cloud.world_bounds, double(kWidth) / kHeight, 30, 40, 50);
  pc::PointPipelines pipelines = pc::create_point_pipelines(*ctx, WGPUTextureFormat_RGBA8Unorm);

  pc::GpuPointCloud dedicated = pc::upload_point_cloud(*ctx, cloud);
  pc::PagedPoints store = pc::create_paged_points(*ctx, 1 << 20);
  pc::GpuPointCloud paged;
  paged.attributes = cloud.attributes;
  for (const auto& chunk : cloud.chunks) pc::upload_chunk_paged(*ctx, store, paged, chunk);
  pc::finish_upload(*ctx, paged);
  ASSERT_EQ(paged.point_count, dedicated.point_count);
  ASSERT_EQ(paged.chunks.size(), dedicated.chunks.size());
  const auto alignment = ctx->limits.minStorageBufferOffsetAlignment;
  for (const auto& c : paged.chunks) {
    EXPECT_EQ(c.points_offset % alignment, 0u);
    EXPECT_EQ(c.survivors_offset % alignment, 0u);
    EXPECT_FALSE(c.points);  // no buffer of its own
  }
  const uint64_t pages = store.stats->buffers_created;
  EXPECT_EQ(pages, (cloud.chunks.size() + 6) / 7 + 1) << "seven chunks to a page, and survivors";
  EXPECT_EQ(store.allocator->stats().dedicated_buffers, 0u);

  // Same chunks, same order, same uniforms: only where the points are bound differs, so the
  // images must be identical, with and without CLOD (tolerances below).
  pc::PointRenderSettings settings;
  settings.point_size = 3.0f;
  for (float k : {0.0f, 0.5f}) {
    SCOPED_TRACE(k > 0 ? "CLOD" : "all points");
    settings.clod_k = k;
    gpu::Image a = draw(*ctx, pipelines, dedicated, camera, settings);
    if (k > 0) {
      uint64_t survivors = pc::read_clod_survivors(*ctx, dedicated);
      EXPECT_GT(survivors, 0u);
      EXPECT_LT(survivors, dedicated.point_count);
    }
    gpu::Image b = draw(*ctx, pipelines, paged, camera, settings);
    if (k > 0) {
      EXPECT_EQ(pc::read_clod_survivors(*ctx, paged), pc::read_clod_survivors(*ctx, dedicated));
    }
    const uint8_t bg[3] = {18, 20, 26};
    EXPECT_GT(test::coverage_stats(a, bg).coverage, k > 0 ? 0.05 : 0.2);
    // Tolerance: all points, none; CLOD, at most 0.1% of pixels. The CLOD pass appends
    // survivors with an atomic counter, so their draw order (and which of two points at the
    // same depth wins a pixel) varies from run to run on either path.
    EXPECT_LE(test::differing_fraction(a, b, 0), k > 0 ? 0.001 : 0.0);
  }

  // The last frame drew every paged chunk: mark it, then free them all.
  const uint64_t serial = pc::mark_frame_submitted(*ctx, store);
  std::vector<gpu::SubAllocation> freed;
  for (const auto& c : paged.chunks) {
    freed.push_back(c.range);
    freed.push_back(c.survivors_range);
  }
  const uint64_t live = store.allocator->stats().allocations;
  pc::free_chunks_deferred(store, paged.chunks);
  EXPECT_TRUE(paged.chunks.empty());
  EXPECT_EQ(store.pending.size(), freed.size());
  // Until that frame is reported complete, nothing goes back and new data lands elsewhere.
  EXPECT_EQ(pc::collect_frees_completed(store, serial - 1), 0u);
  EXPECT_EQ(store.allocator->stats().allocations, live);
  pc::GpuPointCloud again;
  pc::upload_chunk_paged(*ctx, store, again, cloud.chunks[0]);
  for (const auto& f : freed) {
    EXPECT_FALSE(overlaps(again.chunks[0].range, f));
    EXPECT_FALSE(overlaps(again.chunks[0].survivors_range, f));
  }
  // Once it completed, the ranges are freed and reused without new buffers.
  ctx->wait_idle();
  EXPECT_GE(store.fence.completed(), serial);
  EXPECT_EQ(pc::collect_frees(*ctx, store), freed.size());
  EXPECT_TRUE(store.pending.empty());
  EXPECT_EQ(store.allocator->stats().allocations, 2u);
  const uint64_t created = store.stats->buffers_created;
  for (size_t i = 1; i < cloud.chunks.size(); ++i)
    pc::upload_chunk_paged(*ctx, store, again, cloud.chunks[i]);
  EXPECT_EQ(store.stats->buffers_created, created);
  // And the reused ranges hold the new data: the same image again.
  again.attributes = cloud.attributes;
  pc::finish_upload(*ctx, again);
  settings.clod_k = 0;
  EXPECT_EQ(test::differing_fraction(draw(*ctx, pipelines, dedicated, camera, settings),
                                     draw(*ctx, pipelines, again, camera, settings), 0),
            0.0);
  ctx->check("paged points");
}

TEST_P(PagedPointsGpu, FenceCompletesFramesInOrder) {
  auto ctx = context();
  gpu::FrameFence fence;
  EXPECT_EQ(fence.completed(), 0u);
  EXPECT_EQ(fence.mark(*ctx), 1u);
  EXPECT_EQ(fence.mark(*ctx), 2u);
  EXPECT_EQ(fence.submitted(), 2u);
  ctx->wait_idle();
  ctx->poll(false);
  EXPECT_EQ(fence.completed(), 2u);
}

INSTANTIATE_TEST_SUITE_P(Backends, PagedPointsGpu, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
