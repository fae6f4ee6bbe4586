// TilesetPlugin end to end: a generated 4-level tileset streamed by the engine (headless) while
// the camera flies from far to near. Finer levels load as it approaches, resident memory stays
// within the budget, the last frame shows the data, and the render world on its own thread
// reaches the same final image as on the main thread.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/renderer/png.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "test_util.hpp"
#include "tiles_fixtures.hpp"
#include "tileset_engine.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

constexpr uint32_t kWidth = 160, kHeight = 120;
constexpr uint64_t kBudget = 1'000'000;  // bytes: about half of the 85 tiles

struct Step {
  uint32_t resident_tiles = 0, drawn_tiles = 0;
  uint64_t resident_points = 0, drawn_points = 0;
};

struct StreamRun {
  std::vector<Step> steps;  // after each camera position, once the streamer is idle
  uint64_t max_resident_bytes = 0, peak_resident_bytes = 0, errors = 0, evictions = 0;
  uint64_t gpu_points = 0;  // resident on the GPU after the last frame
  std::vector<gpu::Image> frames;
  bool all_idle = true;
};

StreamRun stream(const std::string& backend, bool pipelined, const fs::path& tileset) {
  StreamRun out;
  Engine engine;
  tiles3d::TilesetPlugin tiles;
  tiles.uri = tileset.string();
  tiles.streamer.threads = 2;
  tiles.streamer.traversal.memory_budget = kBudget;
  tiles.streamer.traversal.max_sse = 2.0;
  tiles.width = kWidth;
  tiles.height = kHeight;
  tiles.render.point_size = 3.0f;
  test::add_tileset_engine_plugins(engine, backend, pipelined, std::move(tiles), 1.0 / 30.0);
  engine.render().insert_resource(
      FrameCapture{[&out](uint64_t, const gpu::Image& image) { out.frames.push_back(image); }});

  Registry& main = engine.main();
  Entity camera = main.create();
  main.emplace<Camera>(camera);
  // Far to near over (300, 300, 0) of the 1000 m square (Z up), then across to (750, 750, 0)
  // near the ground: the tiles left behind are evicted to make room.
  const double path[][3] = {
      {300, 300, 8000}, {300, 300, 3000}, {300, 300, 1200}, {300, 300, 400}, {750, 750, 400}};
  for (const auto& p : path) {
    const double x = p[0], y = p[1], d = p[2];
    main.get<Camera>(camera).look_at(z_up_to_y_up({x, y - d, d * 0.6}), z_up_to_y_up({x, y, 0}));
    main.get<Camera>(camera).near_plane = 1.0;
    const bool idle = test::update_until_idle(engine, [&] {
      out.max_resident_bytes =
          std::max(out.max_resident_bytes, main.resource<tiles3d::TilesetStats>().resident_bytes);
    });
    out.all_idle = out.all_idle && idle;
    const auto& stats = main.resource<tiles3d::TilesetStats>();
    out.steps.push_back(
        {stats.resident_tiles, stats.drawn_tiles, stats.resident_points, stats.drawn_points});
  }
  const auto& stats = main.resource<tiles3d::TilesetStats>();
  out.peak_resident_bytes = stats.peak_resident_bytes;
  out.errors = stats.errors;
  out.evictions = stats.evictions;
  engine.shutdown();
  out.gpu_points = engine.render().resource<RenderStats>().points_total;
  return out;
}

class TilesetStreamGpu : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(TilesetStreamGpu, FollowsTheCameraWithinTheBudget) {
  fs::path dir = fs::temp_directory_path() /
                 ("stipple_tileset_stream_" + std::to_string(::getpid()) + "_" + GetParam());
  fs::remove_all(dir);
  int tiles = test::write_grid_tileset(dir, 4, 1000);  // 85 tiles x 1000 points
  ASSERT_EQ(tiles, 85);

  StreamRun single = stream(GetParam(), false, dir / "tileset.json");
  StreamRun piped = stream(GetParam(), true, dir / "tileset.json");
  fs::remove_all(dir);

  for (const StreamRun* run : {&single, &piped}) {
    SCOPED_TRACE(run == &single ? "single thread" : "pipelined");
    for (const Step& s : run->steps)
      std::printf("resident %u tiles %llu points, drawn %u tiles %llu points\n", s.resident_tiles,
                  (unsigned long long)s.resident_points, s.drawn_tiles,
                  (unsigned long long)s.drawn_points);
    std::printf("frames %zu, peak %llu bytes, %llu evictions\n", run->frames.size(),
                (unsigned long long)run->peak_resident_bytes, (unsigned long long)run->evictions);
    EXPECT_TRUE(run->all_idle);
    EXPECT_EQ(run->errors, 0u);
    ASSERT_EQ(run->steps.size(), 5u);
    // Finer levels load as the camera approaches (steps 0-3).
    EXPECT_GE(run->steps[0].drawn_tiles, 1u);
    for (size_t i = 1; i < 4; ++i) {
      EXPECT_GT(run->steps[i].drawn_tiles, run->steps[i - 1].drawn_tiles) << "step " << i;
      EXPECT_GT(run->steps[i].resident_tiles, run->steps[i - 1].resident_tiles) << "step " << i;
      EXPECT_GT(run->steps[i].resident_points, run->steps[i - 1].resident_points) << "step " << i;
    }
    // Moving across (step 4) evicts tiles left behind; the budget holds on every frame.
    EXPECT_GT(run->evictions, 0u);
    // GPU data of evicted tiles is freed: the GPU holds at most the resident tiles' points.
    EXPECT_GT(run->gpu_points, 0u);
    EXPECT_LE(run->gpu_points, run->steps.back().resident_points);
    EXPECT_LE(run->max_resident_bytes, kBudget);
    EXPECT_LE(run->peak_resident_bytes, kBudget);
    EXPECT_GT(run->peak_resident_bytes, 0u);
    // The last frame shows the data.
    ASSERT_FALSE(run->frames.empty());
    const uint8_t bg[3] = {18, 20, 26};
    EXPECT_GT(test::coverage_stats(run->frames.back(), bg, 1).coverage, 0.01);
  }
  // Both modes settle on the same tiles and the same final image.
  for (size_t i = 0; i < single.steps.size(); ++i) {
    EXPECT_EQ(single.steps[i].drawn_tiles, piped.steps[i].drawn_tiles) << "step " << i;
    EXPECT_EQ(single.steps[i].drawn_points, piped.steps[i].drawn_points) << "step " << i;
  }
  ASSERT_FALSE(single.frames.empty());
  ASSERT_FALSE(piped.frames.empty());
  EXPECT_EQ(test::differing_fraction(single.frames.back(), piped.frames.back(), 0), 0.0);
}

// Double-click picking through the engine: TilesetPlugin registers its picker, and the scene's
// pick (what the camera controller calls) finds the drawn point a ray is cast through.
TEST_P(TilesetStreamGpu, PicksTheDrawnPointUnderTheRay) {
  fs::path dir = fs::temp_directory_path() /
                 ("stipple_tileset_pick_" + std::to_string(::getpid()) + "_" + GetParam());
  fs::remove_all(dir);
  ASSERT_EQ(test::write_grid_tileset(dir, 3, 500), 21);
  Engine engine;
  tiles3d::TilesetPlugin tiles;
  tiles.uri = (dir / "tileset.json").string();
  tiles.streamer.threads = 2;
  tiles.width = kWidth;
  tiles.height = kHeight;
  test::add_tileset_engine_plugins(engine, GetParam(), false, std::move(tiles), 0.0);
  Registry& main = engine.main();
  Entity camera = main.create();
  main.emplace<Camera>(camera);
  main.get<Camera>(camera).look_at(z_up_to_y_up({500, -500, 800}), z_up_to_y_up({500, 500, 0}));
  main.get<Camera>(camera).near_plane = 1.0;
  test::update_until_idle(engine);
  engine.update();
  const auto& s = main.resource<tiles3d::TilesetStream>();
  ASSERT_FALSE(s.draw.empty());
  // The drawn point nearest to the camera: a thin cone through it hits it and nothing before.
  const glm::dvec3 eye = main.get<Camera>(camera).position;
  glm::dvec3 target{0.0};
  double nearest = 1e300;
  for (uint32_t t : s.draw)
    for (const auto& chunk : s.chunks[t]->chunks)
      for (const auto& v : chunk.vertices) {
        glm::dvec3 p = chunk.origin + glm::dvec3(v.x, v.y, v.z);
        if (glm::distance(p, eye) < nearest) nearest = glm::distance(p, eye), target = p;
      }
  auto hit = pc::pick_scene(main, {eye, glm::normalize(target - eye), 1e-4});
  ASSERT_TRUE(hit);
  EXPECT_LT(glm::distance(hit->point, target), 1e-6);
  EXPECT_NEAR(hit->t, nearest, 1e-6);
  // Up into the sky: nothing.
  EXPECT_FALSE(pc::pick_scene(main, {eye, {0, 1, 0}, 1e-2}));
  engine.shutdown();
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Backends, TilesetStreamGpu, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });

// `stipple render` on a view that wants more than --memory-mb: the traversal settles on coarser
// tiles that fit, the command finishes normally (no stall detection, no --max-frames) and says
// that the budget limited detail; with room, the same view draws every leaf.
TEST(TilesetRenderCli, BudgetLimitedViewFinishesAndSaysSo) {
  fs::path dir =
      fs::temp_directory_path() / ("stipple_tileset_budget_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  test::write_grid_tileset(dir, 4, 2000);  // 64 leaves of 2000 points: about 2 MiB resident
  const std::string common = (dir / "tileset.json").string() +
                             " --width 160 --height 120 --max-sse 0.5 --max-frames 5000 -o ";
  // "rendered N points" counts the points resident on the GPU (tiles drawn at some frame).
  auto rendered = [](const std::string& output) -> uint64_t {
    auto at = output.find("rendered ");
    return at == std::string::npos ? 0 : std::stoull(output.substr(at + 9));
  };
  auto full = test::run_stipple("render " + common + (dir / "full.png").string());
  ASSERT_EQ(full.exit_code, 0) << full.output;
  EXPECT_GE(rendered(full.output), 64u * 2000u) << full.output;
  EXPECT_EQ(full.output.find("screen-space error"), std::string::npos) << full.output;

  auto starved =
      test::run_stipple("render " + common + (dir / "starved.png").string() + " --memory-mb 1");
  ASSERT_EQ(starved.exit_code, 0) << starved.output;
  EXPECT_NE(
      starved.output.find("wants more than --memory-mb 1 allow: drawn at a screen-space error"),
      std::string::npos)
      << starved.output;
  EXPECT_EQ(starved.output.find("--max-frames"), std::string::npos) << starved.output;
  // Coarser tiles, within 1 MiB (about 32 tiles of 2000 points), but a full picture of the data.
  const uint64_t points = rendered(starved.output);
  EXPECT_GT(points, 0u) << starved.output;
  EXPECT_LE(points, 32u * 2000u) << starved.output;
  const uint8_t bg[3] = {18, 20, 26};
  const double full_coverage =
      test::coverage_stats(gpu::read_png(dir / "full.png"), bg, 1).coverage;
  const double starved_coverage =
      test::coverage_stats(gpu::read_png(dir / "starved.png"), bg, 1).coverage;
  EXPECT_GT(starved_coverage, 0.5 * full_coverage);
  fs::remove_all(dir);
}
