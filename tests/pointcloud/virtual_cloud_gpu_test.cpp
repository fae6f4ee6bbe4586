// The virtualized point cloud (seed 002) in a headless engine over a camera flight: the LoD's
// selection is loaded asynchronously into per-pointlet host buffers within the host budget,
// loaded prefixes are reused (only missing points are read again), and once settled the frame
// draws what the LoD asked for, or all the budget allows; the pipelined engine (render world on
// its own thread) draws the same images as the sequential one.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "sanitizer.hpp"
#include "scene_las.hpp"

#include "stipple/core/error.hpp"
#include "stipple/core/memory.hpp"
#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

class VirtualCloud : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("stipple-virtual-cloud-" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    test::write_scene_las(dir_ / "scene.las", 200000);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static fs::path dir_;

  // Runs frames until the selection settles (at most 400), checking the budgets every frame.
  static const pc::VirtualCloudStats& settle(Engine& engine, uint64_t host_budget, uint64_t bucket,
                                             uint64_t gpu_budget) {
    Registry& render = engine.render();
    for (int i = 0; i < 400; ++i) {
      engine.update();
      const auto& s = render.resource<pc::VirtualCloudStats>();
      EXPECT_LE(s.host_bytes, host_budget);
      EXPECT_LE(s.gpu_bytes, gpu_budget);
      EXPECT_LE(s.selected_points, bucket);
      EXPECT_LE(s.selected_points, s.desired_points);
      if (s.settled && s.selections > 0) return s;
      pc::wait_for_virtual_loads(engine.main().resource<pc::VirtualCloudHandle>(), 0.05);
    }
    ADD_FAILURE() << "the selection did not settle";
    return render.resource<pc::VirtualCloudStats>();
  }
};
fs::path VirtualCloud::dir_;

// A headless engine drawing the generated scan from its cache (m = 2000, B = 40,000) at
// 320x200 with the given budgets. process_over: a process budget of this much over what the
// process holds once the device is up (0: none), with 8 MiB staging slots. async: the selection
// on its own thread (the viewer's way).
void add_virtual_cloud(Engine& engine, const std::string& backend, const fs::path& dir,
                       uint64_t host_budget, uint64_t gpu_budget, uint64_t process_over,
                       bool async = false) {
  engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{});
  GpuPlugin gpu;
  gpu.options.backend = backend;
  engine.add_plugin(std::move(gpu));
  engine.add_plugin(RenderGraphPlugin{});
  const uint64_t process_budget = process_over > 0 ? resident_bytes() + process_over : 0;
  pc::VirtualPointCloudPlugin v;
  v.options.files = {dir / "scene.las"};
  v.options.cache_dir = dir / "cache";
  v.options.build.pointlets = 2000;
  v.options.build.progress = false;
  v.options.bucket = 40000;
  v.options.host_budget = host_budget;
  v.options.gpu_budget = gpu_budget;
  v.options.process_budget = process_budget;
  if (process_over > 0) v.options.staging_bytes = uint64_t(8) << 20;
  v.options.async_selection = async;
  engine.add_plugin(std::move(v));
  engine.add_plugin(HeadlessTargetPlugin{320, 200, "", 0});
}

}  // namespace

// The cache (200,000 points, 4 MB) is 13 times the smaller host budget.
TEST_P(VirtualCloud, FlightStaysInBudgetAndReusesLoadedPoints) {
  constexpr uint64_t kGpuBudget = uint64_t(8) << 20;
  // The small budget also with the selection on its own thread: the budgets hold every frame.
  for (const auto& [host_budget, async] :
       {std::pair{uint64_t(64) << 20, false}, std::pair{uint64_t(300000), false},
        std::pair{uint64_t(300000), true}}) {
    SCOPED_TRACE(host_budget);
    SCOPED_TRACE(async ? "async selection" : "selection in the frame");
    Engine engine;
    add_virtual_cloud(engine, GetParam(), dir_, host_budget, kGpuBudget, 0, async);
    Registry& main = engine.main();
    const Aabb box = main.resource<pc::SceneInfo>().world_bounds;
    const Entity camera_entity = main.create();
    main.emplace<Camera>(camera_entity, frame_box(box, 1.6));

    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    uint64_t desired_sum = 0;
    for (int step = 0; step < 6; ++step) {
      Camera c = step == 0 ? frame_box(box, 1.6)
                           : frame_box(box, 1.6, 360 * u(rng), 20 + 60 * u(rng), 20 + 40 * u(rng));
      main.get<Camera>(camera_entity) = c;
      const pc::VirtualCloudStats s = settle(engine, host_budget, 40000, kGpuBudget);
      desired_sum += s.desired_points;
      EXPECT_GT(s.desired_points, 0u);
      if (host_budget >= (uint64_t(64) << 20)) {
        // Room for everything: the frame draws exactly what the LoD asked for.
        EXPECT_EQ(s.selected_points, s.desired_points) << "step " << step;
      } else {
        // 300 kB hold 15,000 points: what is drawn is what fits.
        EXPECT_LE(s.selected_points, host_budget / sizeof(pc::PointletRecord));
        EXPECT_GT(s.selected_points, 0u);
      }
    }
    const auto& s = engine.render().resource<pc::VirtualCloudStats>();
    std::printf("host budget %llu B: peak %llu B of loaded points; GPU %llu B of %llu\n",
                static_cast<unsigned long long>(host_budget),
                static_cast<unsigned long long>(s.peak_host_bytes),
                static_cast<unsigned long long>(s.gpu_bytes),
                static_cast<unsigned long long>(kGpuBudget));
    EXPECT_GT(s.gpu_bytes, 40000u * 32);  // both frames' buffers of the bucket are counted
    if (host_budget >= (uint64_t(64) << 20)) {
      // Prefixes already loaded are not read again: a flight reads less than it draws (each
      // step's points read from scratch would be desired_sum, over-fetch included 1.25x).
      EXPECT_LT(s.points_read, desired_sum);
      EXPECT_GT(s.loads, 0u);
    }
    engine.shutdown();
  }
}

// A process budget under what the process holds before any point loads (its baseline) is an
// error that names the least budget that works.
TEST_P(VirtualCloud, AProcessBudgetUnderTheBaselineIsAnError) {
  Engine engine;
  // 16 MiB over what the process holds with its device up: less than the staging slots, the
  // margin and room for points need.
  try {
    add_virtual_cloud(engine, GetParam(), dir_, uint64_t(64) << 20, 0, uint64_t(16) << 20);
    ADD_FAILURE() << "the process budget was accepted";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("is below what this process needs"), std::string::npos) << what;
    // The minimum named is over the budget given.
    std::smatch given, least;
    ASSERT_TRUE(std::regex_search(what, given, std::regex("--host-memory (\\d+) MiB"))) << what;
    ASSERT_TRUE(std::regex_search(what, least, std::regex("at least (\\d+) MiB"))) << what;
    EXPECT_GT(std::stoull(least[1]), std::stoull(given[1])) << what;
  }
  engine.shutdown();
}

// A process budget over the baseline but short of what the points could take lowers what the
// points may take (measured after the first frame) below the host budget, and the loaded
// points keep to it.
TEST_P(VirtualCloud, AProcessBudgetLowersThePointsBudget) {
  if (test::kAddressSanitizer)
    GTEST_SKIP() << "resident memory under AddressSanitizer counts shadow memory and the "
                    "quarantine: the process budget is about the plain build";
  Engine engine;
  // 160 MiB over what the process holds with its device up: what the frames add, the staging
  // slots (16 MiB), the point store and the margin (32 MiB) leave the points less than the
  // 256 MiB host budget.
  constexpr uint64_t kHostBudget = uint64_t(256) << 20;
  add_virtual_cloud(engine, GetParam(), dir_, kHostBudget, 0, uint64_t(160) << 20);
  Registry& main = engine.main();
  const Aabb box = main.resource<pc::SceneInfo>().world_bounds;
  const Entity camera = main.create();
  main.emplace<Camera>(camera, frame_box(box, 1.6));
  for (int frame = 0; frame < 40; ++frame) {
    main.get<Camera>(camera) = frame_box(box, 1.6, 9.0 * frame, 40.0, 40.0);
    engine.update();
    pc::wait_for_virtual_loads(main.resource<pc::VirtualCloudHandle>(), 0.02);
  }
  const auto& s = engine.render().resource<pc::VirtualCloudStats>();
  EXPECT_GT(s.process_bytes, 0u);
  EXPECT_LT(s.host_budget, kHostBudget);
  EXPECT_LE(s.host_bytes, s.host_budget);
  EXPECT_GT(s.selected_points, 0u);
  engine.shutdown();
}

// Seed 000's pipelined mode (the render world draws frame N on its own thread while the main
// world builds N+1) changes when a frame is drawn, not what, and so does a selection on its own
// thread (the frames draw the last one until it is done): at each of three views, once the
// selection settled, sequential, pipelined and pipelined engines with the async selection draw
// byte-equal images.
TEST_P(VirtualCloud, PipelinedAndSequentialDrawTheSameImages) {
  std::vector<gpu::Image> images[3];
  for (const int mode : {0, 1, 2}) {
    const bool pipelined = mode > 0;
    SCOPED_TRACE(mode == 0 ? "sequential" : mode == 1 ? "pipelined" : "pipelined, async selection");
    Engine engine;
    if (pipelined) engine.add_plugin(PipelinedRenderingPlugin{});
    add_virtual_cloud(engine, GetParam(), dir_, uint64_t(64) << 20, 0, 0, mode == 2);
    Registry& main = engine.main();
    Registry& render = engine.render();
    const Aabb box = main.resource<pc::SceneInfo>().world_bounds;
    const Entity camera = main.create();
    main.emplace<Camera>(camera, frame_box(box, 1.6));
    for (int view = 0; view < 3; ++view) {
      main.get<Camera>(camera) =
          frame_box(box, 1.6, 30.0 + 110.0 * view, 30.0 + 10.0 * view, 45.0 - 10.0 * view);
      bool settled = false;
      for (int i = 0; i < 400 && !settled; ++i) {
        engine.update();
        engine.wait_for_render();  // the render world is idle: its resources may be read
        const auto& s = render.resource<pc::VirtualCloudStats>();
        settled = s.settled && s.selections > 0;
        if (!settled) pc::wait_for_virtual_loads(main.resource<pc::VirtualCloudHandle>(), 0.05);
      }
      EXPECT_TRUE(settled) << "view " << view;
      // The selections ran where the mode says.
      EXPECT_EQ(render.resource<pc::VirtualCloudStats>().async_select_ms > 0, mode == 2);
      auto image = std::make_shared<gpu::Image>();
      render.insert_resource(
          FrameCapture{[image](uint64_t, const gpu::Image& frame) { *image = frame; }});
      engine.update();
      engine.wait_for_render();
      render.insert_resource(FrameCapture{});
      ASSERT_EQ(image->width, 320u);
      images[mode].push_back(*image);
    }
    engine.shutdown();
  }
  for (const int mode : {1, 2})
    for (size_t view = 0; view < images[0].size(); ++view) {
      SCOPED_TRACE(mode);
      const gpu::Image &a = images[0][view], &b = images[mode][view];
      ASSERT_EQ(a.rgba.size(), b.rgba.size());
      size_t differing = 0, drawn = 0;
      for (size_t p = 0; p < a.rgba.size(); p += 4) {
        differing += !std::equal(&a.rgba[p], &a.rgba[p] + 4, &b.rgba[p]);
        drawn += !std::equal(&a.rgba[p], &a.rgba[p] + 3, &a.rgba[0]);  // not the corner's colour
      }
      EXPECT_EQ(differing, 0u) << "view " << view;
      EXPECT_GT(drawn, a.rgba.size() / 4 / 20) << "view " << view << ": hardly any points drawn";
    }
  // The views differ, so equal images are not an image that ignores the view.
  EXPECT_NE(images[0][0].rgba, images[0][1].rgba);
}

INSTANTIATE_TEST_SUITE_P(Backends, VirtualCloud, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
