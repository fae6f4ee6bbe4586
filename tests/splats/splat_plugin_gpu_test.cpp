// SplatPlugin through the engine: splats with the point cloud plugin's points in one frame
// (the points hide the splat behind them, not the one in front), splats alone (the frame is
// cleared to the background first), and a close-up whose kept frame the tile rasterizer draws
// whole (drawn again once its pair buffers have grown), on both WebGPU implementations.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <memory>
#include <random>
#include <vector>

#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/splats/splat_plugin.hpp"

using namespace stipple;

namespace {

constexpr uint32_t kWidth = 160, kHeight = 120;

std::shared_ptr<const pc::PointCloud> red_wall() {
  auto cloud = std::make_shared<pc::PointCloud>();
  pc::PointChunk chunk;
  for (int iy = 0; iy <= 80; ++iy)
    for (int ix = 0; ix <= 60; ++ix) {
      const float x = -3.0f + 0.05f * float(ix), y = -2.0f + 0.05f * float(iy);
      chunk.vertices.push_back({x, y, 0.0f, 0xff0000ffu, 0u});
      chunk.bounds.extend(glm::dvec3(x, y, 0.0));
    }
  chunk.spacing = 0.05;
  cloud->world_bounds = chunk.bounds;
  cloud->source_bounds = chunk.bounds;
  cloud->point_count = chunk.vertices.size();
  cloud->attributes.has_rgb = true;
  cloud->chunks.push_back(std::move(chunk));
  return cloud;
}

// A green splat in front of the wall, a blue one behind it.
std::shared_ptr<const io::SplatSet> two_splats() {
  auto set = std::make_shared<io::SplatSet>();
  auto add = [&](glm::vec3 p, glm::vec3 color) {
    set->positions.push_back(p);
    set->scales.push_back({0.12f, 0.12f, 0.12f});
    set->rotations.push_back({0, 0, 0, 1});
    set->opacities.push_back(1.0f);
    set->sh_dc.push_back((color - 0.5f) / 0.28209479177387814f);
  };
  add({-1.5f, 0.8f, 1.0f}, {0, 1, 0});
  add({-1.5f, -0.8f, -1.0f}, {0, 0, 1});
  return set;
}

// A close-up's few hundred large, faint splats: each covers much of the view, so the frame
// wants far more (tile, splat) pairs than the tile rasterizer's first guess of 4 a splat.
std::shared_ptr<const io::SplatSet> close_up() {
  auto set = std::make_shared<io::SplatSet>();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int i = 0; i < 400; ++i) {
    set->positions.push_back({u(rng) * 1.5f - 0.75f, u(rng) - 0.5f, u(rng) - 0.5f});
    set->scales.push_back({0.4f + 0.4f * u(rng), 0.4f + 0.4f * u(rng), 0.1f + 0.2f * u(rng)});
    set->rotations.push_back(
        glm::normalize(glm::vec4(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f)));
    set->opacities.push_back(0.02f + 0.08f * u(rng));
    set->sh_dc.push_back({u(rng) * 3 - 1.5f, u(rng) * 3 - 1.5f, u(rng) * 3 - 1.5f});
  }
  return set;
}

gpu::Image render(const std::string& backend, bool with_points,
                  std::shared_ptr<const io::SplatSet> set = two_splats(),
                  splats::SplatRasterizer rasterizer = splats::SplatRasterizer::Quads,
                  const glm::dvec3& eye = {0, 0, 6}, uint32_t width = kWidth,
                  uint32_t height = kHeight) {
  Engine engine;
  engine.add_plugins(TransformPlugin{}, CameraPlugin{});
  GpuPlugin gpu;
  gpu.options.backend = backend;
  engine.add_plugin(std::move(gpu));
  engine.add_plugin(RenderGraphPlugin{});
  if (with_points) {
    pc::PointCloudPlugin points;
    points.inputs.points = red_wall();
    points.inputs.progress = false;
    points.settings.render.color = pc::ColorMode::Rgb;
    points.settings.render.point_size = 6.0f;
    points.settings.render.edl = false;
    engine.add_plugin(std::move(points));
  }
  splats::SplatPlugin splat_plugin;
  splat_plugin.sets.push_back(std::move(set));
  splat_plugin.settings.background = {0.0f, 0.0f, 0.0f};
  splat_plugin.settings.rasterizer = rasterizer;
  engine.add_plugin(std::move(splat_plugin));
  engine.add_plugin(HeadlessTargetPlugin{width, height, "", 0});
  std::vector<gpu::Image> frames;
  engine.render().insert_resource(
      FrameCapture{[&frames](uint64_t, const gpu::Image& image) { frames.push_back(image); }});
  Camera camera;
  camera.look_at(eye, {0, 0, 0});
  engine.main().emplace<Camera>(engine.main().create(), camera);
  engine.run(1);
  engine.shutdown();
  EXPECT_EQ(frames.size(), 1u);
  return frames.empty() ? gpu::Image{} : frames[0];
}

glm::ivec3 at(const gpu::Image& image, glm::vec3 p) {
  Camera camera;
  camera.look_at({0, 0, 6}, {0, 0, 0});
  const glm::dvec4 c =
      camera.view_projection(double(kWidth) / kHeight) * glm::dvec4(glm::dvec3(p), 1.0);
  const int x = int((c.x / c.w * 0.5 + 0.5) * kWidth), y = int((0.5 - c.y / c.w * 0.5) * kHeight);
  const uint8_t* px = &image.rgba[(size_t(y) * kWidth + size_t(x)) * 4];
  return {px[0], px[1], px[2]};
}

class SplatPluginTest : public ::testing::TestWithParam<std::string> {};

TEST_P(SplatPluginTest, SplatsAndPointsOccludeInOneFrame) {
  const gpu::Image image = render(GetParam(), true);
  ASSERT_EQ(image.width, kWidth);
  const glm::ivec3 front = at(image, {-1.5f, 0.8f, 1.0f});
  const glm::ivec3 behind = at(image, {-1.5f, -0.8f, -1.0f});
  EXPECT_GT(front.g, 200) << "the splat in front of the points shows";
  EXPECT_LT(front.r, 60);
  EXPECT_GT(behind.r, 200) << "the points hide the splat behind them";
  EXPECT_LT(behind.b, 60);
}

TEST_P(SplatPluginTest, SplatsAloneOverTheBackground) {
  const gpu::Image image = render(GetParam(), false);
  ASSERT_EQ(image.width, kWidth);
  EXPECT_GT(at(image, {-1.5f, 0.8f, 1.0f}).g, 200);
  EXPECT_GT(at(image, {-1.5f, -0.8f, -1.0f}).b, 200);
  const glm::ivec3 corner(image.rgba[0], image.rgba[1], image.rgba[2]);
  EXPECT_EQ(corner, glm::ivec3(0, 0, 0)) << "cleared to the background";
}

TEST_P(SplatPluginTest, TileRasterizerKeepsACloseUpWhole) {
  // The captured first frame wants about 60 times the pairs its buffers first hold: it is drawn
  // again, grown, before it is kept, and then equals the quads' frame but for the quads' 8-bit
  // blending of 400 faint layers (measured on lavapipe: mean 2.15 levels, max 12; the first
  // frame kept as drawn, without the farthest splats' pairs: mean 5.4, max 27).
  const glm::dvec3 eye(0.2, 0.3, 2.5);
  const gpu::Image tiles =
      render(GetParam(), false, close_up(), splats::SplatRasterizer::Tiles, eye, 320, 240);
  const gpu::Image quads =
      render(GetParam(), false, close_up(), splats::SplatRasterizer::Quads, eye, 320, 240);
  ASSERT_EQ(tiles.rgba.size(), quads.rgba.size());
  ASSERT_FALSE(tiles.rgba.empty());
  double sum = 0;
  int max = 0;
  for (size_t i = 0; i < tiles.rgba.size(); ++i) {
    if (i % 4 == 3) continue;
    const int d = std::abs(int(tiles.rgba[i]) - int(quads.rgba[i]));
    sum += d;
    max = std::max(max, d);
  }
  const double mean = sum / double(tiles.rgba.size() / 4 * 3);
  std::printf("tiles against quads: mean %.3f levels, max %d\n", mean, max);
  EXPECT_LT(mean, 3.0);
  EXPECT_LE(max, 18);
}

INSTANTIATE_TEST_SUITE_P(Backends, SplatPluginTest, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });

}  // namespace
