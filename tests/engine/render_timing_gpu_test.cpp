// The frame graph's pass times through the engine (RenderGraphPlugin), for both WebGPU
// implementations: frames that wait for the GPU have their own times as soon as they end; frames
// that do not (the web page's mode) get theirs a few frames later, under the names of their own
// passes, and after a drain RenderStats holds every timed frame's, in frame order.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <tuple>
#include <vector>

#include "stipple/engine/engine.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"

using namespace stipple;

namespace {

// Render-world resource of NamedPassesPlugin: the passes of each drawn frame (by its number,
// 1 for the first), and the frames drawn so far.
struct NamedPasses {
  std::function<std::vector<std::string>(uint64_t frame)> names;
  uint64_t drawn = 0;
};

// Adds one render pass per name to each frame's graph, each clearing the target.
struct NamedPassesPlugin {
  std::function<std::vector<std::string>(uint64_t frame)> names;
  void build(Engine& engine) {
    engine.render().insert_resource(NamedPasses{names, 0});
    engine.add_system(
        RenderStage::Queue,
        [](Registry& render) {
          auto& fg = render.resource<FrameGraph>();
          if (!fg.active) return;
          auto& passes = render.resource<NamedPasses>();
          for (const std::string& name : passes.names(++passes.drawn))
            fg.graph
                .add_pass(name, gpu::PassKind::Render,
                          [](gpu::PassContext& pc) {
                            WGPURenderPassColorAttachment color =
                                WGPU_RENDER_PASS_COLOR_ATTACHMENT_INIT;
                            color.view = pc.view("color");
                            color.loadOp = WGPULoadOp_Clear;
                            color.storeOp = WGPUStoreOp_Store;
                            color.clearValue = {0.2, 0.4, 0.6, 1.0};
                            WGPURenderPassDescriptor desc = WGPU_RENDER_PASS_DESCRIPTOR_INIT;
                            desc.colorAttachmentCount = 1;
                            desc.colorAttachments = &color;
                            gpu::RenderPassEncoder pass = pc.begin_render_pass(desc);
                            wgpuRenderPassEncoderEnd(pass.get());
                          })
                .write("color");
        },
        "named_passes");
  }
};

struct Mode {
  bool wait_for_gpu = true;
  uint32_t timer_slots = 4;
  bool pipelined = false;
  uint32_t max_frames_in_flight = 0;
};

// (backend, pipelined)
class RenderTiming : public ::testing::TestWithParam<std::tuple<std::string, bool>> {
 protected:
  void SetUp() override {
    // Timestamp queries are optional: without them there is nothing to check here.
    gpu::ContextOptions options;
    options.backend = std::get<0>(GetParam());
    if (!gpu::create_context(options)->has_feature(WGPUFeatureName_TimestampQuery))
      GTEST_SKIP() << "no timestamp queries on this adapter";
  }

  void make(Engine& engine, const Mode& setup,
            std::function<std::vector<std::string>(uint64_t)> names) {
    if (std::get<1>(GetParam())) engine.add_plugin(PipelinedRenderingPlugin{});
    GpuPlugin gpu;
    gpu.options.backend = std::get<0>(GetParam());
    engine.add_plugin(std::move(gpu));
    RenderGraphPlugin graph;
    graph.keep_history = true;
    graph.wait_for_gpu = setup.wait_for_gpu;
    graph.timer_slots = setup.timer_slots;
    graph.max_frames_in_flight = setup.max_frames_in_flight;
    engine.add_plugin(std::move(graph));
    engine.add_plugin(NamedPassesPlugin{std::move(names)});
    engine.add_plugin(HeadlessTargetPlugin{32, 32, "", 0});
  }
};

void expect_valid_times(const RenderStats& stats) {
  for (const auto& [name, times] : stats.history)
    for (double ms : times) EXPECT_TRUE(std::isfinite(ms) && ms >= 0.0) << name << ": " << ms;
  for (double ms : stats.gpu_ms) EXPECT_TRUE(std::isfinite(ms) && ms >= 0.0) << ms;
}

}  // namespace

// The default: each frame ends with its own times (what `stipple render --stats` and the bench
// commands read right after a frame).
TEST_P(RenderTiming, FramesThatWaitHaveTheirOwnTimes) {
  Engine engine;
  make(engine, {}, [](uint64_t) { return std::vector<std::string>{"a", "b"}; });
  for (uint64_t frame = 1; frame <= 3; ++frame) {
    engine.update();
    engine.wait_for_render();
    const auto& stats = engine.render().resource<RenderStats>();
    ASSERT_EQ(stats.frames, frame);
    EXPECT_EQ(stats.pass_ms_frame, frame);
    EXPECT_EQ(stats.pass_ms.size(), 2u);
    EXPECT_EQ(stats.gpu_ms.size(), frame);
  }
  engine.shutdown();
  const auto& stats = engine.render().resource<RenderStats>();
  EXPECT_EQ(stats.gpu_frames, (std::vector<uint64_t>{1, 2, 3}));
  EXPECT_EQ(stats.history.at("a").size(), 3u);
  EXPECT_EQ(stats.untimed_frames, 0u);
  expect_valid_times(stats);
}

// Without waiting, with a slot for every frame: after N frames and a drain, every pass has N
// times and every frame its total, in frame order.
TEST_P(RenderTiming, FramesThatDoNotWaitHaveEveryTimeAfterADrain) {
  constexpr uint64_t kFrames = 6;
  Engine engine;
  make(engine, {.wait_for_gpu = false, .timer_slots = kFrames}, [](uint64_t) {
    return std::vector<std::string>{"a", "b"};
  });
  engine.run(kFrames);
  drain_pass_times(engine);
  const auto& stats = engine.render().resource<RenderStats>();
  EXPECT_EQ(stats.frames, kFrames);
  EXPECT_EQ(stats.untimed_frames, 0u);
  EXPECT_EQ(stats.gpu_frames, (std::vector<uint64_t>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(stats.gpu_ms.size(), kFrames);
  EXPECT_EQ(stats.history.at("a").size(), kFrames);
  EXPECT_EQ(stats.history.at("b").size(), kFrames);
  EXPECT_EQ(stats.pass_ms_frame, kFrames);
  EXPECT_EQ(stats.wall_ms.size(), kFrames);
  expect_valid_times(stats);
  engine.shutdown();
}

// Frames that do not wait for the GPU still end with at most max_frames_in_flight of them
// unfinished on it (as a swapchain bounds them): one means each frame ends with its work done,
// two that the one before it is. Unbounded (0), frames are not tracked at all.
TEST_P(RenderTiming, FramesInFlightAreBounded) {
  for (uint32_t bound : {1u, 2u, 0u}) {
    SCOPED_TRACE("max frames in flight " + std::to_string(bound));
    Engine engine;
    make(engine, {.wait_for_gpu = false, .timer_slots = 4, .max_frames_in_flight = bound},
         [](uint64_t) { return std::vector<std::string>{"a"}; });
    for (uint64_t frame = 1; frame <= 5; ++frame) {
      engine.update();
      engine.wait_for_render();  // the frame has ended (pipelined: on the render thread)
      const gpu::FrameFence& fence = engine.render().resource<FrameGraph>().fence;
      if (bound == 0) {
        EXPECT_EQ(fence.submitted(), 0u);
        continue;
      }
      EXPECT_EQ(fence.submitted(), frame);
      EXPECT_GE(fence.completed() + bound, frame + 1) << "frame " << frame;
    }
    drain_pass_times(engine);
    engine.shutdown();
  }
}

// The pass list changes every frame (a on odd frames, b and c on even ones, "both" always, each
// at a different query index from one frame to the next): each frame's times are filed under its
// own passes, whenever they arrive. With two slots, frames that find both in flight go untimed;
// the ones timed are counted exactly.
TEST_P(RenderTiming, TimesArriveUnderTheirOwnFramesPasses) {
  for (uint32_t slots : {12u, 2u}) {
    SCOPED_TRACE("slots " + std::to_string(slots));
    constexpr uint64_t kFrames = 12;
    Engine engine;
    make(engine, {.wait_for_gpu = false, .timer_slots = slots}, [](uint64_t frame) {
      return frame % 2 == 1 ? std::vector<std::string>{"a", "both"}
                            : std::vector<std::string>{"both", "b", "c"};
    });
    engine.run(kFrames);
    drain_pass_times(engine);
    const auto& stats = engine.render().resource<RenderStats>();
    ASSERT_EQ(stats.frames, kFrames);
    const uint64_t timed = stats.gpu_frames.size();
    EXPECT_EQ(timed + stats.untimed_frames, kFrames);
    if (slots >= kFrames) {
      EXPECT_EQ(timed, kFrames);
    }
    EXPECT_GE(timed, std::min<uint64_t>(slots, kFrames));  // the first frames find a free slot
    uint64_t odd = 0;
    for (size_t i = 0; i < timed; ++i) {
      if (i > 0) {
        EXPECT_LT(stats.gpu_frames[i - 1], stats.gpu_frames[i]) << "out of order";
      }
      odd += stats.gpu_frames[i] % 2;
    }
    auto count = [&stats](const char* pass) {
      auto it = stats.history.find(pass);
      return it == stats.history.end() ? size_t(0) : it->second.size();
    };
    EXPECT_EQ(count("a"), odd);
    EXPECT_EQ(count("b"), timed - odd);
    EXPECT_EQ(count("c"), timed - odd);
    EXPECT_EQ(count("both"), timed);
    expect_valid_times(stats);
    engine.shutdown();
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, RenderTiming,
                         ::testing::Combine(::testing::Values("dawn", "wgpu"), ::testing::Bool()),
                         [](const auto& info) {
                           return std::get<0>(info.param) +
                                  (std::get<1>(info.param) ? "_pipelined" : "");
                         });
