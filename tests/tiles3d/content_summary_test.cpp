// Tile contents summarised from their headers (io::summarize_content): the points a pnts or glb
// declares without decoding, what is not points (b3dm, glb triangles) and named as such;
// not-point content decodes to no points with a reason instead of failing its tile; and a
// tileset whose points are a small part of its volume is framed on the points.
#include <filesystem>

#include <gtest/gtest.h>

#include "stipple/core/error.hpp"
#include "stipple/io/content_summary.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
using namespace stipple::test;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// A glb of one mesh with a point primitive of `points` points (if any) and a triangle primitive
// (if `triangles`), used by `uses` nodes.
Bytes glb(uint32_t points, bool triangles, int uses) {
  Bytes bin;
  append(bin, std::vector<float>(9, 0.0f));
  json prims = json::array();
  if (points) prims.push_back({{"mode", 0}, {"attributes", {{"POSITION", 0}}}});
  if (triangles) prims.push_back({{"attributes", {{"POSITION", 1}}}});
  json nodes = json::array();
  for (int i = 0; i < uses; ++i) nodes.push_back({{"mesh", 0}});
  json j = {{"asset", {{"version", "2.0"}}},
            {"buffers", {{{"byteLength", bin.size()}}}},
            {"bufferViews", {{{"buffer", 0}, {"byteLength", bin.size()}}}},
            {"accessors",
             {{{"componentType", 5126}, {"count", points}, {"type", "VEC3"}},
              {{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}}}},
            {"meshes", {{{"primitives", prims}}}},
            {"nodes", nodes}};
  return make_glb(j, bin);
}

Bytes b3dm() {
  Bytes b = {'b', '3', 'd', 'm'};
  put_u32(b, 1);
  put_u32(b, 28);
  for (int i = 0; i < 4; ++i) put_u32(b, 0);
  return b;
}

io::Fetcher files() {
  return [](const std::string& u) { return io::fetch(u); };
}

}  // namespace

TEST(ContentSummary, PointsFromHeadersAndWhatIsNotDrawn) {
  const fs::path dir = fresh_temp_dir("summary");
  const double rtc[3] = {0, 0, 0};
  write_file(dir / "a.pnts", grid_pnts(1234, 1.0f, rtc, 10));
  write_file(dir / "b.glb", glb(500, false, 2));  // one mesh used by two nodes
  write_file(dir / "c.glb", glb(0, true, 1));
  write_file(dir / "d.glb", glb(70, true, 1));
  write_file(dir / "e.b3dm", b3dm());
  write_file(dir / "f.pnts", Bytes{'p', 'n', 't', 's', 1, 0});
  auto s = [&](const char* name) { return io::summarize_content((dir / name).string(), files()); };
  auto a = s("a.pnts"), b = s("b.glb"), c = s("c.glb"), d = s("d.glb"), e = s("e.b3dm");
  EXPECT_EQ(a.type, "pnts");
  EXPECT_EQ(a.points, 1234u);
  EXPECT_TRUE(a.drawable);
  EXPECT_EQ(b.type, "glb");
  EXPECT_EQ(b.points, 1000u);
  EXPECT_TRUE(b.drawable);
  EXPECT_EQ(c.points, 0u);
  EXPECT_EQ(c.other_primitives, 1u);
  EXPECT_FALSE(c.drawable);
  EXPECT_EQ(d.points, 70u);
  EXPECT_EQ(d.other_primitives, 1u);
  EXPECT_TRUE(d.drawable);
  EXPECT_EQ(e.type, "b3dm");
  EXPECT_FALSE(e.drawable);
  EXPECT_TRUE(e.error.empty());
  // A cut header is an error naming the file, not a throw.
  auto f = s("f.pnts");
  EXPECT_NE(f.error.find("f.pnts"), std::string::npos) << f.error;

  std::vector<std::string> uris;
  for (const char* n : {"a.pnts", "b.glb", "c.glb", "d.glb", "e.b3dm", "f.pnts"})
    uris.push_back((dir / n).string());
  io::ContentTotals t = io::summarize_contents(uris, files(), 3);
  EXPECT_EQ(t.contents, 6u);
  EXPECT_EQ(t.points, 1234u + 1000u + 70u);
  EXPECT_EQ(t.by_type["glb"], 3u);
  EXPECT_EQ(t.by_type["pnts"], 2u);
  EXPECT_EQ(t.not_drawn["b3dm"], 1u);
  EXPECT_EQ(t.not_drawn["glb"], 1u);
  EXPECT_EQ(t.other_primitives, 2u);
  EXPECT_EQ(t.errors.size(), 1u);
  fs::remove_all(dir);
}

TEST(ContentSummary, MeshContentDecodesToNoPointsWithAReason) {
  io::PointContent m = tiles3d::decode_content(b3dm(), "m.b3dm", {}, {});
  EXPECT_EQ(m.point_count, 0u);
  EXPECT_EQ(m.not_drawn, io::describe_content_type("b3dm"));
  io::PointContent g = tiles3d::decode_content(glb(0, true, 1), "g.glb", {}, {});
  EXPECT_EQ(g.point_count, 0u);
  EXPECT_EQ(g.not_drawn, "glb meshes");
  EXPECT_THROW(tiles3d::decode_content(Bytes{'x', 'y', 'z', 'w'}, "x.bin", {}, {}), Error);
}

// A city of meshes (root, 1 km) with a small point cloud in one child (10 m): framed on the
// points, with one warning naming the b3dm content; a tileset of points only keeps its root.
TEST(ContentSummary, FramesThePointContent) {
  const fs::path dir = fresh_temp_dir("frame");
  const double rtc[3] = {100, 100, 0};
  write_file(dir / "city.b3dm", b3dm());
  write_file(dir / "points.pnts", grid_pnts(300, 10.0f, rtc, 20));
  auto box = [](double cx, double cy, double h) {
    return json{{"box", {cx, cy, h, h, 0, 0, 0, h, 0, 0, 0, h}}};
  };
  json ts = {{"asset", {{"version", "1.0"}}},
             {"geometricError", 100},
             {"root",
              {{"boundingVolume", box(0, 0, 500)},
               {"geometricError", 50},
               {"content", {{"uri", "city.b3dm"}}},
               {"children",
                {{{"boundingVolume", box(105, 105, 5)},
                  {"geometricError", 0},
                  {"content", {{"uri", "points.pnts"}}}}}}}}};
  write_json(dir / "tileset.json", ts);
  io::Tileset t = io::load_tileset((dir / "tileset.json").string());
  const glm::dmat4 m = tiles3d::world_from_tileset(t);
  std::string warning;
  std::set<std::string> kinds;
  Aabb b = tiles3d::drawable_world_bounds(t, m, files(), &warning, &kinds);
  EXPECT_NEAR(glm::length(b.size()), std::sqrt(3.0) * 10, 1e-6);
  EXPECT_NEAR(b.center().x, 105, 1e-6);
  EXPECT_NE(warning.find("b3dm"), std::string::npos) << warning;
  EXPECT_EQ(kinds, std::set<std::string>{io::describe_content_type("b3dm")});
  // Points only: the root volume, no warning.
  ts["root"]["content"]["uri"] = "points.pnts";
  write_json(dir / "tileset.json", ts);
  t = io::load_tileset((dir / "tileset.json").string());
  warning.clear();
  b = tiles3d::drawable_world_bounds(t, m, files(), &warning);
  EXPECT_NEAR(glm::length(b.size()), std::sqrt(3.0) * 1000, 1e-6);
  EXPECT_TRUE(warning.empty()) << warning;
  fs::remove_all(dir);
}
