// The engine's rendering plugins end to end: the same scene drawn through the engine with the
// render world on its own thread and on the main thread gives the same frames, bit for bit.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;

namespace {

class EngineRender : public ::testing::TestWithParam<std::string> {};

// Six frames of the built-in scene with a camera circling it (driven by the fixed-step clock)
// and a point budget, so the chunk choice changes from frame to frame too.
std::vector<gpu::Image> render_frames(const std::string& backend, bool pipelined) {
  Engine engine;
  TimePlugin time;
  time.fixed_delta = 1.0 / 30.0;
  engine.add_plugins(time, TransformPlugin{}, CameraPlugin{});
  if (pipelined) engine.add_plugin(PipelinedRenderingPlugin{});
  GpuPlugin gpu;
  gpu.options.backend = backend;
  engine.add_plugin(std::move(gpu));
  engine.add_plugin(RenderGraphPlugin{});
  pc::PointCloudPlugin points;
  points.inputs.scene.point_count = 40000;
  points.inputs.chunk_points = 2048;
  points.inputs.progress = false;
  points.settings.budget = 30000;
  points.settings.render.point_size = 3.0f;
  engine.add_plugin(std::move(points));
  engine.add_plugin(HeadlessTargetPlugin{160, 120, "", 0});

  std::vector<gpu::Image> frames;  // filled on the render thread, read after shutdown()
  engine.render().insert_resource(
      FrameCapture{[&frames](uint64_t, const gpu::Image& image) { frames.push_back(image); }});
  Registry& main = engine.main();
  const Aabb bounds = main.resource<pc::SceneInfo>().world_bounds;
  main.emplace<Camera>(main.create(), frame_box(bounds, 160.0 / 120.0));
  engine.add_system(
      MainStage::Update,
      [bounds](Registry& r) {
        double angle = 20.0 + 40.0 * r.resource<Time>().elapsed_seconds;
        r.view<Camera>().each([&](Camera& c) { c = frame_box(bounds, 160.0 / 120.0, angle); });
      },
      "circle_camera");
  engine.run(6);
  engine.shutdown();
  EXPECT_EQ(engine.render().resource<RenderStats>().frames, 6u);
  return frames;
}

std::string png_bytes(const gpu::Image& image, const std::string& name) {
  auto path = std::filesystem::temp_directory_path() /
              ("stipple_engine_render_" + std::to_string(::getpid()) + "_" + name + ".png");
  gpu::write_png(path, image);
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::filesystem::remove(path);
  return bytes;
}

}  // namespace

TEST_P(EngineRender, PipelinedAndSingleThreadedFramesAreIdentical) {
  auto single = render_frames(GetParam(), false);
  auto pipelined = render_frames(GetParam(), true);
  ASSERT_EQ(single.size(), 6u);
  ASSERT_EQ(pipelined.size(), 6u);
  const uint8_t bg[3] = {18, 20, 26};
  for (size_t i = 0; i < single.size(); ++i) {
    EXPECT_GT(test::coverage_stats(single[i], bg, 1).coverage, 0.1) << "frame " << i;
    EXPECT_EQ(png_bytes(single[i], "single"), png_bytes(pipelined[i], "pipelined"))
        << "frame " << i;
    if (i > 0) {  // the camera moves: frames differ from each other
      EXPECT_GT(test::differing_fraction(single[i], single[i - 1], 2), 0.01) << "frame " << i;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, EngineRender, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
