// COPC streamed through the 3D Tiles traversal and streamer: hierarchy pages are read as the
// view reaches them, and only the nodes a view selects are fetched (counted per range URI).
#include <algorithm>
#include <map>
#include <mutex>
#include <set>

#include <gtest/gtest.h>

#include "copc_fixture.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace stipple;

namespace {

// Counts reads by kind: node chunks (URIs with a point count) and everything else (pages,
// header).
struct Reads {
  std::mutex mutex;
  std::set<std::string> nodes;
  int pages = 0, other = 0;
  io::Fetcher fetcher() {
    return [this](const std::string& uri) {
      {
        std::lock_guard lock(mutex);
        if (!io::fragment_field(uri, "points").empty())
          nodes.insert(uri);
        else
          ++other;
      }
      return io::fetch(uri);
    };
  }
};

const fs::path& deep_copc() {
  static const fs::path path = [] {
    fs::path dir = fs::temp_directory_path() / "stipple_copc_stream";
    fs::create_directories(dir);
    fs::path f = dir / "deep.copc.laz";
    if (!fs::exists(f) && !test::write_test_copc(f, 300'000, "--depth 7 --capacity 300"))
      return fs::path();
    return f;
  }();
  return path;
}

// Looking at the data's centre from `distance` south and as high (file units).
tiles3d::View oblique_view(const io::Tileset& ts, double distance) {
  tiles3d::View v;
  v.world_from_tileset = tiles3d::world_from_tileset(ts);
  const glm::dvec3 c = (ts.copc->header.min + ts.copc->header.max) * 0.5;
  v.camera.look_at(z_up_to_y_up(c + glm::dvec3(0, -distance, distance)), z_up_to_y_up(c));
  return v;
}

bool stream_until_idle(tiles3d::TileStreamer& s, const tiles3d::View& v) {
  for (int i = 0; i < 5000; ++i) {
    s.update(v);
    if (s.idle()) return true;
    s.wait_for_progress();
  }
  return false;
}

}  // namespace

TEST(CopcStream, APartialViewReadsAStrictSubsetOfTheNodes) {
  STIPPLE_REQUIRE_COPC_WRITER();
  ASSERT_FALSE(deep_copc().empty());
  const std::string uri = deep_copc().string();
  // The whole hierarchy, for the counts.
  io::Tileset all = io::load_tileset(uri);
  ASSERT_TRUE(io::expand_all(
      all, [](const std::string& u) { return io::fetch(u); }, {}, 1 << 20));
  size_t nodes = 0;
  for (const auto& t : all.tiles) nodes += t.contents.size();
  ASSERT_GE(all.tiles.back().depth, 5u) << "the written hierarchy is not deep";
  ASSERT_GT(all.subtrees, 3u) << "the written hierarchy has too few pages";

  Reads reads;
  auto fetcher = reads.fetcher();
  auto ts = std::make_shared<io::Tileset>(io::load_copc_tileset(uri, fetcher));
  tiles3d::StreamerOptions options;
  options.fetcher = fetcher;
  options.traversal.max_sse = 2;
  tiles3d::TileStreamer streamer(ts, options);
  // Close to one corner of the data, looking at it.
  tiles3d::View v;
  v.world_from_tileset = tiles3d::world_from_tileset(*ts);
  const io::LasHeader& h = ts->copc->header;
  const glm::dvec3 corner = h.min + (h.max - h.min) * 0.1;
  v.camera.look_at(z_up_to_y_up(corner + glm::dvec3(-20, -20, 30)), z_up_to_y_up(corner));
  ASSERT_TRUE(stream_until_idle(streamer, v));
  EXPECT_GT(reads.nodes.size(), 0u);
  EXPECT_LT(reads.nodes.size(), nodes) << "a partial view read every node";
  EXPECT_LT(uint32_t(ts->subtrees), all.subtrees) << "a partial view read every page";
  // What is drawn is resident, and each read node was read once.
  const auto& sel = streamer.update(v);
  EXPECT_FALSE(sel.render.empty());
  for (uint32_t t : sel.render) EXPECT_NE(streamer.content(t), nullptr);
  EXPECT_EQ(streamer.stats().failed, 0u);

  // Far away with a tiny error threshold: every node, every point.
  Reads every;
  auto f2 = every.fetcher();
  auto ts2 = std::make_shared<io::Tileset>(io::load_copc_tileset(uri, f2));
  options.fetcher = f2;
  options.traversal.max_sse = 1e-6;
  options.traversal.memory_budget = 4ull << 30;
  tiles3d::TileStreamer whole(ts2, options);
  const tiles3d::View far = oblique_view(*ts2, 3000);
  ASSERT_TRUE(stream_until_idle(whole, far));
  EXPECT_EQ(every.nodes.size(), nodes);
  uint64_t points = 0;
  for (uint32_t t : whole.update(far).render)
    for (const auto& content : *whole.content(t)) points += content.point_count;
  EXPECT_EQ(points, 300'000u);
}

TEST(CopcStream, ATruncatedNodeFailsAloneAndTheViewCompletes) {
  STIPPLE_REQUIRE_DATA(path, "laz/lone-star.copc.laz");
  // The fetcher cuts the first level-2 node's chunk it reads in half, as a dropped connection
  // would.
  std::string victim;
  std::mutex mutex;
  io::Fetcher fetcher = [&](const std::string& uri) {
    auto bytes = io::fetch(uri);
    if (io::fragment_field(uri, "key").starts_with("2-")) {
      std::lock_guard lock(mutex);
      if (victim.empty()) victim = uri;
      if (victim == uri) bytes.resize(bytes.size() / 2);
    }
    return bytes;
  };
  auto ts = std::make_shared<io::Tileset>(io::load_copc_tileset(path.string(), fetcher));
  tiles3d::StreamerOptions options;
  options.fetcher = fetcher;
  options.traversal.max_sse = 1e-6;
  tiles3d::TileStreamer streamer(ts, options);
  const tiles3d::View v = oblique_view(*ts, 60);
  ASSERT_TRUE(stream_until_idle(streamer, v));
  auto stats = streamer.stats();
  EXPECT_EQ(stats.failed, 1u);
  EXPECT_EQ(stats.loaded, 14u);  // the 14 other nodes
  ASSERT_EQ(streamer.errors().size(), 1u);
  EXPECT_EQ(streamer.errors()[0].message.find(victim), 0u) << streamer.errors()[0].message;
  EXPECT_FALSE(streamer.update(v).render.empty());
}

// Potree's point budget: the selection draws at most --budget points (the nodes' declared
// counts bound it before they load), coarser where the view wants more; without it every
// point is drawn.
TEST(CopcStream, APointBudgetBoundsTheSelection) {
  STIPPLE_REQUIRE_DATA(path, "laz/lone-star.copc.laz");
  for (uint64_t budget : {uint64_t(0), uint64_t(200'000), uint64_t(60'000)}) {
    auto ts = std::make_shared<io::Tileset>(io::load_tileset(path.string()));
    tiles3d::StreamerOptions options;
    options.traversal.max_sse = 1e-6;
    options.traversal.point_budget = budget;
    tiles3d::TileStreamer streamer(ts, options);
    const tiles3d::View v = oblique_view(*ts, 60);
    ASSERT_TRUE(stream_until_idle(streamer, v));
    const auto& sel = streamer.update(v);
    uint64_t drawn = 0;
    for (uint32_t t : sel.render)
      for (const auto& content : *streamer.content(t)) drawn += content.point_count;
    if (budget == 0) {
      EXPECT_EQ(drawn, 518862u);
      EXPECT_FALSE(sel.budget_limited);
    } else {
      EXPECT_LE(drawn, budget);
      EXPECT_GT(drawn, 0u);
      EXPECT_TRUE(sel.budget_limited);
      EXPECT_LE(sel.footprint_points, budget);
    }
  }
}
