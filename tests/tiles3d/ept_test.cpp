// Entwine Point Tile datasets written by the test's own writer (tests/common/ept_writer.hpp, from
// the EPT description) read back as a streamed octree for each data type (laszip, binary,
// zstandard): every node a tile, hierarchy files behind -1 counts read when reached, every point
// back with its attributes (every dimension type in the binary ones); the streamer draws them
// all; broken files are clear errors naming the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "ept_writer.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/fetch.hpp"
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

}  // namespace

class EptData : public testing::TestWithParam<const char*> {};

TEST_P(EptData, ReadsEveryNodeAndPoint) {
  const std::string type = GetParam();
  const fs::path dir = fresh_temp_dir("ept-" + type);
  const auto points = ept_points(12000);
  const EptWriteResult w = write_ept(dir, points, type, 300, 2);
  ASSERT_GE(w.depth, 3);
  ASSERT_GT(w.hierarchy_files, 2u);
  if (const char* out = std::getenv("STIPPLE_WRITE_EPT_SEEDS"); out && type == "binary") {
    fs::copy_file(dir / "ept.json", fs::path(out) / "ept.json",
                  fs::copy_options::overwrite_existing);
    fs::copy_file(dir / "ept-hierarchy/0-0-0-0.json", fs::path(out) / "0-0-0-0.json",
                  fs::copy_options::overwrite_existing);
  }
  const std::string meta = (dir / "ept.json").string();
  ASSERT_TRUE(io::is_ept_input(meta));
  io::TilesetOptions options;
  io::Tileset ts = io::load_tileset(meta, files(), options);
  ASSERT_TRUE(ts.ept);
  EXPECT_GT(ts.pending, 0u);
  ASSERT_TRUE(io::expand_all(ts, files(), options, 1000000));
  EXPECT_TRUE(ts.errors.empty()) << ts.errors.front();
  EXPECT_EQ(ts.tiles.size(), w.nodes);
  EXPECT_EQ(ts.subtrees, w.hierarchy_files);
  using Row = std::tuple<int64_t, int64_t, int64_t, uint32_t, double, double, double, double>;
  std::vector<Row> want, got;
  for (const auto& p : points)
    want.emplace_back(
        std::llround(p.x * 100), std::llround(p.y * 100), std::llround(p.z * 100),
        uint32_t(p.red >> 8) | uint32_t(p.green >> 8) << 8 | uint32_t(p.blue >> 8) << 16,
        p.intensity, p.classification, p.return_number, p.gps_time);
  std::vector<double> extras_want, extras_got;
  if (type != "laszip")
    for (const auto& p : points)
      for (double v : {double(p.i8), double(p.i16), double(p.i64), double(p.u32), double(p.u64),
                       double(p.f32), double(p.number_of_returns)})
        extras_want.push_back(v);
  for (const auto& tile : ts.tiles)
    for (const auto& uri : tile.contents) {
      io::PointContent c = io::decode_ept_node(*ts.ept, io::fetch(uri), uri);
      auto v = [&](const char* k, size_t i) { return c.attributes.at(k).values.at(i); };
      for (size_t i = 0; i < c.point_count; ++i) {
        const glm::dvec3 p = c.center + glm::dvec3(c.positions[i]);
        EXPECT_LE(tile.box.distance(p), 0.01);
        got.emplace_back(std::llround(p.x * 100), std::llround(p.y * 100), std::llround(p.z * 100),
                         c.rgba[i] & 0xffffff, v("intensity", i), v("classification", i),
                         v("return_number", i), v("gps_time", i));
        if (type != "laszip")
          for (const char* k :
               {"Int8", "Int16", "Int64", "UInt32", "UInt64", "Float", "number_of_returns"})
            extras_got.push_back(v(k, i));
      }
    }
  ASSERT_EQ(got.size(), want.size());
  std::sort(want.begin(), want.end());
  std::sort(got.begin(), got.end());
  EXPECT_TRUE(got == want);
  std::sort(extras_want.begin(), extras_want.end());
  std::sort(extras_got.begin(), extras_got.end());
  EXPECT_TRUE(extras_got == extras_want);
  tiles3d::RenderLoadOptions o;
  o.streamer.traversal.max_sse = 0.01;
  auto r = tiles3d::load_tileset_for_render(meta, o);
  EXPECT_TRUE(r.errors.empty()) << r.errors.front().message;
  EXPECT_EQ(r.cloud.point_count, points.size());
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Ept, EptData, testing::Values("laszip", "binary", "zstandard"));

TEST(Ept, BrokenFilesAreClearErrors) {
  const fs::path dir = fresh_temp_dir("ept-bad");
  write_ept(dir, ept_points(2000), "zstandard", 200, 1);
  const std::string meta = (dir / "ept.json").string();
  std::string original;
  {
    std::ifstream in(dir / "ept.json");
    original.assign(std::istreambuf_iterator<char>(in), {});
  }
  auto expect_error = [&](const std::string& text, const char* needle) {
    std::ofstream(dir / "ept.json") << text;
    try {
      io::load_tileset(meta, files());
      ADD_FAILURE() << "no error for " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("ept.json"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  auto edit = [&](const char* from, const char* to) {
    std::string s = original;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, std::strlen(from), to);
  };
  expect_error(edit("\"zstandard\"", "\"brotli\""), "dataType");
  expect_error(edit("\"span\": 128", "\"span\": 0"), "span");
  expect_error(edit("\"name\": \"X\"", "\"name\": \"Q\""), "X, Y or Z");
  expect_error("[]", "not a JSON object");
  std::ofstream(dir / "ept.json") << original;
  // A hierarchy file naming a node outside its subtree, and one that is not JSON.
  std::ofstream(dir / "ept-hierarchy/0-0-0-0.json")
      << R"({"0-0-0-0": 5, "1-0-0-0": 3, "2-3-3-3": 1})";
  EXPECT_THROW(io::load_tileset(meta, files()), Error);
  std::ofstream(dir / "ept-hierarchy/0-0-0-0.json") << "{";
  EXPECT_THROW(io::load_tileset(meta, files()), Error);
  // A node whose zstd data is cut: its decode names its URI.
  write_ept(dir, ept_points(2000), "zstandard", 200, 1);
  io::Tileset ts = io::load_tileset(meta, files());
  const std::string uri = ts.tiles[0].contents.at(0);
  std::vector<uint8_t> bytes = io::fetch(uri);
  bytes.resize(bytes.size() / 2);
  try {
    io::decode_ept_node(*ts.ept, bytes, uri);
    ADD_FAILURE() << "cut zstd data decoded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("ept-data"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// Early Entwine builds wrote "version": "0.0.0" over the 1.0 layout: read, with one warning that
// names the version; a 0.x whose layout differs (here its count under another name, as no 1.0
// dataset has it) is a clear error naming the version and what is not 1.0's.
TEST(Ept, Version000InThe10LayoutIsReadWithAWarning) {
  const fs::path dir = fresh_temp_dir("ept-000");
  const auto points = ept_points(3000);
  write_ept(dir, points, "binary", 300, 2);
  const std::string meta = (dir / "ept.json").string();
  std::string text = set_ept_version(dir, "0.0.0");
  ASSERT_NE(text.find("\"0.0.0\""), std::string::npos);
  io::TilesetOptions options;
  io::Tileset ts = io::load_tileset(meta, files(), options);
  ASSERT_TRUE(ts.ept);
  EXPECT_EQ(ts.ept->version, "0.0.0");
  ASSERT_EQ(ts.warnings.size(), 1u);
  EXPECT_NE(ts.warnings[0].find("'0.0.0'"), std::string::npos) << ts.warnings[0];
  EXPECT_NE(ts.warnings[0].find("ept.json"), std::string::npos) << ts.warnings[0];
  tiles3d::RenderLoadOptions o;
  o.streamer.traversal.max_sse = 0.01;
  auto r = tiles3d::load_tileset_for_render(meta, o);
  EXPECT_TRUE(r.errors.empty()) << r.errors.front().message;
  EXPECT_EQ(r.cloud.point_count, points.size());
  // Another layout under 0.0.0.
  const size_t count = text.find("\"points\"");
  ASSERT_NE(count, std::string::npos);
  text.replace(count, 8, "\"numPoints\"");
  std::ofstream(dir / "ept.json") << text;
  try {
    io::load_tileset(meta, files());
    ADD_FAILURE() << "a 0.0.0 dataset in another layout was read";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("ept.json"), std::string::npos) << what;
    EXPECT_NE(what.find("'0.0.0'"), std::string::npos) << what;
    EXPECT_NE(what.find("points is missing"), std::string::npos) << what;
  }
  // Any other version that is not 1.x stays refused.
  const size_t version = text.find("\"0.0.0\"");
  text.replace(version, 7, "\"2.0.0\"");
  std::ofstream(dir / "ept.json") << text;
  EXPECT_THROW(io::load_tileset(meta, files()), Error);
  fs::remove_all(dir);
}
