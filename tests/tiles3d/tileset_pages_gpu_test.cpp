// Streamed tiles in suballocator pages (TilesetPlugin::gpu_page_bytes) over a camera flight with
// evictions: the GPU buffers created stay bounded by the resident set (pages are reused, never a
// buffer per tile), ranges of evicted tiles go back once their frames completed, and every frame
// equals the one drawn with dedicated buffers per tile.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "stipple/engine/render_plugins.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "test_util.hpp"
#include "tiles_fixtures.hpp"
#include "tileset_engine.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

constexpr uint32_t kWidth = 160, kHeight = 120;
constexpr uint64_t kBudget = 1'000'000;  // bytes of converted tiles: about 45 of the 85
constexpr uint64_t kPage = 128 << 10;    // ~5 tiles of 1000 points (24 KB each) to a page

struct PagedRun {
  std::vector<gpu::Image> frames;  // one per camera position, once the streamer is idle
  tiles3d::TilesetGpuStats gpu;
  uint64_t evictions = 0, loads = 0;
  uint32_t last_drawn_tiles = 0;
};

PagedRun stream(const std::string& backend, bool pipelined, const fs::path& tileset,
                uint64_t page) {
  PagedRun out;
  Engine engine;
  tiles3d::TilesetPlugin tiles;
  tiles.uri = tileset.string();
  tiles.streamer.threads = 2;
  tiles.streamer.traversal.memory_budget = kBudget;
  tiles.streamer.traversal.max_sse = 2.0;
  tiles.width = kWidth;
  tiles.height = kHeight;
  tiles.render.point_size = 3.0f;
  tiles.gpu_page_bytes = page;
  test::add_tileset_engine_plugins(engine, backend, pipelined, std::move(tiles), 1.0 / 30.0);
  gpu::Image last;
  engine.render().insert_resource(
      FrameCapture{[&last](uint64_t, const gpu::Image& image) { last = image; }});

  Registry& main = engine.main();
  Entity camera = main.create();
  main.emplace<Camera>(camera);
  // Far to near, then across and back near the ground: tiles left behind are evicted and
  // reloaded, so ranges are freed and reused many times.
  const double path[][3] = {{300, 300, 8000}, {300, 300, 1200}, {300, 300, 400}, {750, 750, 400},
                            {250, 750, 300},  {750, 250, 300},  {300, 300, 400}};
  for (const auto& p : path) {
    const double x = p[0], y = p[1], d = p[2];
    main.get<Camera>(camera).look_at(z_up_to_y_up({x, y - d, d * 0.6}), z_up_to_y_up({x, y, 0}));
    main.get<Camera>(camera).near_plane = 1.0;
    test::update_until_idle(engine);
    // Two more frames: the pipelined render world draws what the last update extracted.
    engine.update();
    engine.update();
    // `last` is written by the render thread when pipelined: read it once that frame is drawn
    // (ThreadSanitizer reported the copy racing the next capture).
    engine.wait_for_render();
    out.frames.push_back(last);
  }
  const auto& stats = main.resource<tiles3d::TilesetStats>();
  out.evictions = stats.evictions;
  out.loads = stats.loads_completed;
  out.last_drawn_tiles = stats.drawn_tiles;
  engine.shutdown();
  out.gpu = engine.render().resource<tiles3d::TilesetGpuStats>();
  return out;
}

class TilesetPagesGpu : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(TilesetPagesGpu, BoundedBuffersSameImages) {
  fs::path dir = fs::temp_directory_path() /
                 ("stipple_tileset_pages_" + std::to_string(::getpid()) + "_" + GetParam());
  fs::remove_all(dir);
  ASSERT_EQ(test::write_grid_tileset(dir, 4, 1000), 85);
  const fs::path json = dir / "tileset.json";
  PagedRun dedicated = stream(GetParam(), false, json, 0);
  PagedRun paged = stream(GetParam(), false, json, kPage);
  PagedRun piped = stream(GetParam(), true, json, kPage);
  fs::remove_all(dir);

  for (const PagedRun* run : {&paged, &piped}) {
    SCOPED_TRACE(run == &paged ? "single thread" : "pipelined");
    const auto& g = run->gpu;
    std::printf(
        "%s: %llu tile uploads (%llu chunks), %llu frees, %llu loads, %llu evictions; "
        "%llu buffers created, %u pages, %llu ranges freed, %llu pending, "
        "fragmentation %.2f\n",
        run == &paged ? "single" : "pipelined", (unsigned long long)g.uploads,
        (unsigned long long)g.pages.chunks_uploaded, (unsigned long long)g.frees,
        (unsigned long long)run->loads, (unsigned long long)run->evictions,
        (unsigned long long)g.pages.buffers_created, g.allocator.pages,
        (unsigned long long)g.pages.ranges_freed, (unsigned long long)g.pending_frees,
        g.allocator.fragmentation);
    EXPECT_TRUE(g.paged);
    EXPECT_GT(run->evictions, 0u);
    EXPECT_GT(g.frees, 20u);
    EXPECT_GT(g.pages.ranges_freed, 20u);
    // Every range ever allocated is live on the GPU, waiting for its frame, or freed.
    EXPECT_EQ(2 * g.pages.chunks_uploaded,
              g.allocator.allocations + g.pending_frees + g.pages.ranges_freed);
    EXPECT_EQ(g.pages.frees_queued, g.pending_frees + g.pages.ranges_freed);
    // Pages are kept and reused: what was created is what exists, never a dedicated buffer,
    // and about what the resident tiles need (GPU bytes per tile ~ 1.2x their budget bytes; a
    // page's worth of slack per page for fragmentation and for ranges waiting for a frame).
    EXPECT_EQ(g.pages.buffers_created, g.allocator.pages);
    EXPECT_EQ(g.allocator.dedicated_buffers, 0u);
    const uint64_t bound = 2 * (kBudget * 12 / 10 + kPage - 1) / kPage;
    EXPECT_LE(g.pages.buffers_created, bound);
    EXPECT_GT(g.uploads, 4 * g.pages.buffers_created) << "pages must be reused";
    EXPECT_EQ(g.gpu_points, uint64_t(g.gpu_tiles) * 1000);
  }
  // Same tiles, same order, same uniforms: the pixels must be identical (tolerance 0) to the
  // frames drawn from dedicated buffers, at every camera position.
  ASSERT_EQ(dedicated.frames.size(), paged.frames.size());
  ASSERT_EQ(dedicated.frames.size(), piped.frames.size());
  EXPECT_FALSE(dedicated.gpu.paged);
  const uint8_t bg[3] = {18, 20, 26};
  for (size_t i = 0; i < dedicated.frames.size(); ++i) {
    SCOPED_TRACE("position " + std::to_string(i));
    ASSERT_EQ(dedicated.frames[i].width, kWidth);
    EXPECT_GT(test::coverage_stats(dedicated.frames[i], bg, 1).coverage, 0.004);
    EXPECT_EQ(test::differing_fraction(dedicated.frames[i], paged.frames[i], 0), 0.0);
    EXPECT_EQ(test::differing_fraction(dedicated.frames[i], piped.frames[i], 0), 0.0);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, TilesetPagesGpu, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });
