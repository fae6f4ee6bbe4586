// GPU tests on whatever Vulkan device exists (lavapipe in CI), for both WebGPU implementations.
// Each test runs in its own process (gtest_discover_tests), so each binds one implementation.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "stipple/core/error.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;

namespace {

class Render : public ::testing::TestWithParam<std::string> {
 protected:
  std::unique_ptr<gpu::Context> context() {
    gpu::ContextOptions options;
    options.backend = GetParam();
    return gpu::create_context(options);
  }
};

struct Frame {
  gpu::Image image;
};

// Naive squares without EDL: the plain projection these tests check.
gpu::Image render(gpu::Context& ctx, const pc::PointCloud& cloud, const Camera& camera,
                  float point_size, uint32_t w = 160, uint32_t h = 120) {
  auto gpu_cloud = pc::upload_point_cloud(ctx, cloud);
  auto target = gpu::create_offscreen_target(ctx, w, h);
  auto pipelines = pc::create_point_pipelines(ctx, target.color_format, target.depth_format);
  pc::PointRenderSettings settings;
  settings.point_size = point_size;
  settings.round = false;
  settings.splat = pc::SplatMode::Naive;
  settings.edl = false;
  settings.background = {0, 0, 0};
  pc::draw_points(ctx, pipelines, gpu_cloud, camera, settings, target.color.get(),
                  target.color_view.get(), w, h);
  auto image = gpu::read_texture(ctx, target.color.get(), w, h, target.color_format);
  ctx.check("test render");
  return image;
}

// A cloud from source-frame (Z-up) points with given colours.
pc::PointCloud make_cloud(const std::vector<glm::dvec3>& points,
                          const std::vector<glm::u16vec3>& colors) {
  io::PointBatch batch;
  batch.positions = points;
  batch.rgb = colors;
  pc::PointCloud cloud;
  pc::append_batch(cloud, batch, 8, 1 << 20);
  pc::finish_cloud(cloud);
  return cloud;
}

const uint8_t* pixel(const gpu::Image& image, uint32_t x, uint32_t y) {
  return &image.rgba[(size_t(y) * image.width + x) * 4];
}

}  // namespace

TEST_P(Render, ContextHasAdapterLimitsAndReadsBack) {
  auto ctx = context();
  EXPECT_EQ(ctx->description.backend, GetParam());
  // The device was created with the adapter's limits, not WebGPU's defaults (128 MiB).
  EXPECT_GE(ctx->limits.maxStorageBufferBindingSize, 128ull << 20);
  EXPECT_GE(ctx->limits.maxBufferSize, 256ull << 20);
  std::vector<uint32_t> data(1000);
  for (uint32_t i = 0; i < data.size(); ++i) data[i] = i * 2654435761u;
  auto buffer = gpu::create_buffer(
      *ctx, data.size() * 4, WGPUBufferUsage_Storage | WGPUBufferUsage_CopySrc, "t", data.data());
  auto bytes = gpu::read_buffer(*ctx, buffer.get(), 40, 400);
  ASSERT_EQ(bytes.size(), 400u);
  EXPECT_EQ(std::memcmp(bytes.data(), data.data() + 10, 400), 0);
}

TEST_P(Render, ShaderErrorsAreReported) {
  auto ctx = context();
  try {
    gpu::create_shader(*ctx, "fn broken( {", "broken.wgsl");
    FAIL() << "expected a compile error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("broken.wgsl"), std::string::npos) << e.what();
  }
}

TEST_P(Render, PointsLandWhereTheCameraProjectsThem) {
  auto ctx = context();
  // Three coloured points in a plane 10 m in front of a camera looking north (Z-up source).
  auto cloud =
      make_cloud({{0, 10, 0}, {2, 10, 0}, {0, 10, 1.5}}, {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}});
  Camera camera;
  camera.fov_y = glm::radians(60.0);
  camera.look_at(z_up_to_y_up({0, 0, 0}), z_up_to_y_up({0, 10, 0}));
  const uint32_t w = 160, h = 120;
  auto image = render(*ctx, cloud, camera, 3.0f, w, h);
  glm::dmat4 vp = camera.view_projection(double(w) / h);
  auto project = [&](glm::dvec3 p) {
    glm::dvec4 c = vp * glm::dvec4(z_up_to_y_up(p), 1.0);
    return glm::dvec2((c.x / c.w * 0.5 + 0.5) * w, (0.5 - c.y / c.w * 0.5) * h);
  };
  const uint8_t expected[3][3] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}};
  glm::dvec3 points[3] = {{0, 10, 0}, {2, 10, 0}, {0, 10, 1.5}};
  size_t lit = 0;
  for (int i = 0; i < 3; ++i) {
    glm::dvec2 s = project(points[i]);
    const uint8_t* p = pixel(image, uint32_t(s.x), uint32_t(s.y));
    EXPECT_EQ(p[0], expected[i][0]) << "point " << i;
    EXPECT_EQ(p[1], expected[i][1]) << "point " << i;
    EXPECT_EQ(p[2], expected[i][2]) << "point " << i;
  }
  for (size_t i = 0; i < size_t(w) * h; ++i)
    lit += image.rgba[i * 4] + image.rgba[i * 4 + 1] + image.rgba[i * 4 + 2] > 0;
  // Three 3x3-pixel squares, nothing else.
  EXPECT_EQ(lit, 27u);
}

TEST_P(Render, NearerPointWins) {
  auto ctx = context();
  // Same ray, red at 5 m, green at 20 m; drawn far-first and near-first in two clouds.
  Camera camera;
  camera.look_at(z_up_to_y_up({0, 0, 0}), z_up_to_y_up({0, 1, 0}));
  for (bool near_first : {false, true}) {
    auto cloud = near_first ? make_cloud({{0, 5, 0}, {0, 20, 0}}, {{255, 0, 0}, {0, 255, 0}})
                            : make_cloud({{0, 20, 0}, {0, 5, 0}}, {{0, 255, 0}, {255, 0, 0}});
    auto image = render(*ctx, cloud, camera, 5.0f);
    const uint8_t* p = pixel(image, 80, 60);
    EXPECT_EQ(p[0], 255) << "near_first=" << near_first;
    EXPECT_EQ(p[1], 0) << "near_first=" << near_first;
  }
}

namespace {

// The precision baseline without camera-relative rendering: positions made absolute in float32
// on the CPU (one chunk at the world origin), so the GPU applies the full view-projection,
// translation included, in float. At 6.4e6 m float32 resolves 0.5 m: millimetre detail is lost.
pc::PointCloud float_only_cloud(const pc::PointCloud& cloud) {
  pc::PointCloud flat = cloud;
  flat.chunks.clear();
  flat.chunks.emplace_back();
  pc::PointChunk& out = flat.chunks.back();
  out.origin = glm::dvec3(0.0);
  for (const pc::PointChunk& chunk : cloud.chunks)
    for (auto v : chunk.vertices) {
      glm::vec3 world(chunk.origin + glm::dvec3(v.x, v.y, v.z));
      v.x = world.x;
      v.y = world.y;
      v.z = world.z;
      out.vertices.push_back(v);
    }
  out.bounds = flat.world_bounds;
  out.spacing = 0.001;
  return flat;
}

struct MillimetreGrid {
  std::vector<glm::dvec3> points;
  std::vector<glm::u16vec3> colors;
  Camera camera;
};

// 20 x 20 points 1 mm apart around `base` (Z-up), seen from 5 cm.
MillimetreGrid millimetre_grid(glm::dvec3 base) {
  MillimetreGrid g;
  for (int j = 0; j < 20; ++j)
    for (int i = 0; i < 20; ++i) {
      g.points.push_back(base + glm::dvec3((i - 10) * 0.001, 0.0, (j - 10) * 0.001));
      g.colors.push_back({uint16_t(i * 12), uint16_t(j * 12), 200});
    }
  g.camera.near_plane = 0.001;
  g.camera.look_at(z_up_to_y_up(base + glm::dvec3(0, -0.05, 0)), z_up_to_y_up(base));
  return g;
}

const glm::dvec3 kEcef(6378137.0 * 0.6, 6378137.0 * 0.5, 6378137.0 * 0.62);

}  // namespace

TEST_P(Render, EarthScaleCoordinatesRenderLikeTheOrigin) {
  // Camera-relative rendering (seed 000, section 5): a grid of points 1 mm apart seen from
  // 5 cm renders the same at the origin and 6.4e6 m away (ECEF magnitude).
  auto ctx = context();
  auto scene_at = [&](glm::dvec3 base) {
    auto g = millimetre_grid(base);
    return render(*ctx, make_cloud(g.points, g.colors), g.camera, 2.0f);
  };
  auto at_origin = scene_at({0, 0, 0});
  auto at_earth = scene_at(kEcef);
  auto stats = test::coverage_stats(at_origin, std::array<uint8_t, 3>{0, 0, 0}.data());
  EXPECT_GT(stats.coverage, 0.05);
  // Tolerance: at most 1% of pixels may differ by more than 2 levels (float rounding of the
  // sub-millimetre offsets may move a point edge by one pixel).
  EXPECT_LT(test::differing_fraction(at_origin, at_earth, 2), 0.01);
}

TEST_P(Render, FloatOnlyPathFailsAtEarthScale) {
  // The same grid through the float-only path: fine at the origin (so the helper itself is
  // right), wrecked at ECEF magnitude.
  auto ctx = context();
  auto origin = millimetre_grid({0, 0, 0});
  auto reference = render(*ctx, make_cloud(origin.points, origin.colors), origin.camera, 2.0f);
  auto float_origin =
      render(*ctx, float_only_cloud(make_cloud(origin.points, origin.colors)), origin.camera, 2.0f);
  EXPECT_LT(test::differing_fraction(reference, float_origin, 2), 0.01);

  auto earth = millimetre_grid(kEcef);
  auto float_earth =
      render(*ctx, float_only_cloud(make_cloud(earth.points, earth.colors)), earth.camera, 2.0f);
  const uint8_t black[3] = {0, 0, 0};
  double covered = test::coverage_stats(reference, black).coverage;
  double covered_float = test::coverage_stats(float_earth, black).coverage;
  // Tolerance: the images must differ a lot: most of the grid's pixels (at least half of the
  // reference's coverage) change, whether the grid collapses to a few 0.5 m-quantised spots or
  // smears across the view.
  EXPECT_GT(test::differing_fraction(reference, float_earth, 2), 0.5 * covered)
      << "coverage " << covered << " vs float-only " << covered_float;
}

TEST_P(Render, AutzenShowsAllPointsInTheirColours) {
  STIPPLE_REQUIRE_DATA(path, "las/autzen_trim.las");
  auto ctx = context();
  pc::LoadOptions options;
  options.progress = false;
  auto cloud = pc::load_point_cloud({path}, options);
  ASSERT_EQ(cloud.point_count, 110000u);
  // The data's own mean colour (8-bit values stored in 16-bit fields).
  size_t colored = 0;
  const auto data_mean = test::mean_rgb(path, &colored);
  ASSERT_EQ(colored, 110000u);
  const uint32_t w = 640, h = 360;
  Camera camera = frame_box(cloud.world_bounds, double(w) / h);
  auto gpu_cloud = pc::upload_point_cloud(*ctx, cloud);
  EXPECT_EQ(gpu_cloud.point_count, 110000u);
  auto image = render(*ctx, cloud, camera, pc::auto_point_size(cloud, camera, h), w, h);
  auto stats = test::coverage_stats(image, std::array<uint8_t, 3>{0, 0, 0}.data(), 0);
  EXPECT_GT(stats.coverage, 0.10);
  EXPECT_LT(stats.coverage, 0.5);
  // Tolerance: covered pixels average within 8 levels of the data's mean per channel.
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(stats.mean[c], data_mean[c], 8.0) << "channel " << c;
}

INSTANTIATE_TEST_SUITE_P(Backends, Render, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
