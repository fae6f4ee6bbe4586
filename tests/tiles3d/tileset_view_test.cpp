// The viewer over a tileset without a GPU: double-click picking against the drawn tiles' chunks
// (bounds skip chunks out of the cone; resident but undrawn tiles are not picked), the pickers
// registry the camera controller asks, and the streamer's budget and max SSE changed at run time.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>

#include <glm/geometric.hpp>

#include "stipple/engine/registry.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
using namespace stipple::tiles3d;
using namespace stipple::pc;
namespace fs = std::filesystem;

namespace {

// One chunk at `origin` with the given offsets; bounds from the points unless given.
pc::PointChunk chunk_at(const glm::dvec3& origin, std::vector<glm::vec3> offsets) {
  pc::PointChunk c;
  c.origin = origin;
  for (const auto& o : offsets) {
    c.vertices.push_back({o.x, o.y, o.z, 0xffffffffu, 0});
    c.bounds.extend(origin + glm::dvec3(o));
  }
  return c;
}

std::shared_ptr<const TileChunks> tile(uint32_t id, std::vector<pc::PointChunk> chunks) {
  auto t = std::make_shared<TileChunks>();
  t->tile = id;
  for (const auto& c : chunks) t->points += c.vertices.size();
  t->chunks = std::move(chunks);
  return t;
}

// Tiles 0..3: tile 1 has a point at (0, 0, -50) (far from its origin, as tiles have large
// origins and small float offsets), tile 2 one at (0, 0, -30) but is resident only (not
// drawn), tile 3 one at (0, 0, -20) whose bounds claim it lies elsewhere.
TilesetStream stream_state() {
  TilesetStream s;
  s.chunks.resize(4);
  const glm::dvec3 far_origin(1e6, 2e3, -3e6);
  s.chunks[1] = tile(1, {chunk_at(far_origin, {glm::vec3(glm::dvec3(0, 0, -50) - far_origin),
                                               glm::vec3(glm::dvec3(5, 0, -50) - far_origin)}),
                         chunk_at({0, 0, -40}, {{3, 0, 0}})});
  s.chunks[2] = tile(2, {chunk_at({0, 0, -30}, {{0, 0, 0}})});
  auto lying = chunk_at({0, 0, -20}, {{0, 0, 0}});
  lying.bounds = {{100, 100, 100}, {101, 101, 101}};  // the picker trusts bounds: skipped
  s.chunks[3] = tile(3, {lying});
  s.draw = {1, 3};
  return s;
}

}  // namespace

TEST(TilesetPicking, NearestDrawnPointAlongTheRay) {
  TilesetStream s = stream_state();
  const PickRay down_z{{0, 0, 0}, {0, 0, -1}, 0.01};
  auto hit = pick_tileset_point(s, down_z);
  ASSERT_TRUE(hit);
  // Tile 2's nearer point is not drawn; tile 3's is outside its (stated) bounds.
  EXPECT_NEAR(glm::distance(hit->point, glm::dvec3(0, 0, -50)), 0, 1e-3);
  EXPECT_NEAR(hit->t, 50, 1e-3);
  // Once tile 2 is drawn too, its point is the nearest.
  s.draw = {1, 2, 3};
  hit = pick_tileset_point(s, down_z);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(glm::distance(hit->point, glm::dvec3(0, 0, -30)), 0, 1e-9);
  // A ray through (3, 0, -40) from the side: the chunk at -40 alone.
  hit = pick_tileset_point(s, {{3, 0, 0}, {0, 0, -1}, 0.001});
  ASSERT_TRUE(hit);
  EXPECT_NEAR(glm::distance(hit->point, glm::dvec3(3, 0, -40)), 0, 1e-9);
  // Empty space: behind, and beside every point.
  EXPECT_FALSE(pick_tileset_point(s, {{0, 0, 0}, {0, 0, 1}, 0.01}));
  EXPECT_FALSE(pick_tileset_point(s, {{0, 0, 0}, glm::normalize(glm::dvec3(0, 1, -1)), 0.01}));
  s.draw.clear();
  EXPECT_FALSE(pick_tileset_point(s, down_z));
}

TEST(TilesetPicking, ConeTestAgainstBounds) {
  const Aabb box{{-1, -1, -11}, {1, 1, -9}};
  EXPECT_TRUE(cone_may_hit(box, {{0, 0, 0}, {0, 0, -1}, 0.0}, 1e30));
  EXPECT_FALSE(cone_may_hit(box, {{0, 0, 0}, {0, 0, 1}, 0.1}, 1e30));  // behind
  EXPECT_FALSE(cone_may_hit(box, {{0, 0, 0}, {0, 0, -1}, 0.0}, 5.0));  // past a better hit
  // Beside the box, 1.5 off the axis: the box grows by tan_radius times its farthest corner's
  // distance (11.6 m), so a cone of 0.15 may reach it and one of 0.1 cannot.
  EXPECT_TRUE(cone_may_hit(box, {{2.5, 0, 0}, {0, 0, -1}, 0.15}, 1e30));
  EXPECT_FALSE(cone_may_hit(box, {{2.5, 0, 0}, {0, 0, -1}, 0.1}, 1e30));
  EXPECT_FALSE(cone_may_hit(Aabb{}, {{0, 0, 0}, {0, 0, -1}, 1.0}, 1e30));
}

namespace {
std::optional<PickHit> first_picker(Registry&, const PickRay&) {
  return PickHit{{1, 2, 3}, 10.0};
}
std::optional<PickHit> nearer_picker(Registry&, const PickRay&) {
  return PickHit{{4, 5, 6}, 5.0};
}
std::optional<PickHit> missing_picker(Registry&, const PickRay&) {
  return std::nullopt;
}
}  // namespace

TEST(TilesetPicking, SceneKeepsTheNearestOfEveryPicker) {
  Registry main;
  EXPECT_FALSE(pick_scene(main, {}));
  add_scene_picker(main, first_picker);
  add_scene_picker(main, missing_picker);
  EXPECT_EQ(pick_scene(main, {})->point, glm::dvec3(1, 2, 3));
  add_scene_picker(main, nearer_picker);
  EXPECT_EQ(pick_scene(main, {})->point, glm::dvec3(4, 5, 6));
  EXPECT_EQ(main.resource<ScenePickers>().pickers.size(), 3u);
}

namespace {

struct Settled {
  uint32_t drawn = 0;
  uint64_t resident_bytes = 0, drawn_bytes = 0, max_resident_bytes = 0;
};

// Updates until the streamer is idle; the largest resident size seen on the way.
Settled settle(tiles3d::TileStreamer& streamer, const tiles3d::View& view) {
  Settled out;
  for (int i = 0; i < 500; ++i) {
    const auto& selection = streamer.update(view);
    out.max_resident_bytes = std::max(out.max_resident_bytes, streamer.stats().resident_bytes);
    if (streamer.idle()) {
      out.drawn = uint32_t(selection.render.size());
      for (uint32_t t : selection.render) out.drawn_bytes += streamer.states()[t].bytes;
      break;
    }
    streamer.wait_for_progress();
  }
  EXPECT_TRUE(streamer.idle());
  out.resident_bytes = streamer.stats().resident_bytes;
  return out;
}

}  // namespace

TEST(TilesetStreamer, BudgetAndMaxSseChangeAtRunTime) {
  fs::path dir = fs::temp_directory_path() / ("stipple_view_budget_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ASSERT_EQ(test::write_grid_tileset(dir, 4, 1000), 85);
  auto ts = std::make_shared<io::Tileset>(io::load_tileset((dir / "tileset.json").string()));
  tiles3d::StreamerOptions options;
  options.threads = 2;
  options.traversal.memory_budget = 64 << 20;  // everything fits
  options.traversal.max_sse = 4;
  tiles3d::TileStreamer streamer(ts, options);
  // Far to near: the coarse tiles seen on the way stay resident, unused.
  tiles3d::View view;
  Settled before;
  for (double d : {8000.0, 3000.0, 1200.0, 400.0}) {
    view.camera.look_at(z_up_to_y_up({300, 300 - d, d * 0.6}), z_up_to_y_up({300, 300, 0}));
    view.camera.near_plane = 1.0;
    before = settle(streamer, view);
  }
  ASSERT_GT(before.drawn, 4u);
  ASSERT_LT(before.drawn_bytes, before.resident_bytes);
  const uint64_t evictions = streamer.stats().evictions;

  // A budget between what is drawn and what is resident: unused tiles go, drawn ones stay.
  tiles3d::TraversalOptions lower = streamer.traversal_options();
  lower.memory_budget = (before.drawn_bytes + before.resident_bytes) / 2;
  streamer.set_traversal_options(lower);
  EXPECT_EQ(streamer.traversal_options().memory_budget, lower.memory_budget);
  Settled after = settle(streamer, view);
  EXPECT_LE(after.resident_bytes, lower.memory_budget);
  EXPECT_LT(after.resident_bytes, before.resident_bytes);
  EXPECT_GT(streamer.stats().evictions, evictions);
  EXPECT_EQ(after.drawn, before.drawn);

  // A coarser max SSE: fewer (coarser) tiles, loaded within the lower budget.
  tiles3d::TraversalOptions coarser = lower;
  coarser.max_sse = 64;
  streamer.set_traversal_options(coarser);
  Settled coarse = settle(streamer, view);
  EXPECT_GT(coarse.drawn, 0u);
  EXPECT_LT(coarse.drawn, before.drawn);
  EXPECT_LE(coarse.max_resident_bytes, lower.memory_budget);
  EXPECT_TRUE(streamer.errors().empty());
  fs::remove_all(dir);
}
