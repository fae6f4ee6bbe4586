// Seed 002, III-D, on the compute rasterizer: hole filling (a sparse cloud's gaps closed within
// the radius, larger holes left open) and the occlusion check of eq. 4 (a floor seen through
// the gaps of a sparse wall in front of it is suppressed, as in the seed's Fig. 9). Images are
// counted by colour; the tolerances are stated with each expectation.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/render_graph.hpp"

using namespace stipple;

namespace {

constexpr uint32_t kW = 320, kH = 200;

class RasterFill : public ::testing::TestWithParam<std::string> {
 protected:
  std::unique_ptr<gpu::Context> context() {
    gpu::ContextOptions options;
    options.backend = GetParam();
    options.optional_features = pc::compute_raster_features();
    return gpu::create_context(options);
  }
};

// A camera 10 m in front of the z = 0 plane, looking at it: a pixel there is 2 * 10 *
// tan(30 deg) / 200 = 0.0577 m.
Camera front_camera() {
  Camera c;
  c.fov_y = glm::radians(60.0);
  c.look_at({0, 0, 10}, {0, 0, 0});
  c.near_plane = 0.1;
  return c;
}
constexpr double kPixel = 2 * 10 * 0.57735026918962573 / kH;

// A square grid of points in the plane z, `spacing` apart, `n` x `n`, centred on the axis.
void add_grid(std::vector<glm::dvec3>& positions, std::vector<uint32_t>& colors, double z,
              double spacing, int n, uint32_t rgba) {
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      // Half a pixel off the pixel grid, so each point falls inside one pixel.
      positions.push_back({(i - n / 2 + 0.5) * spacing, (j - n / 2 + 0.5) * spacing, z});
      colors.push_back(rgba);
    }
}

gpu::Image render(gpu::Context& ctx, const std::vector<glm::dvec3>& positions,
                  const std::vector<uint32_t>& colors, const pc::ComputeRasterOptions& base) {
  pc::BatchedCloud cloud;
  pc::append_batches(cloud, positions, colors, pc::SpatialOrder::Morton);
  auto gpu_cloud = pc::upload_batched_cloud(ctx, cloud);
  auto target = gpu::create_offscreen_target(ctx, kW, kH);
  auto pipeline = pc::create_compute_raster_pipeline(ctx, target.color_format);
  pc::ComputeRasterOptions options = base;
  options.background = {0, 0, 0};
  gpu::RenderGraph graph;
  graph.import_texture("color", target.color.get(), target.color_view.get(),
                       {kW, kH, target.color_format, WGPUTextureUsage_RenderAttachment},
                       gpu::Access::Writable);
  pc::add_compute_raster_passes(graph, pipeline, gpu_cloud, front_camera(), options, kW, kH);
  gpu::TransientPool pool;
  graph.execute(ctx, pool);
  ctx.check("raster fill test");
  return gpu::read_texture(ctx, target.color.get(), kW, kH, target.color_format);
}

// Pixels of the centre box (half the width and height) with this colour (within 8 levels).
double share(const gpu::Image& image, uint8_t r, uint8_t g, uint8_t b) {
  size_t hit = 0, total = 0;
  for (uint32_t y = kH / 4; y < kH * 3 / 4; ++y)
    for (uint32_t x = kW / 4; x < kW * 3 / 4; ++x) {
      const uint8_t* p = &image.rgba[(size_t(y) * kW + x) * 4];
      ++total;
      if (std::abs(p[0] - r) <= 8 && std::abs(p[1] - g) <= 8 && std::abs(p[2] - b) <= 8) ++hit;
    }
  return double(hit) / double(total);
}

}  // namespace

TEST_P(RasterFill, HoleFillingClosesGapsWithinTheRadius) {
  auto ctx = context();
  std::vector<glm::dvec3> positions;
  std::vector<uint32_t> colors;
  // Points 2 pixels apart, over more than the centre box: a quarter of the pixels are drawn.
  add_grid(positions, colors, 0.0, 2 * kPixel, 200, pc::pack_rgba(200, 100, 50));
  pc::ComputeRasterOptions off;
  const double plain = share(render(*ctx, positions, colors, off), 200, 100, 50);
  EXPECT_NEAR(plain, 0.25, 0.03);
  pc::ComputeRasterOptions fill = off;
  fill.fill_radius = 1;  // 3 x 3: every gap of one pixel has a drawn neighbour
  EXPECT_GT(share(render(*ctx, positions, colors, fill), 200, 100, 50), 0.99);
  // Points 4 pixels apart leave gaps a radius of 1 cannot reach (the seed's Fig. 7), 2 can.
  positions.clear();
  colors.clear();
  add_grid(positions, colors, 0.0, 4 * kPixel, 100, pc::pack_rgba(200, 100, 50));
  const double sparse = share(render(*ctx, positions, colors, fill), 200, 100, 50);
  EXPECT_NEAR(sparse, 9.0 / 16.0, 0.04);  // each 4 x 4 cell: the point and its 3 x 3 ring
  fill.fill_radius = 2;
  EXPECT_GT(share(render(*ctx, positions, colors, fill), 200, 100, 50), 0.99);
}

TEST_P(RasterFill, OcclusionCheckSuppressesTheBackgroundSeenThroughAWall) {
  auto ctx = context();
  std::vector<glm::dvec3> positions;
  std::vector<uint32_t> colors;
  // A dense red floor 5 m behind a sparse green wall (points 3 pixels apart): without the check
  // most of the wall's area shows the floor.
  add_grid(positions, colors, -5.0, 1.5 * kPixel, 400, pc::pack_rgba(220, 30, 30));
  add_grid(positions, colors, 0.0, 3 * kPixel, 60, pc::pack_rgba(30, 220, 30));  // 180 px wide
  pc::ComputeRasterOptions off;
  const auto plain = render(*ctx, positions, colors, off);
  EXPECT_GT(share(plain, 220, 30, 30), 0.6);
  EXPECT_NEAR(share(plain, 30, 220, 30), 1.0 / 9.0, 0.03);
  // Eq. 4 with the seed's threshold 0.1: a floor pixel with a wall point 2 pixels away is seen
  // at atan(2 * 15 * tan(FOV_x / w) * 2 / 5), about 0.07 rad, so it goes.
  pc::ComputeRasterOptions check = off;
  check.occlusion_beta = 0.1f;
  check.occlusion_radius = 2;
  const auto checked = render(*ctx, positions, colors, check);
  EXPECT_LT(share(checked, 220, 30, 30), 0.05);
  EXPECT_NEAR(share(checked, 30, 220, 30), 1.0 / 9.0, 0.03);  // the wall keeps its points
  // Filled afterwards, the wall is closed and green.
  check.fill_radius = 2;
  EXPECT_GT(share(render(*ctx, positions, colors, check), 30, 220, 30), 0.95);
  // Beyond the wall, the floor is untouched (no nearer neighbour).
  const uint8_t* corner = &checked.rgba[(size_t(5) * kW + 5) * 4];
  EXPECT_GT(corner[0], 200);
}

INSTANTIATE_TEST_SUITE_P(Backends, RasterFill, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
