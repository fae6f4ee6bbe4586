// The pointlets' level of detail on the GPU (seed 002, III-B, eqs. 2-3 and the point bucket B)
// against the CPU implementation of the same equations: per-pointlet counts for fixed cameras.
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <numeric>

#include <gtest/gtest.h>

#include "scene_pointlets.hpp"

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/pointlet_lod.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "stipple/renderer/gpu.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

class PointletLod : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() { dir_ = test::make_scene_pointlets("pointlet-lod"); }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static fs::path dir_;
};
fs::path PointletLod::dir_;

// Counts within one point of the CPU's (the two sum 3,000 float weights in different orders), the
// same pointlets culled, and the bucket respected.
void expect_same(const std::vector<uint32_t>& gpu, const std::vector<uint32_t>& cpu,
                 uint64_t bucket) {
  ASSERT_EQ(gpu.size(), cpu.size());
  uint64_t total = 0;
  for (size_t i = 0; i < gpu.size(); ++i) {
    ASSERT_LE(std::abs(int64_t(gpu[i]) - int64_t(cpu[i])), 1) << "pointlet " << i;
    ASSERT_EQ(gpu[i] == 0, cpu[i] == 0) << "pointlet " << i << ": " << gpu[i] << " vs " << cpu[i];
    total += gpu[i];
  }
  EXPECT_LE(total, bucket);
}

}  // namespace

TEST_P(PointletLod, CountsEqualTheCpuEquations) {
  gpu::ContextOptions options;
  options.backend = GetParam();
  auto ctx = gpu::create_context(options);
  pc::PointletCache cache = pc::PointletCache::open(dir_ / "scene.pointlets");
  ASSERT_EQ(cache.pointlets().size(), 3125u);
  pc::GpuPointlets gpu_pointlets = pc::upload_pointlets(*ctx, cache);
  pc::PointletLodPipeline pipeline = pc::create_pointlet_lod_pipeline(*ctx);
  const auto boxes = pc::pointlet_boxes(cache.pointlets(), gpu_pointlets.origin);
  std::vector<uint32_t> sizes;
  for (const auto& e : cache.pointlets()) sizes.push_back(e.count);

  Aabb box;
  box.extend(z_up_to_y_up(cache.info().source_bounds.min));
  box.extend(z_up_to_y_up(cache.info().source_bounds.max));
  const uint32_t width = 640, height = 360;
  // An overview, and a close view from inside the scene that sees part of it.
  Camera overview = frame_box(box, double(width) / height);
  Camera close;
  const glm::dvec3 c = box.center();
  close.look_at(c + glm::dvec3(-0.05, 0.02, 0.0) * box.size().x,
                c + glm::dvec3(0.2, -0.01, 0.1) * box.size().x);
  close.near_plane = 0.1;
  for (const Camera& camera : {overview, close}) {
    for (uint64_t bucket : {uint64_t(20000), uint64_t(150000), uint64_t(10'000'000)}) {
      std::vector<float> weights;
      auto cpu = pc::pointlet_lod_cpu(boxes, sizes, sizes, gpu_pointlets.origin, camera, width,
                                      height, bucket, &weights);
      auto gpu =
          pc::compute_pointlet_lod(*ctx, pipeline, gpu_pointlets, camera, width, height, bucket);
      expect_same(gpu, cpu, bucket);
      const uint64_t visible =
          size_t(std::count_if(weights.begin(), weights.end(), [](float w) { return w > 0; }));
      const uint64_t drawn = std::accumulate(gpu.begin(), gpu.end(), uint64_t(0));
      ASSERT_GT(visible, 0u);
      if (bucket == 10'000'000) {
        // A bucket far above the cloud: the visible pointlets are drawn nearly whole (the
        // capped ones whole, the rest by importance).
        uint64_t visible_points = 0;
        for (size_t i = 0; i < weights.size(); ++i)
          if (weights[i] > 0) visible_points += sizes[i];
        EXPECT_GT(drawn, visible_points / 2);
      } else if (bucket == 20000) {
        // A bucket well under the cloud: normalised importance fills it, less rounding (under
        // one point per visible pointlet) and what the pointlets' sizes cap.
        EXPECT_GT(drawn, bucket / 2);
      } else {
        // Importance concentrates near the camera, where pointlets are capped by their size
        // (the seed does not hand the excess to others): the bucket is an upper bound.
        EXPECT_LE(drawn, bucket);
      }
    }
  }
  // The overview culls nothing; the close view culls some.
  auto all = pc::compute_pointlet_lod(*ctx, pipeline, gpu_pointlets, overview, width, height);
  EXPECT_EQ(std::count(all.begin(), all.end(), 0u), 0);
  auto part = pc::compute_pointlet_lod(*ctx, pipeline, gpu_pointlets, close, width, height);
  EXPECT_GT(std::count(part.begin(), part.end(), 0u), 100);
  // What is loaded caps the counts.
  std::vector<uint32_t> loaded(sizes.size(), 3);
  pc::set_loaded_points(*ctx, gpu_pointlets, loaded);
  auto capped = pc::compute_pointlet_lod(*ctx, pipeline, gpu_pointlets, overview, width, height);
  EXPECT_EQ(*std::max_element(capped.begin(), capped.end()), 3u);
  expect_same(capped,
              pc::pointlet_lod_cpu(boxes, sizes, loaded, gpu_pointlets.origin, overview, width,
                                   height, pc::kDefaultPointBucket),
              pc::kDefaultPointBucket);
}

INSTANTIATE_TEST_SUITE_P(Backends, PointletLod, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
