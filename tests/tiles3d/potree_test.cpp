// Potree 2.0 clouds (metadata.json, hierarchy.bin, octree.bin) written by the test's own writer
// (tests/common/potree_writer.hpp, from the format's description) read back as a streamed
// octree: every node is a tile, hierarchy chunks behind proxy nodes are read when reached, and
// every point comes back with every attribute type Potree defines; the streamer draws them all;
// broken files are clear errors naming the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <tuple>

#include "potree_brotli.hpp"
#include "potree_writer.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/potree.hpp"
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
  if (const char* out = std::getenv("STIPPLE_WRITE_POTREE_SEEDS"))
    for (const char* f : {"metadata.json", "hierarchy.bin"})
      fs::copy_file(dir / f, fs::path(out) / (std::string(f) + ".seed"),
                    fs::copy_options::overwrite_existing);
}

void reads_every_node_and_attribute(bool brotli_nodes) {
  const fs::path dir = fresh_temp_dir(brotli_nodes ? "potree2-brotli" : "potree2");
  const auto points = potree_points(20000);
  const PotreeWriteResult w =
      write_potree(dir, points, 500, 2, true, brotli_nodes ? potree_brotli : nullptr);
  ASSERT_GE(w.depth, 3);
  ASSERT_GT(w.chunks, 2u);
  if (!brotli_nodes) seed(dir);
  const std::string meta = (dir / "metadata.json").string();
  ASSERT_TRUE(io::is_potree_input(meta));
  io::TilesetOptions options;
  io::Tileset ts = io::load_tileset(meta, files(), options);
  ASSERT_TRUE(ts.potree);
  EXPECT_EQ(ts.potree->encoding, brotli_nodes ? "BROTLI" : "DEFAULT");
  EXPECT_GT(ts.pending, 0u);  // the first chunk's proxies, read later
  ASSERT_TRUE(io::expand_all(ts, files(), options, 1000000));
  EXPECT_TRUE(ts.errors.empty()) << ts.errors.front();
  EXPECT_EQ(ts.tiles.size(), w.nodes);
  EXPECT_EQ(ts.subtrees, w.chunks);  // every chunk read once
  using Row = std::tuple<int64_t, int64_t, int64_t, uint32_t, double, double, double, double,
                         double, double, double, double, double, double, double, double>;
  std::vector<Row> want, got;
  for (const auto& p : points)
    want.emplace_back(std::llround(p.x * 1000), std::llround(p.y * 1000), std::llround(p.z * 1000),
                      uint32_t(p.r / 256) | uint32_t(p.g / 256) << 8 | uint32_t(p.b / 256) << 16,
                      p.intensity, p.classification, p.return_number, p.number_of_returns,
                      p.gps_time, p.i8, p.i16, p.i32, double(p.i64), p.u32, double(p.u64), p.f32);
  uint64_t declared = 0;
  for (size_t t = 0; t < ts.tiles.size(); ++t) {
    const io::Tile& tile = ts.tiles[t];
    EXPECT_NEAR(tile.geometric_error, ts.potree->spacing / double(1u << tile.depth), 1e-12);
    for (const auto& uri : tile.contents) {
      declared += tile.content_points;
      io::PointContent c = io::decode_potree_node(*ts.potree, io::fetch(uri), uri);
      auto v = [&](const char* k, size_t i) { return c.attributes.at(k).values.at(i); };
      for (size_t i = 0; i < c.point_count; ++i) {
        const glm::dvec3 p = c.center + glm::dvec3(c.positions[i]);
        // Inside the node's cube: the node key and the octant bits are read right.
        EXPECT_LE(tile.box.distance(p), 1e-3);
        got.emplace_back(std::llround(p.x * 1000), std::llround(p.y * 1000),
                         std::llround(p.z * 1000), c.rgba[i] & 0xffffff, v("intensity", i),
                         v("classification", i), v("return_number", i), v("number_of_returns", i),
                         v("gps_time", i), v("extra int8", i), v("extra int16", i),
                         v("extra int32", i), v("extra int64", i), v("extra uint32", i),
                         v("extra uint64", i), v("extra float", i));
      }
    }
  }
  EXPECT_EQ(declared, points.size());
  std::sort(want.begin(), want.end());
  std::sort(got.begin(), got.end());
  // Positions through float offsets from the node centre: within a millimetre of the source.
  ASSERT_EQ(got.size(), want.size());
  size_t equal = 0;
  for (size_t i = 0; i < got.size(); ++i) equal += got[i] == want[i];
  EXPECT_EQ(equal, want.size());
  fs::remove_all(dir);
}

}  // namespace

TEST(Potree2, ReadsEveryNodeAndAttribute) {
  reads_every_node_and_attribute(false);
}

// BROTLI: each node one Brotli stream, attribute after attribute, position and rgb as Morton
// codes (positions above 16 bits an axis use the upper 64 bits of the code).
TEST(Potree2, ReadsBrotliNodes) {
  reads_every_node_and_attribute(true);
}

TEST(Potree2, StreamsEveryPointForRendering) {
  const fs::path dir = fresh_temp_dir("potree2-render");
  write_potree(dir, potree_points(12000), 400, 1);
  tiles3d::RenderLoadOptions o;
  o.streamer.traversal.max_sse = 0.01;  // refine everything
  auto r = tiles3d::load_tileset_for_render((dir / "metadata.json").string(), o);
  EXPECT_TRUE(r.errors.empty()) << r.errors.front().message;
  EXPECT_EQ(r.cloud.point_count, 12000u);
  EXPECT_TRUE(r.cloud.attributes.has_rgb);
  EXPECT_TRUE(r.cloud.attributes.has_intensity);
  EXPECT_TRUE(r.cloud.attributes.has_classification);
  fs::remove_all(dir);
}

TEST(Potree2, BrokenFilesAreClearErrors) {
  const fs::path dir = fresh_temp_dir("potree2-bad");
  write_potree(dir, potree_points(3000), 200, 1);
  const std::string meta = (dir / "metadata.json").string();
  const std::string original = [&] {
    std::ifstream in(dir / "metadata.json");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  auto expect_error = [&](const std::string& text, const char* needle) {
    std::ofstream(dir / "metadata.json") << text;
    try {
      io::load_tileset(meta, files());
      ADD_FAILURE() << "no error for " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("metadata.json"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  auto edit = [&](const char* from, const char* to) {
    std::string s = original;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, std::strlen(from), to);
  };
  expect_error(edit("\"DEFAULT\"", "\"LZ4\""), "unknown encoding 'LZ4'");
  expect_error(edit("\"version\": \"2.0\"", "\"version\": \"1.8\""), "version");
  expect_error(edit("\"firstChunkSize\": ", "\"firstChunkSize\": 1"), "firstChunkSize");
  expect_error(edit("\"int32\"", "\"float\""), "position");
  expect_error("{", "not a JSON object");
  std::ofstream(dir / "metadata.json") << original;
  // A cut hierarchy: the first chunk cannot be read whole.
  fs::resize_file(dir / "hierarchy.bin", 30);
  EXPECT_THROW(io::load_tileset(meta, files()), Error);
  // A node whose bytes are cut: its decode names its URI.
  write_potree(dir, potree_points(3000), 200, 1);
  io::Tileset ts = io::load_tileset(meta, files());
  io::expand_all(ts, files(), {}, 1000);
  const std::string uri = ts.tiles[0].contents.at(0);
  std::vector<uint8_t> bytes = io::fetch(uri);
  bytes.pop_back();
  EXPECT_THROW(io::decode_potree_node(*ts.potree, bytes, uri), Error);
  // A BROTLI node cut short, and one that decompresses to more than its count makes.
  write_potree(dir, potree_points(3000), 200, 1, true, potree_brotli);
  ts = io::load_tileset(meta, files());
  const std::string node = ts.tiles[0].contents.at(0);
  bytes = io::fetch(node);
  EXPECT_NO_THROW(io::decode_potree_node(*ts.potree, bytes, node));
  std::vector<uint8_t> cut(bytes.begin(), bytes.end() - 4);
  EXPECT_THROW(io::decode_potree_node(*ts.potree, cut, node), Error);
  std::string fewer = node;
  fewer.replace(fewer.find("&points=") + 8, fewer.find("&key") - fewer.find("&points=") - 8, "1");
  EXPECT_THROW(io::decode_potree_node(*ts.potree, bytes, fewer), Error);
  fs::remove_all(dir);
}
