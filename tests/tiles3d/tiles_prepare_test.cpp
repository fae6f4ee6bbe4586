// The streamer's post-decode hook (StreamerOptions::prepare): it runs on the worker pool, never
// on the thread that calls update(); its result is kept with the tile while it is Loaded, counts
// towards the memory budget, and is released when the tile is evicted.
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "stipple/io/tileset.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

// Transforms the hook was given, by tile (checked against the tileset's).
struct SeenTransforms {
  std::mutex mutex;
  std::map<uint32_t, glm::dmat4> by_tile;
};

}  // namespace

TEST(StreamerPrepare, RunsOnWorkersAndIsResidentWithTheTile) {
  fs::path dir = fs::temp_directory_path() / ("stipple-prepare-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const uint32_t points = 2000;
  int count = test::write_grid_tileset(dir, 4, points);  // 85 tiles
  auto ts = std::make_shared<io::Tileset>(io::load_tileset((dir / "tileset.json").string()));
  ASSERT_EQ(int(ts->tiles.size()), count);

  std::mutex mutex;
  std::set<std::thread::id> threads;
  std::atomic<int> live{0}, calls{0};  // live: prepared results not yet destroyed
  SeenTransforms seen;
  tiles3d::StreamerOptions opt;
  opt.threads = 3;
  opt.traversal.memory_budget = 1'200'000;  // ~ 30 of the 85 tiles: the flight evicts
  opt.traversal.max_sse = 4;
  opt.prepare = [&](uint32_t tile, const glm::dmat4& transform,
                    std::vector<io::PointContent>& contents) {
    {
      std::lock_guard lock(mutex);
      threads.insert(std::this_thread::get_id());
    }
    ++calls;
    {
      std::lock_guard lock(seen.mutex);
      seen.by_tile[tile] = transform;
    }
    std::shared_ptr<tiles3d::TileChunks> c(new tiles3d::TileChunks,
                                           [&live](tiles3d::TileChunks* p) {
                                             --live;
                                             delete p;
                                           });
    c->tile = tile;
    for (const auto& content : contents) c->points += content.point_count;
    ++live;
    contents.clear();  // consumed: only the prepared form stays resident
    // Not the decoded size (16 bytes a point): the budget must count this one.
    return tiles3d::PreparedTile{c, c->points * 20};
  };
  auto owned = std::make_unique<tiles3d::TileStreamer>(ts, opt);
  tiles3d::TileStreamer& streamer = *owned;
  const std::thread::id caller = std::this_thread::get_id();

  uint32_t checked = 0;
  for (int step = 0; step <= 40; ++step) {
    double x = 25 * step;
    tiles3d::View v;
    v.camera.look_at(z_up_to_y_up({x, -50, 120}), z_up_to_y_up({x, 200, 0}));
    for (int i = 0; i < 20; ++i) {
      const auto& sel = streamer.update(v);
      auto s = streamer.stats();
      ASSERT_LE(s.resident_bytes, opt.traversal.memory_budget);
      // Every resident tile's bytes are its prepared bytes (the contents were consumed).
      uint64_t sum = 0;
      for (uint32_t t = 0; t < streamer.states().size(); ++t) {
        const auto& st = streamer.states()[t];
        const tiles3d::PreparedTile* p = streamer.prepared(t);
        if (st.state != tiles3d::LoadState::Loaded) {
          ASSERT_EQ(p, nullptr) << "tile " << t;
          continue;
        }
        ASSERT_NE(p, nullptr) << "tile " << t;
        const auto& c = p->chunks;
        ASSERT_EQ(c->tile, t);
        ASSERT_EQ(c->points, points);
        {
          std::lock_guard lock(seen.mutex);
          ASSERT_EQ(seen.by_tile.at(t), ts->tiles[t].transform);
        }
        ASSERT_EQ(st.bytes, p->bytes);
        ASSERT_EQ(p->bytes, uint64_t(points) * 20);
        ASSERT_TRUE(streamer.content(t)->empty());
        sum += st.bytes;
        ++checked;
      }
      ASSERT_EQ(sum, s.resident_bytes);
      for (uint32_t t : sel.render) ASSERT_NE(streamer.prepared(t), nullptr);
      if (streamer.idle()) break;
      streamer.wait_for_progress();
    }
  }
  auto s = streamer.stats();
  EXPECT_GT(s.evictions, 0u);
  EXPECT_GT(checked, 0u);
  EXPECT_GE(calls.load(), int(s.loads_completed));
  {
    std::lock_guard lock(mutex);
    EXPECT_FALSE(threads.empty());
    EXPECT_EQ(threads.count(caller), 0u) << "the hook ran on the thread that calls update()";
  }
  // Evicted (and discarded) tiles released their prepared data: only resident tiles and loads
  // still in flight hold some; none once the streamer is gone.
  EXPECT_GE(uint32_t(live.load()), s.loaded);
  EXPECT_LE(uint32_t(live.load()), s.loaded + s.in_flight);
  owned.reset();
  EXPECT_EQ(live.load(), 0);
  fs::remove_all(dir);
}

TEST(StreamerPrepare, AThrowingHookFailsTheTile) {
  fs::path dir = fs::temp_directory_path() / ("stipple-prepare-fail-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  test::write_grid_tileset(dir, 1, 100);
  auto ts = std::make_shared<io::Tileset>(io::load_tileset((dir / "tileset.json").string()));
  tiles3d::StreamerOptions opt;
  opt.threads = 1;
  opt.prepare = [](uint32_t, const glm::dmat4&,
                   std::vector<io::PointContent>&) -> tiles3d::PreparedTile {
    throw std::runtime_error("conversion failed");
  };
  tiles3d::TileStreamer streamer(ts, opt);
  tiles3d::View v;
  v.camera.look_at(z_up_to_y_up({500, -500, 800}), z_up_to_y_up({500, 500, 0}));
  for (int i = 0; i < 100; ++i) {
    streamer.update(v);
    if (streamer.idle()) break;
    streamer.wait_for_progress();
  }
  ASSERT_FALSE(streamer.errors().empty());
  EXPECT_NE(streamer.errors()[0].message.find("conversion failed"), std::string::npos);
  EXPECT_EQ(streamer.states()[0].state, tiles3d::LoadState::Failed);
  EXPECT_EQ(streamer.stats().resident_bytes, 0u);
  fs::remove_all(dir);
}
