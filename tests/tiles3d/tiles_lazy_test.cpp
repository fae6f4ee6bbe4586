// Lazy reading of the 3D Tiles tree and the memory budget as a bound on the selection: external
// tilesets are fetched only when the traversal refines into them, child subtrees of implicit
// tiling only when it reaches their root tiles, a broken one costs its tile only, and a view
// that wants more than the budget settles on coarser tiles instead of loading and evicting
// forever. Requests are counted through the streamer's Fetcher.
#include <algorithm>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>

#include <gtest/gtest.h>

#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/pnts.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "stipple/tiles3d/traversal.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
using namespace stipple::test;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir(const std::string& name) {
  return fresh_temp_dir("lazy-" + name);
}

// Counts every request by URI; serves made-up bytes for URIs `synth` answers, files otherwise.
// Called from the streamer's workers: locked.
class CountingFetcher {
 public:
  std::function<std::optional<Bytes>(const std::string&)> synth;

  io::Fetcher fetcher() {
    return [this](const std::string& uri) {
      {
        std::lock_guard lock(mutex_);
        ++counts_[uri];
      }
      if (synth)
        if (auto b = synth(uri)) return *b;
      return io::fetch(uri);
    };
  }
  int count(const std::string& uri) {
    std::lock_guard lock(mutex_);
    auto it = counts_.find(uri);
    return it == counts_.end() ? 0 : it->second;
  }
  // Requests whose URI contains `part`, and the most any one of them was requested.
  int count_containing(const std::string& part, int* most = nullptr) {
    std::lock_guard lock(mutex_);
    int n = 0, m = 0;
    for (const auto& [uri, c] : counts_)
      if (uri.find(part) != std::string::npos) n += c, m = std::max(m, c);
    if (most) *most = m;
    return n;
  }
  int total() { return count_containing(""); }

 private:
  std::mutex mutex_;
  std::map<std::string, int> counts_;
};

tiles3d::View look(const glm::dvec3& eye_z_up, const glm::dvec3& target_z_up, double fov_deg) {
  tiles3d::View v;
  v.camera.fov_y = glm::radians(fov_deg);
  v.camera.look_at(z_up_to_y_up(eye_z_up), z_up_to_y_up(target_z_up));
  v.camera.near_plane = 1.0;
  return v;
}

// Updates until the streamer is idle; false when it never is within `max_updates`.
bool stream_until_idle(tiles3d::TileStreamer& s, const tiles3d::View& v, int max_updates = 2000,
                       const std::function<void(const tiles3d::Selection&)>& each = nullptr) {
  for (int i = 0; i < max_updates; ++i) {
    const auto& sel = s.update(v);
    if (each) each(sel);
    if (s.idle()) return true;
    s.wait_for_progress();
  }
  return false;
}

std::shared_ptr<io::Tileset> load(const fs::path& path, CountingFetcher& counter) {
  auto f = counter.fetcher();
  return std::make_shared<io::Tileset>(io::parse_tileset(f(path.string()), path.string(), f));
}

json box_tile(double cx, double cy, double cz, double hx, double hy, double hz, double error) {
  return {{"boundingVolume", {{"box", {cx, cy, cz, hx, 0, 0, 0, hy, 0, 0, 0, hz}}}},
          {"geometricError", error}};
}

}  // namespace

TEST(TilesLazy, ExternalTilesetIsFetchedWhenTraversalRefinesIntoIt) {
  fs::path dir = temp_dir("external");
  // Two external grid tilesets side by side; the right one is moved by its tile's transform.
  write_grid_tileset(dir / "left", 3, 300);
  write_grid_tileset(dir / "right", 3, 300);
  double rtc[3] = {0, 0, 0};
  write_file(dir / "root.pnts", grid_pnts(300, 2000.0f, rtc, 10));
  json left = box_tile(500, 500, 500, 500, 500, 500, 62.5);
  left["content"] = {{"uri", "left/tileset.json"}};
  json right = box_tile(500, 500, 500, 500, 500, 500, 62.5);
  right["content"] = {{"uri", "right/tileset.json"}};
  right["transform"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1000, 0, 0, 1};
  json root = box_tile(1000, 500, 500, 1000, 500, 500, 200);
  root["refine"] = "REPLACE";
  root["content"] = {{"uri", "root.pnts"}};
  root["children"] = {left, right};
  write_json(dir / "tileset.json",
             {{"asset", {{"version", "1.1"}}}, {"geometricError", 400}, {"root", root}});
  const std::string left_json = (dir / "left/tileset.json").string();
  const std::string right_json = (dir / "right/tileset.json").string();

  CountingFetcher counter;
  auto ts = load(dir / "tileset.json", counter);
  ASSERT_EQ(ts->tiles.size(), 3u);
  EXPECT_EQ(ts->pending, 2u);
  EXPECT_EQ(counter.total(), 1);  // tileset.json only
  tiles3d::StreamerOptions opt;
  opt.threads = 2;
  opt.fetcher = counter.fetcher();
  tiles3d::TileStreamer streamer(ts, opt);

  // Far away, the root is fine enough: nothing below it is read.
  auto far = look({1000, -20000, 20000}, {1000, 500, 0}, 50);
  ASSERT_TRUE(stream_until_idle(streamer, far));
  EXPECT_EQ(streamer.update(far).render, (std::vector<uint32_t>{0}));
  EXPECT_EQ(counter.count(left_json), 0);
  EXPECT_EQ(counter.count(right_json), 0);
  EXPECT_EQ(ts->tiles.size(), 3u);

  // Inside the left half looking away from the right one: only the left tileset is read, once,
  // and its tiles replace the root.
  auto near_left = look({500, 500, 300}, {-500, 500, 0}, 40);
  bool root_kept_while_reading = false;
  ASSERT_TRUE(stream_until_idle(streamer, near_left, 2000, [&](const tiles3d::Selection& sel) {
    root_kept_while_reading |=
        streamer.stats().expanding > 0 && std::count(sel.render.begin(), sel.render.end(), 0u) == 1;
  }));
  EXPECT_TRUE(root_kept_while_reading);
  EXPECT_EQ(counter.count(left_json), 1);
  EXPECT_EQ(counter.count(right_json), 0);
  EXPECT_EQ(ts->external_tilesets, 1u);
  EXPECT_EQ(ts->tiles.size(), 3u + 21u);  // the left grid: 1 + 4 + 16 tiles
  EXPECT_FALSE(ts->tiles[1].pending);
  EXPECT_TRUE(ts->tiles[2].pending);
  const auto& sel = streamer.update(near_left);
  ASSERT_FALSE(sel.render.empty());
  for (uint32_t t : sel.render) {
    ASSERT_NE(streamer.content(t), nullptr);
    EXPECT_EQ(ts->tiles[t].contents[0].rfind((dir / "left").string(), 0), 0u)
        << ts->tiles[t].contents[0];
    EXPECT_GE(ts->tiles[t].depth, 2u);
  }
  EXPECT_TRUE(streamer.errors().empty());

  // Looking at the right half reads it, under its tile's transform.
  auto near_right = look({1500, 500, 300}, {2500, 500, 0}, 40);
  ASSERT_TRUE(stream_until_idle(streamer, near_right));
  EXPECT_EQ(counter.count(right_json), 1);
  EXPECT_EQ(counter.count(left_json), 1);
  ASSERT_EQ(ts->tiles[2].children.size(), 1u);
  EXPECT_NEAR(ts->tiles[ts->tiles[2].children[0]].box.center.x, 1500, 1e-9);
  for (uint32_t t : streamer.update(near_right).render)
    EXPECT_EQ(ts->tiles[t].contents[0].rfind((dir / "right").string(), 0), 0u);
  // Every content was fetched once: nothing was loaded twice.
  int most = 0;
  counter.count_containing(".pnts", &most);
  EXPECT_EQ(most, 1);
  fs::remove_all(dir);
}

TEST(TilesLazy, ImplicitOctreeReadsChildSubtreesOnDemand) {
  fs::path dir = temp_dir("octree");
  // Levels 0-4, subtrees of 2 levels: subtree files at levels 0, 2 and 4 (1 + 64 + 4096), every
  // tile available with content. Subtrees and contents are made up by the fetcher.
  json ts_json = {{"asset", {{"version", "1.1"}}},
                  {"geometricError", 1024},
                  {"root",
                   {{"boundingVolume", {{"box", {0, 0, 0, 512, 0, 0, 0, 512, 0, 0, 0, 512}}}},
                    {"geometricError", 512},
                    {"refine", "REPLACE"},
                    {"content", {{"uri", "content/{level}/{x}/{y}/{z}.pnts"}}},
                    {"implicitTiling",
                     {{"subdivisionScheme", "OCTREE"},
                      {"subtreeLevels", 2},
                      {"availableLevels", 5},
                      {"subtrees", {{"uri", "subtrees/{level}/{x}/{y}/{z}.subtree"}}}}}}}};
  write_json(dir / "tileset.json", ts_json);
  const Bytes subtree = json_bytes({{"tileAvailability", {{"constant", 1}}},
                                    {"contentAvailability", {{{"constant", 1}}}},
                                    {"childSubtreeAvailability", {{"constant", 1}}}});
  double rtc[3] = {0, 0, 0};
  const Bytes content = grid_pnts(20, 1.0f, rtc, 90);
  CountingFetcher counter;
  counter.synth = [&](const std::string& uri) -> std::optional<Bytes> {
    if (uri.find("/subtrees/") != std::string::npos) return subtree;
    if (uri.find("/content/") != std::string::npos) return content;
    return std::nullopt;
  };
  auto ts = load(dir / "tileset.json", counter);
  // Loading reads the root subtree: the root, 8 tiles at level 1, and the 64 roots of the level-2
  // subtrees (volumes only, pending).
  EXPECT_EQ(counter.count_containing("/subtrees/"), 1);
  ASSERT_EQ(ts->tiles.size(), 73u);
  EXPECT_EQ(ts->pending, 64u);
  EXPECT_EQ(ts->subtrees, 1u);

  tiles3d::StreamerOptions opt;
  opt.threads = 2;
  opt.fetcher = counter.fetcher();
  opt.traversal.max_sse = 128;
  tiles3d::TileStreamer streamer(ts, opt);
  // In the (-,-,-) corner looking into it: most of the octree is behind the camera or too far.
  auto v = look({-300, -300, -300}, {-512, -512, -512}, 40);
  ASSERT_TRUE(stream_until_idle(streamer, v));
  EXPECT_TRUE(streamer.errors().empty());
  int most = 0;
  const int level2 = counter.count_containing("/subtrees/2/", &most);
  EXPECT_EQ(most, 1);  // no subtree read twice
  const int level4 = counter.count_containing("/subtrees/4/", &most);
  EXPECT_LE(most, 1);
  std::printf("subtrees read: level 2: %d of 64, level 4: %d of 4096; tiles %zu\n", level2, level4,
              ts->tiles.size());
  EXPECT_GT(level2, 0);
  EXPECT_LT(level2, 64);
  EXPECT_GT(level4, 0);
  EXPECT_LT(level4, 4096 / 8);
  EXPECT_EQ(ts->subtrees, uint32_t(1 + level2 + level4));
  // Tiles are made only for subtrees read: a level-2 subtree adds 8 tiles at level 3 and the 64
  // roots of its level-4 subtrees; a level-4 subtree only gives its root its content.
  EXPECT_EQ(ts->tiles.size(), size_t(73 + 72 * level2));
  // The finest level is drawn near the camera.
  const auto& sel = streamer.update(v);
  uint32_t deepest = 0;
  for (uint32_t t : sel.render) {
    ASSERT_NE(streamer.content(t), nullptr);
    deepest = std::max(deepest, ts->tiles[t].depth);
  }
  EXPECT_EQ(deepest, 4u);
  fs::remove_all(dir);
}

TEST(TilesLazy, BrokenExternalTilesetOrSubtreeCostsItsTileOnly) {
  fs::path dir = temp_dir("broken");
  double rtc[3] = {0, 0, 0};
  write_file(dir / "good.pnts", grid_pnts(100, 10.0f, rtc, 10));
  write_file(dir / "bad.json", {'{', '"', 'a'});
  // Implicit quadtree below the last child: one subtree level, the 4 level-1 subtrees exist but
  // for (1,1,1).
  for (const char* name : {"1.0.0", "1.1.0", "1.0.1"})
    write_json(dir / "sub" / (std::string(name) + ".subtree"),
               {{"tileAvailability", {{"constant", 1}}},
                {"contentAvailability", {{{"constant", 1}}}},
                {"childSubtreeAvailability", {{"constant", 0}}}});
  write_json(dir / "sub/0.0.0.subtree", {{"tileAvailability", {{"constant", 1}}},
                                         {"contentAvailability", {{{"constant", 1}}}},
                                         {"childSubtreeAvailability", {{"constant", 1}}}});
  for (const char* name : {"0/0_0", "1/0_0", "1/1_0", "1/0_1", "1/1_1"})
    write_file(dir / "content" / (std::string(name) + ".pnts"), grid_pnts(50, 10.0f, rtc, 20));
  json good = box_tile(5, 5, 5, 5, 5, 5, 1);
  good["content"] = {{"uri", "good.pnts"}};
  json bad = box_tile(25, 5, 5, 5, 5, 5, 1);
  bad["content"] = {{"uri", "bad.json"}};
  json missing = box_tile(45, 5, 5, 5, 5, 5, 1);
  missing["content"] = {{"uri", "missing.json"}};
  json implicit = box_tile(65, 5, 5, 5, 5, 5, 1);
  implicit["content"] = {{"uri", "content/{level}/{x}_{y}.pnts"}};
  implicit["implicitTiling"] = {{"subdivisionScheme", "QUADTREE"},
                                {"subtreeLevels", 1},
                                {"availableLevels", 2},
                                {"subtrees", {{"uri", "sub/{level}.{x}.{y}.subtree"}}}};
  json root = box_tile(40, 5, 5, 40, 5, 5, 1000);
  root["refine"] = "ADD";
  root["children"] = {good, bad, missing, implicit};
  write_json(dir / "tileset.json",
             {{"asset", {{"version", "1.1"}}}, {"geometricError", 1000}, {"root", root}});

  CountingFetcher counter;
  auto ts = load(dir / "tileset.json", counter);
  // root, 4 children, the implicit child's 4 subtree roots.
  ASSERT_EQ(ts->tiles.size(), 9u);
  EXPECT_TRUE(ts->errors.empty());
  tiles3d::StreamerOptions opt;
  opt.threads = 2;
  opt.fetcher = counter.fetcher();
  opt.traversal.max_sse = 1e-9;  // everything
  tiles3d::TileStreamer streamer(ts, opt);
  auto v = look({40, -100, 60}, {40, 5, 0}, 60);
  ASSERT_TRUE(stream_until_idle(streamer, v));
  // One error on each broken tile, naming the file; nothing else failed.
  std::map<uint32_t, std::string> errors;
  for (const auto& e : streamer.errors()) errors[e.tile] += e.message;
  ASSERT_EQ(streamer.errors().size(), 3u);
  const uint32_t missing_subtree = ts->tiles[4].children[3];  // (1,1,1): children in Morton order
  EXPECT_NE(errors[2].find("bad.json"), std::string::npos) << errors[2];
  EXPECT_NE(errors[3].find("missing.json"), std::string::npos) << errors[3];
  EXPECT_NE(errors[missing_subtree].find("1.1.1.subtree"), std::string::npos)
      << errors[missing_subtree];
  EXPECT_FALSE(ts->tiles[2].error.empty());
  EXPECT_FALSE(ts->tiles[3].error.empty());
  EXPECT_FALSE(ts->tiles[missing_subtree].error.empty());
  EXPECT_FALSE(ts->tiles[2].pending);  // not retried
  // The rest renders: the good tile, the implicit root and its three readable children.
  const auto& sel = streamer.update(v);
  std::vector<uint32_t> render = sel.render;
  std::sort(render.begin(), render.end());
  std::vector<uint32_t> expected = {1, 4};
  for (uint32_t c : ts->tiles[4].children)
    if (c != missing_subtree) expected.push_back(c);
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(render, expected);
  EXPECT_EQ(counter.count((dir / "bad.json").string()), 1);
  fs::remove_all(dir);
}

TEST(TilesLazy, TraversalAsksForPendingChildrenOnlyWhenRefining) {
  // A root over one tile whose children are an external tileset not read yet.
  io::Tileset ts;
  io::Tile root;
  root.box.center = {50, 50, 5};
  root.box.half_axes = glm::dmat3(glm::dvec3(50, 0, 0), glm::dvec3(0, 50, 0), glm::dvec3(0, 0, 5));
  root.geometric_error = 100;
  root.contents = {"root.pnts"};
  io::Tile child = root;
  child.parent = 0;
  child.depth = 1;
  child.geometric_error = 50;
  child.contents.clear();
  auto pending = std::make_shared<io::PendingChildren>();
  pending->uris = {"ext.json"};
  child.pending = pending;
  root.children = {1};
  ts.tiles = {root, child};
  std::vector<tiles3d::TileState> st(2);
  st[0] = {tiles3d::LoadState::Loaded, 100, 0};
  tiles3d::TraversalOptions opt;
  auto far = tiles3d::select_tiles(ts, look({50, 40, 1e6}, {50, 50, 0}, 50), st, opt, 1);
  EXPECT_TRUE(far.expands.empty());
  EXPECT_EQ(far.render, (std::vector<uint32_t>{0}));
  // Close: the child wants refining, so its tileset is asked for; the root stays drawn.
  auto near = tiles3d::select_tiles(ts, look({50, 40, 60}, {50, 50, 0}, 50), st, opt, 2);
  ASSERT_EQ(near.expands.size(), 1u);
  EXPECT_EQ(near.expands[0].tile, 1u);
  EXPECT_EQ(near.render, (std::vector<uint32_t>{0}));
  EXPECT_TRUE(near.loads.empty());
}

TEST(TilesLazy, TraversalRaisesTheThresholdToFitTheBudget) {
  // Root (loaded, 100 bytes) over 4 children never loaded (assumed as large as the root).
  io::Tileset ts;
  auto box = [](double cx, double cy, double half) {
    io::Tile t;
    t.box.center = {cx, cy, 5};
    t.box.half_axes =
        glm::dmat3(glm::dvec3(half, 0, 0), glm::dvec3(0, half, 0), glm::dvec3(0, 0, 5));
    t.contents = {"x"};
    return t;
  };
  ts.tiles.push_back(box(50, 50, 50));
  ts.tiles[0].geometric_error = 100;
  for (int c = 0; c < 4; ++c) {
    io::Tile t = box(25 + 50 * (c & 1), 25 + 50 * (c >> 1), 25);
    t.parent = 0;
    t.depth = 1;
    ts.tiles[0].children.push_back(uint32_t(ts.tiles.size()));
    ts.tiles.push_back(t);
  }
  std::vector<tiles3d::TileState> st(ts.tiles.size());
  st[0] = {tiles3d::LoadState::Loaded, 100, 0};
  auto v = look({50, 40, 60}, {50, 50, 0}, 50);
  tiles3d::TraversalOptions opt;
  // Room for the children while the root is kept: they are requested.
  opt.memory_budget = 500;
  auto fits = tiles3d::select_tiles(ts, v, st, opt, 1);
  EXPECT_FALSE(fits.budget_limited);
  EXPECT_EQ(fits.loads.size(), 4u);
  EXPECT_EQ(fits.footprint, 500u);
  EXPECT_EQ(fits.sse_threshold, opt.max_sse);
  // No room: the root is drawn and nothing is requested that could not be kept.
  opt.memory_budget = 499;
  auto starved = tiles3d::select_tiles(ts, v, st, opt, 2);
  EXPECT_TRUE(starved.budget_limited);
  EXPECT_GT(starved.sse_threshold, opt.max_sse);
  EXPECT_EQ(starved.render, (std::vector<uint32_t>{0}));
  EXPECT_TRUE(starved.loads.empty());
  EXPECT_EQ(starved.footprint, 100u);
  EXPECT_TRUE(starved.evict.empty());
  // Children whose size is known are planned with it: two of 150 bytes fit beside the root when
  // the other two are known to be small.
  st[1].bytes = st[2].bytes = 150;
  st[3].bytes = st[4].bytes = 10;
  opt.memory_budget = 420;
  auto known = tiles3d::select_tiles(ts, v, st, opt, 3);
  EXPECT_FALSE(known.budget_limited);
  EXPECT_EQ(known.footprint, 420u);
  // Not even the root fits: nothing at all.
  opt.memory_budget = 50;
  auto none = tiles3d::select_tiles(ts, v, st, opt, 4);
  EXPECT_TRUE(none.budget_limited);
  EXPECT_TRUE(none.render.empty());
  EXPECT_TRUE(none.loads.empty());
}

TEST(TilesLazy, BudgetStarvedViewConvergesWithoutChurn) {
  fs::path dir = temp_dir("starved");
  write_grid_tileset(dir, 4, 2000);  // 85 tiles x 2000 points
  double rtc[3] = {0, 0, 0};
  const uint64_t tile_bytes =
      io::decode_pnts(grid_pnts(2000, 1.0f, rtc, 0), "t.pnts").memory_bytes();
  CountingFetcher counter;
  auto ts = load(dir / "tileset.json", counter);
  tiles3d::StreamerOptions opt;
  opt.threads = 2;
  opt.fetcher = counter.fetcher();
  opt.traversal.max_sse = 0.5;  // the view wants all 64 leaves
  opt.traversal.memory_budget = 12 * tile_bytes;
  tiles3d::TileStreamer streamer(ts, opt);
  auto v = look({500, 400, 1500}, {500, 500, 0}, 50);
  uint64_t worst = 0;
  ASSERT_TRUE(stream_until_idle(streamer, v, 500, [&](const tiles3d::Selection&) {
    worst = std::max(worst, streamer.stats().resident_bytes);
  }));
  EXPECT_LE(worst, opt.traversal.memory_budget);
  auto settled = streamer.stats();
  EXPECT_TRUE(settled.budget_limited);
  EXPECT_GT(settled.sse_threshold, opt.traversal.max_sse);
  EXPECT_LE(settled.peak_resident_bytes, opt.traversal.memory_budget);
  const int fetches = counter.total();
  // Settled: more frames of the same view load, cancel and evict nothing.
  for (int i = 0; i < 50; ++i) {
    const auto& sel = streamer.update(v);
    ASSERT_TRUE(streamer.idle());
    ASSERT_TRUE(sel.loads.empty() ||
                std::all_of(sel.loads.begin(), sel.loads.end(), [&](const tiles3d::LoadRequest& r) {
                  return streamer.states()[r.tile].state == tiles3d::LoadState::Failed;
                }));
    ASSERT_TRUE(sel.cancel.empty());
    ASSERT_TRUE(sel.evict.empty());
    ASSERT_LE(sel.footprint, opt.traversal.memory_budget);
  }
  auto after = streamer.stats();
  EXPECT_EQ(counter.total(), fetches);
  EXPECT_EQ(after.loads_completed, settled.loads_completed);
  EXPECT_EQ(after.evictions, settled.evictions);
  EXPECT_EQ(after.discarded_over_budget, settled.discarded_over_budget);
  // No tile was fetched twice on the way there, and detail went past the root where it fitted.
  int most = 0;
  counter.count_containing(".pnts", &most);
  EXPECT_EQ(most, 1);
  const auto& sel = streamer.update(v);
  ASSERT_FALSE(sel.render.empty());
  uint32_t deepest = 0;
  for (uint32_t t : sel.render) {
    ASSERT_NE(streamer.content(t), nullptr);
    deepest = std::max(deepest, ts->tiles[t].depth);
  }
  EXPECT_GE(deepest, 1u);
  EXPECT_LT(deepest, 3u);  // the leaves (64 of them) cannot fit
  std::printf(
      "settled after %d fetches: %zu tiles drawn, threshold %.2f px, %llu evictions, "
      "%llu discarded\n",
      fetches, sel.render.size(), after.sse_threshold, (unsigned long long)after.evictions,
      (unsigned long long)after.discarded_over_budget);

  // The headless one-shot load settles too and says the budget limited it.
  tiles3d::RenderLoadOptions ro;
  ro.streamer = opt;
  ro.streamer.fetcher = nullptr;
  ro.camera = &v.camera;
  auto r = tiles3d::load_tileset_for_render((dir / "tileset.json").string(), ro);
  EXPECT_TRUE(r.budget_limited);
  EXPECT_TRUE(r.errors.empty());
  EXPECT_GT(r.tiles_rendered, 0u);
  EXPECT_LE(r.stats.peak_resident_bytes, opt.traversal.memory_budget);
  fs::remove_all(dir);
}

TEST(TilesLazy, ExpandAllStopsAtItsCap) {
  fs::path dir = temp_dir("cap");
  write_grid_tileset(dir / "a", 3, 10);
  write_grid_tileset(dir / "b", 3, 10);
  json root = box_tile(500, 500, 500, 500, 500, 500, 100);
  root["children"] = json::array();
  for (const char* sub : {"a", "b"}) {
    json c = box_tile(500, 500, 500, 500, 500, 500, 62.5);
    c["content"] = {{"uri", std::string(sub) + "/tileset.json"}};
    root["children"].push_back(c);
  }
  write_json(dir / "tileset.json",
             {{"asset", {{"version", "1.1"}}}, {"geometricError", 100}, {"root", root}});
  auto fetch = [](const std::string& u) { return io::fetch(u); };
  io::Tileset whole = io::load_tileset((dir / "tileset.json").string());
  EXPECT_TRUE(io::expand_all(whole, fetch, {}, 1000));
  EXPECT_EQ(whole.tiles.size(), 3u + 2 * 21u);
  // A cap of 30 tiles: the first external tileset fits, the second would pass it and stays
  // pending.
  io::Tileset capped = io::load_tileset((dir / "tileset.json").string());
  EXPECT_FALSE(io::expand_all(capped, fetch, {}, 30));
  EXPECT_EQ(capped.tiles.size(), 3u + 21u);
  EXPECT_EQ(capped.pending, 1u);
  EXPECT_TRUE(capped.tiles[2].pending);
  // The streaming limit refuses an expansion with an error on its tile.
  io::TilesetOptions limited;
  limited.max_tiles = 30;
  io::Tileset t = io::load_tileset((dir / "tileset.json").string());
  auto first = io::read_children(1, *t.tiles[1].pending, t.tiles.size(), fetch, limited);
  EXPECT_TRUE(io::attach_children(t, std::move(first), limited).empty());
  auto second = io::read_children(2, *t.tiles[2].pending, t.tiles.size(), fetch, limited);
  auto errors = io::attach_children(t, std::move(second), limited);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].first, 2u);
  EXPECT_NE(errors[0].second.find("tile limit"), std::string::npos) << errors[0].second;
  EXPECT_FALSE(t.tiles[2].pending);
  EXPECT_TRUE(t.tiles[2].children.empty());
  fs::remove_all(dir);
}
