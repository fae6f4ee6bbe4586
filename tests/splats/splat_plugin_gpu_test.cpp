// SplatPlugin through the engine: splats with the point cloud plugin's points in one frame
// (the points hide the splat behind them, not the one in front), and splats alone (the frame is
// cleared to the background first), on both WebGPU implementations.
#include <gtest/gtest.h>

#include <memory>
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

gpu::Image render(const std::string& backend, bool with_points) {
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
  splat_plugin.sets.push_back(two_splats());
  splat_plugin.settings.background = {0.0f, 0.0f, 0.0f};
  engine.add_plugin(std::move(splat_plugin));
  engine.add_plugin(HeadlessTargetPlugin{kWidth, kHeight, "", 0});
  std::vector<gpu::Image> frames;
  engine.render().insert_resource(
      FrameCapture{[&frames](uint64_t, const gpu::Image& image) { frames.push_back(image); }});
  Camera camera;
  camera.look_at({0, 0, 6}, {0, 0, 0});
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

INSTANTIATE_TEST_SUITE_P(Backends, SplatPluginTest, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });

}  // namespace
