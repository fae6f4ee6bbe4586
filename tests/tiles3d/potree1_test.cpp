// Potree 1.x clouds (cloud.js, .hrc hierarchy files, .bin/.las/.laz nodes) written by the test's
// own writer (tests/common/potree1_writer.hpp, from the format's description) read back as a
// streamed octree: every node is a tile, .hrc files below the first are read when reached, and
// every point comes back with every attribute, in formats 1.7 (attribute names) and 1.8
// (attribute objects), binary and LAZ nodes; the streamer draws them all; broken files are clear
// errors naming the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <tuple>

#include "potree1_writer.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/potree.hpp"
#include "stipple/io/source.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/tiles3d/render_load.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
using namespace stipple::test;
namespace fs = std::filesystem;

namespace {

io::Fetcher files() {
  return [](const std::string& u) { return io::fetch(u); };
}

// Seeds for the fuzzer when STIPPLE_WRITE_POTREE_SEEDS names a folder.
void seed(const fs::path& dir) {
  if (const char* out = std::getenv("STIPPLE_WRITE_POTREE_SEEDS")) {
    fs::copy_file(dir / "cloud.js", fs::path(out) / "cloud.js.seed",
                  fs::copy_options::overwrite_existing);
    fs::copy_file(dir / "data" / "r" / "r.hrc", fs::path(out) / "r.hrc.seed",
                  fs::copy_options::overwrite_existing);
  }
}

using Row = std::tuple<int64_t, int64_t, int64_t, uint32_t, double, double, double, double, double>;

Row row(int64_t x, int64_t y, int64_t z, uint32_t rgb, double intensity, double cls, double ret,
        double returns, double gps) {
  return {x, y, z, rgb, intensity, cls, ret, returns, gps};
}

// Reads the whole tree and every node; checks each point against its node's cube and, where the
// nodes carry normals, against the writer's normal. Returns every point as rows.
std::vector<Row> read_all(const fs::path& dir, const Potree1WriteResult& w, bool normals,
                          bool oct16, std::vector<std::pair<double, double>>* extras = nullptr) {
  const std::string cloud = (dir / "cloud.js").string();
  EXPECT_TRUE(io::is_potree_input(cloud));
  io::TilesetOptions options;
  io::Tileset ts = io::load_tileset(cloud, files(), options);
  EXPECT_TRUE(ts.potree);
  EXPECT_EQ(ts.potree->major, 1);
  EXPECT_TRUE(io::expand_all(ts, files(), options, 1000000));
  EXPECT_TRUE(ts.errors.empty()) << ts.errors.front();
  EXPECT_EQ(ts.tiles.size(), w.nodes);
  EXPECT_EQ(ts.subtrees, w.hrc_files);  // every .hrc read once
  std::vector<Row> got;
  for (const io::Tile& tile : ts.tiles) {
    EXPECT_NEAR(tile.geometric_error, ts.potree->spacing / double(1u << tile.depth), 1e-12);
    for (const auto& uri : tile.contents) {
      io::PointContent c = io::decode_potree_node(*ts.potree, io::fetch(uri), uri);
      EXPECT_EQ(c.point_count, tile.content_points);
      auto v = [&](const char* k, size_t i) { return c.attributes.at(k).values.at(i); };
      if (normals) {
        EXPECT_EQ(c.normals.size(), c.point_count);
      }
      for (size_t i = 0; i < c.point_count; ++i) {
        const glm::dvec3 p = c.center + glm::dvec3(c.positions[i]);
        EXPECT_LE(tile.box.distance(p), 1e-3);  // inside the node's cube
        got.push_back(row(std::llround(p.x * 1000), std::llround(p.y * 1000),
                          std::llround(p.z * 1000), c.rgba[i] & 0xffffff, v("intensity", i),
                          v("classification", i), v("return_number", i), v("number_of_returns", i),
                          v("gps_time", i)));
        if (extras) extras->emplace_back(v("extra int16", i), v("extra float", i));
        if (normals) {
          // The source point's normal: its GPS time names it (300000 + i / 10000).
          const size_t src = size_t(std::llround((v("gps_time", i) - 300000.0) * 1e4));
          const auto n = potree1_normal(src);
          const glm::vec3 d = c.normals[i];
          const double dot = d.x * n[0] + d.y * n[1] + d.z * n[2];
          // Floats exactly; oct16 in 8 bits an axis (and PotreeConverter's 128 against 255).
          EXPECT_GT(dot, oct16 ? 0.997 : 0.999999) << src;
        }
      }
    }
  }
  return got;
}

std::vector<Row> source_rows(const std::vector<PotreePoint>& points, bool las) {
  std::vector<Row> want;
  for (const auto& p : points)
    want.push_back(row(std::llround(p.x * 1000), std::llround(p.y * 1000), std::llround(p.z * 1000),
                       uint32_t(p.r / 256) | uint32_t(p.g / 256) << 8 | uint32_t(p.b / 256) << 16,
                       p.intensity, las ? p.classification % 32 : p.classification, p.return_number,
                       p.number_of_returns, p.gps_time));
  std::sort(want.begin(), want.end());
  return want;
}

}  // namespace

TEST(Potree1, Format18ReadsEveryNodeAndAttribute) {
  const fs::path dir = fresh_temp_dir("potree1-18");
  const auto points = potree_points(20000);
  const Potree1WriteResult w = write_potree1(dir, points, {"1.8", "BINARY", 500, 2});
  ASSERT_GE(w.depth, 3);
  ASSERT_GT(w.hrc_files, 2u);
  seed(dir);
  std::vector<std::pair<double, double>> extras;
  std::vector<Row> got = read_all(dir, w, true, false, &extras);
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, source_rows(points, false));
  // Extra attributes of 1.8 objects keep their own names and types.
  std::vector<std::pair<double, double>> want_extras;
  for (const auto& p : points) want_extras.emplace_back(p.i16, p.f32);
  std::sort(extras.begin(), extras.end());
  std::sort(want_extras.begin(), want_extras.end());
  EXPECT_EQ(extras, want_extras);
  fs::remove_all(dir);
}

TEST(Potree1, Format17NamedAttributesAndOct16Normals) {
  const fs::path dir = fresh_temp_dir("potree1-17");
  const auto points = potree_points(6000);
  const Potree1WriteResult w = write_potree1(dir, points, {"1.7", "BINARY", 300, 3});
  ASSERT_GE(w.depth, 3);
  std::vector<Row> got = read_all(dir, w, true, true);
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, source_rows(points, false));
  fs::remove_all(dir);
}

TEST(Potree1, LazNodes) {
  const fs::path dir = fresh_temp_dir("potree1-laz");
  const auto points = potree_points(5000);
  const Potree1WriteResult w = write_potree1(dir, points, {"1.8", "LAZ", 400, 2});
  ASSERT_TRUE(fs::exists(dir / "data" / "r" / "r.laz"));
  std::vector<Row> got = read_all(dir, w, false, false);
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, source_rows(points, true));
  fs::remove_all(dir);
}

TEST(Potree1, StreamsEveryPointForRendering) {
  const fs::path dir = fresh_temp_dir("potree1-render");
  write_potree1(dir, potree_points(12000), {"1.8", "BINARY", 400, 1});
  tiles3d::RenderLoadOptions o;
  o.streamer.traversal.max_sse = 0.01;  // refine everything
  const std::string cloud = (dir / "cloud.js").string();
  ASSERT_EQ(io::source_format(cloud), io::SourceFormat::Potree);
  auto r = tiles3d::load_tileset_for_render(cloud, o);
  EXPECT_TRUE(r.errors.empty()) << r.errors.front().message;
  EXPECT_EQ(r.cloud.point_count, 12000u);
  EXPECT_TRUE(r.cloud.attributes.has_rgb);
  EXPECT_TRUE(r.cloud.attributes.has_intensity);
  EXPECT_TRUE(r.cloud.attributes.has_classification);
  fs::remove_all(dir);
}

TEST(Potree1, BrokenFilesAreClearErrors) {
  const fs::path dir = fresh_temp_dir("potree1-bad");
  write_potree1(dir, potree_points(3000), {"1.8", "BINARY", 200, 1});
  const std::string cloud = (dir / "cloud.js").string();
  const std::string original = [&] {
    std::ifstream in(dir / "cloud.js");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  auto expect_error = [&](const std::string& text, const char* needle, const char* file) {
    std::ofstream(dir / "cloud.js") << text;
    try {
      io::load_tileset(cloud, files());
      ADD_FAILURE() << "no error for " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
    std::ofstream(dir / "cloud.js") << original;
  };
  auto edit = [&](const char* from, const char* to) {
    std::string s = original;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, std::strlen(from), to);
  };
  // 1.4 lists its octree in cloud.js: without the list there is none.
  expect_error(edit("\"version\": \"1.8\"", "\"version\": \"1.4\""), "\"hierarchy\"", "cloud.js");
  expect_error(edit("\"version\": \"1.8\"", "\"version\": \"2.0\""), "version", "cloud.js");
  expect_error(edit("\"hierarchyStepSize\": 1", "\"hierarchyStepSize\": 0"), "hierarchyStepSize",
               "cloud.js");
  expect_error(edit("\"octreeDir\": \"data\"", "\"octreeDir\": \"\""), "octreeDir", "cloud.js");
  expect_error(edit("\"NORMAL\"", "\"NORMAL_OCT16\""), "NORMAL_OCT16 must be 2 bytes", "cloud.js");
  expect_error(edit("\"POSITION_CARTESIAN\"", "\"POSITION\""), "no POSITION_CARTESIAN", "cloud.js");
  expect_error("{", "not a JSON object", "cloud.js");
  // Format 1.7 names only the attributes it defines.
  std::string named = original;
  named.replace(named.find("\"version\": \"1.8\""), 16, "\"version\": \"1.7\"");
  const size_t list = named.find("\"pointAttributes\"");
  named.replace(list, named.find(']', list) + 1 - list,
                "\"pointAttributes\": [\"POSITION_CARTESIAN\", \"HEAT\"]");
  expect_error(named, "unknown point attribute 'HEAT'", "cloud.js");
  // The root's .hrc: cut inside a record, then cut by a whole record (a child has none).
  const fs::path hrc = dir / "data" / "r" / "r.hrc";
  const uintmax_t hrc_size = fs::file_size(hrc);
  fs::resize_file(hrc, hrc_size - 2);
  expect_error(original, "5-byte records", "r.hrc");
  fs::resize_file(hrc, hrc_size - 5);
  expect_error(original, "no record", "r.hrc");
  // A node whose bytes are cut: its decode names its URI.
  write_potree1(dir, potree_points(3000), {"1.8", "BINARY", 200, 1});
  io::Tileset ts = io::load_tileset(cloud, files());
  const std::string uri = ts.tiles[0].contents.at(0);
  std::vector<uint8_t> bytes = io::fetch(uri);
  bytes.pop_back();
  try {
    io::decode_potree_node(*ts.potree, bytes, uri);
    ADD_FAILURE() << "a cut node decoded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("r.bin"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// Formats 1.3 and 1.4 (PotreeConverter before 1.5) list the whole octree in cloud.js and keep
// every node's file in octreeDir itself: 1.4's binary nodes are <name>.bin of uint32 positions
// from the node's corner, 1.3's are <name> of float32 positions in the cloud's coordinates. Every
// node is a tile from the start (nothing pending), and every point comes back.
TEST(Potree1, Formats13And14ListTheirOctreeInCloudJs) {
  for (const char* version : {"1.4", "1.3"}) {
    SCOPED_TRACE(version);
    const bool floats = std::string(version) == "1.3";
    const fs::path dir = fresh_temp_dir(std::string("potree1-") + version);
    // 1.3's floats hold millimetres only near the origin (at UTM northings they step by 0.25 m).
    const auto points = floats ? potree_points(6000, 500, 400) : potree_points(6000);
    const Potree1WriteResult w = write_potree1(dir, points, {version, "BINARY", 300, 1});
    ASSERT_GE(w.depth, 2);
    EXPECT_EQ(w.hrc_files, 0u);
    ASSERT_TRUE(fs::exists(dir / "data" / (floats ? "r0" : "r0.bin")) ||
                fs::exists(dir / "data" / (floats ? "r1" : "r1.bin")));
    const std::string cloud = (dir / "cloud.js").string();
    io::Tileset ts = io::load_tileset(cloud, files());
    ASSERT_TRUE(ts.potree);
    EXPECT_EQ(ts.potree->minor, floats ? 3 : 4);
    EXPECT_TRUE(ts.errors.empty()) << ts.errors.front();
    EXPECT_EQ(ts.pending, 0u);
    EXPECT_EQ(ts.tiles.size(), w.nodes);
    std::vector<std::tuple<int64_t, int64_t, int64_t, uint32_t>> got, want;
    for (const auto& p : points)
      want.emplace_back(std::llround(p.x * 1000), std::llround(p.y * 1000),
                        std::llround(p.z * 1000),
                        uint32_t(p.r / 256) | uint32_t(p.g / 256) << 8 | uint32_t(p.b / 256) << 16);
    uint64_t declared = 0;
    for (size_t t = 0; t < ts.tiles.size(); ++t) {
      const io::Tile& tile = ts.tiles[t];
      EXPECT_LT(tile.parent, int32_t(t));  // parents before children
      EXPECT_NEAR(tile.geometric_error, ts.potree->spacing / double(1u << tile.depth), 1e-12);
      declared += tile.content_points;
      for (const auto& uri : tile.contents) {
        io::PointContent c = io::decode_potree_node(*ts.potree, io::fetch(uri), uri);
        EXPECT_EQ(c.point_count, tile.content_points);
        for (size_t i = 0; i < c.point_count; ++i) {
          const glm::dvec3 p = c.center + glm::dvec3(c.positions[i]);
          EXPECT_LE(tile.box.distance(p), 1e-3);
          got.emplace_back(std::llround(p.x * 1000), std::llround(p.y * 1000),
                           std::llround(p.z * 1000), c.rgba[i] & 0xffffff);
        }
      }
    }
    EXPECT_EQ(declared, points.size());
    std::sort(got.begin(), got.end());
    std::sort(want.begin(), want.end());
    EXPECT_TRUE(got == want);
    // The streamer draws them all.
    tiles3d::RenderLoadOptions o;
    o.streamer.traversal.max_sse = 0.01;
    auto r = tiles3d::load_tileset_for_render(cloud, o);
    EXPECT_TRUE(r.errors.empty()) << r.errors.front().message;
    EXPECT_EQ(r.cloud.point_count, points.size());
    fs::remove_all(dir);
  }
}

// A 1.4 hierarchy with bad entries: each is an error of its own naming it (and its place), its
// subtree is left out, the rest is read; without a root the cloud is an error.
TEST(Potree1, BadHierarchyEntriesAreErrorsOfTheirOwn) {
  const fs::path dir = fresh_temp_dir("potree1-14-bad");
  write_potree1(dir, potree_points(3000), {"1.4", "BINARY", 200, 1});
  const std::string cloud = (dir / "cloud.js").string();
  nlohmann::json j;
  {
    std::ifstream in(dir / "cloud.js");
    in >> j;
  }
  nlohmann::json& h = j["hierarchy"];
  const size_t nodes = h.size();
  ASSERT_GT(nodes, 3u);
  const std::string second = h[1][0];
  h.push_back({"r9", 5});     // not an octant
  h.push_back({second, 7});   // listed twice
  h.push_back({"r7777", 5});  // its parent r777 is not listed
  h.push_back({"r0", -4});    // not a count
  std::ofstream(dir / "cloud.js") << j.dump();
  io::Tileset ts = io::load_tileset(cloud, files());
  EXPECT_EQ(ts.tiles.size(), nodes);
  ASSERT_EQ(ts.errors.size(), 4u);
  auto has = [&](const std::string& a, const std::string& b) {
    return std::any_of(ts.errors.begin(), ts.errors.end(), [&](const std::string& e) {
      return e.find("cloud.js") != std::string::npos && e.find(a) != std::string::npos &&
             e.find(b) != std::string::npos;
    });
  };
  EXPECT_TRUE(has("(r9)", "not [a node name"));
  EXPECT_TRUE(has("(" + second + ")", "second time"));
  EXPECT_TRUE(has("(r7777)", "parent r777 is not listed"));
  EXPECT_TRUE(has("[\"r0\",-4]", "not [a node name"));
  // No root.
  nlohmann::json no_root = j;
  no_root["hierarchy"].erase(0);
  std::ofstream(dir / "cloud.js") << no_root.dump();
  try {
    io::load_tileset(cloud, files());
    ADD_FAILURE() << "a hierarchy without its root was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cloud.js"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no root node r"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
