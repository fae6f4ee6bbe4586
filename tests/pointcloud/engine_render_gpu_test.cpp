// The engine's rendering plugins end to end: the same scene drawn through the engine with the
// render world on its own thread and on the main thread gives the same frames, bit for bit; and
// into a target whose texture is taken only in Draw, after every Queue system (RenderTarget::
// acquire, as the page's canvas is), too.
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
#include "stipple/engine/viewport.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;

namespace {

class EngineRender : public ::testing::TestWithParam<std::string> {};

// Render-world resource of LateTargetPlugin: its texture, and how often the frame's Queue systems
// had run and the texture was asked for; `refuse_odd`: the 2nd, 4th... request is refused.
struct LateTarget {
  gpu::Texture color;
  gpu::TextureView view;
  uint64_t queued = 0, acquired = 0, acquired_after_queue = 0;
  bool refuse_odd = false;
};

// An offscreen RGBA8 target handed over only when the graph is about to run, as the page's
// canvas is (its texture expires when the page's thread yields): the same texture, usage and
// format as HeadlessTargetPlugin's, so the frames must be the same.
struct LateTargetPlugin {
  uint32_t width = 0, height = 0;
  bool refuse_odd = false;
  void build(Engine& engine) {
    engine.main().insert_resource(Viewport{width, height});
    engine.render().insert_resource(LateTarget{.refuse_odd = refuse_odd});
    engine.add_system(
        RenderStage::Prepare,
        [w = width, h = height](Registry& render) {
          RenderTarget target;
          target.width = w;
          target.height = h;
          target.format = WGPUTextureFormat_RGBA8Unorm;
          target.usage = WGPUTextureUsage_RenderAttachment | WGPUTextureUsage_CopySrc |
                         WGPUTextureUsage_StorageBinding;
          target.acquire = [&render](RenderTarget& late) {
            auto& t = render.resource<LateTarget>();
            if (++t.acquired == t.queued) ++t.acquired_after_queue;
            if (t.refuse_odd && t.acquired % 2 == 0) return false;
            if (!t.color) {
              t.color = gpu::create_texture_2d(*render.resource<GpuContext>(), late.width,
                                               late.height, late.format, late.usage, "late");
              t.view = gpu::create_view(t.color);
            }
            late.texture = t.color.get();
            late.view = t.view.get();
            return true;
          };
          render.insert_resource(std::move(target));
        },
        "late_target");
    // After the scene's Queue systems (its plugin was added first).
    engine.add_system(
        RenderStage::Queue, [](Registry& render) { ++render.resource<LateTarget>().queued; },
        "count_queue");
  }
};

enum class Target { Headless, Late, LateRefusingOdd };

// Six frames of the built-in scene with a camera circling it (driven by the fixed-step clock)
// and a point budget, so the chunk choice changes from frame to frame too.
std::vector<gpu::Image> render_frames(const std::string& backend, bool pipelined,
                                      Target kind = Target::Headless) {
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
  if (kind == Target::Headless)
    engine.add_plugin(HeadlessTargetPlugin{160, 120, "", 0});
  else
    engine.add_plugin(LateTargetPlugin{160, 120, kind == Target::LateRefusingOdd});

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
  // A refused texture skips its frame: no graph runs, no frame is counted or captured.
  const uint64_t drawn = kind == Target::LateRefusingOdd ? 3 : 6;
  EXPECT_EQ(engine.render().resource<RenderStats>().frames, drawn);
  if (kind != Target::Headless) {
    const auto& late = engine.render().resource<LateTarget>();
    EXPECT_EQ(late.acquired, 6u);
    EXPECT_EQ(late.acquired_after_queue, 6u) << "the texture was asked for before Queue ended";
  }
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

TEST_P(EngineRender, ALateTargetIsDrawnAsTheHeadlessOneAndMaySkipFrames) {
  auto headless = render_frames(GetParam(), false);
  auto late = render_frames(GetParam(), false, Target::Late);
  ASSERT_EQ(headless.size(), 6u);
  ASSERT_EQ(late.size(), 6u);
  for (size_t i = 0; i < late.size(); ++i)
    EXPECT_EQ(png_bytes(headless[i], "headless"), png_bytes(late[i], "late")) << "frame " << i;
  // The first, third and fifth frames drawn, with the cameras of those frames.
  auto skipping = render_frames(GetParam(), false, Target::LateRefusingOdd);
  ASSERT_EQ(skipping.size(), 3u);
  for (size_t i = 0; i < skipping.size(); ++i)
    EXPECT_EQ(png_bytes(headless[2 * i], "headless"), png_bytes(skipping[i], "skipping"))
        << "frame " << 2 * i;
}

INSTANTIATE_TEST_SUITE_P(Backends, EngineRender, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
