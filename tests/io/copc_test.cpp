// COPC as a streamed source: the info VLR, hierarchy pages and their validation, byte-range
// reads, and node chunks decoded on their own (checked against reading the file whole as LAZ).
#include "stipple/io/copc.hpp"

#include <algorithm>
#include <cstring>
#include <fstream>

#include <gtest/gtest.h>

#include "copc_fixture.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace stipple;
using namespace stipple::io;

namespace {

std::vector<uint8_t> entry(int d, int x, int y, int z, uint64_t offset, int32_t size,
                           int32_t count) {
  std::vector<uint8_t> e(32);
  int32_t k[4] = {d, x, y, z};
  std::memcpy(e.data(), k, 16);
  std::memcpy(e.data() + 16, &offset, 8);
  std::memcpy(e.data() + 24, &size, 4);
  std::memcpy(e.data() + 28, &count, 4);
  return e;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return {};
}

}  // namespace

TEST(Copc, RangeUrisReadExactlyTheirBytes) {
  const fs::path dir = fs::temp_directory_path() / "stipple_copc_range";
  fs::create_directories(dir);
  const fs::path f = dir / "bytes.bin";
  std::vector<uint8_t> data(1000);
  for (size_t i = 0; i < data.size(); ++i) data[i] = uint8_t(i * 7);
  std::ofstream(f, std::ios::binary).write(reinterpret_cast<char*>(data.data()), 1000);
  const std::string uri = range_uri(f.string(), 100, 50);
  ByteRange r;
  ASSERT_TRUE(parse_range_uri(uri + "&points=3", &r));
  EXPECT_EQ(r.offset, 100u);
  EXPECT_EQ(r.size, 50u);
  EXPECT_EQ(fragment_field(uri + "&points=3", "points"), "3");
  FetchStats stats;
  auto got = fetch(uri, {}, &stats);
  ASSERT_EQ(got.size(), 50u);
  EXPECT_TRUE(std::equal(got.begin(), got.end(), data.begin() + 100));
  EXPECT_EQ(stats.total_size, 1000u);
  EXPECT_NE(error_of([&] { fetch(range_uri(f.string(), 990, 20)); }).find("past the end"),
            std::string::npos);
}

TEST(Copc, HierarchyEntriesAreValidated) {
  auto page = [](std::vector<std::vector<uint8_t>> entries) {
    std::vector<uint8_t> out;
    for (auto& e : entries) out.insert(out.end(), e.begin(), e.end());
    return out;
  };
  auto ok = parse_copc_page(
      page({entry(0, 0, 0, 0, 1000, 100, 10), entry(1, 1, 0, 1, 2000, 64, -1)}), "p", 10'000);
  ASSERT_EQ(ok.size(), 2u);
  EXPECT_EQ(ok[1].key, (CopcKey{1, 1, 0, 1}));
  EXPECT_EQ(ok[1].point_count, -1);
  auto msg = [&](std::vector<uint8_t> bytes) {
    return error_of([&] { parse_copc_page(bytes, "p", 10'000); });
  };
  EXPECT_NE(msg(std::vector<uint8_t>(33)).find("whole number"), std::string::npos);
  EXPECT_NE(msg(entry(2, 4, 0, 0, 1000, 10, 1)).find("outside its level"), std::string::npos);
  EXPECT_NE(msg(entry(31, 0, 0, 0, 1000, 10, 1)).find("depth 31"), std::string::npos);
  EXPECT_NE(msg(entry(1, 0, 0, 0, 9990, 100, 1)).find("past the end"), std::string::npos);
  EXPECT_NE(msg(entry(1, 0, 0, 0, 1000, 33, -1)).find("multiple of 32"), std::string::npos);
  EXPECT_NE(msg(entry(1, 0, 0, 0, 1000, -4, 1)).find("negative"), std::string::npos);
  EXPECT_NE(msg(entry(1, 0, 0, 0, 1000, 0, 5)).find("0 bytes"), std::string::npos);
  EXPECT_NE(msg(entry(1, 0, 0, 0, 10, 10, 5)).find("inside the header"), std::string::npos);

  // A page of 1,000 bad entries: 32 problems listed, the rest counted in one more line.
  std::vector<uint8_t> bad;
  for (int i = 0; i < 1000; ++i) {
    auto e = entry(31, 0, 0, 0, 1000, 10, 1);
    bad.insert(bad.end(), e.begin(), e.end());
  }
  std::vector<std::string> errors{"earlier"};
  EXPECT_TRUE(parse_copc_page(bad, "p", 10'000, &errors).empty());
  ASSERT_EQ(errors.size(), 1u + 32u + 1u);
  EXPECT_NE(errors[32].find("entry 31: depth 31"), std::string::npos) << errors[32];
  EXPECT_NE(errors.back().find("968 more entries"), std::string::npos) << errors.back();
}

TEST(Copc, PagesBecomeTilesAndBadEntriesBecomeErrors) {
  auto file = std::make_shared<CopcFile>();
  file->uri = "mem.copc.laz";
  file->file_size = 100'000;
  file->info.halfsize = 8;
  file->info.spacing = 1;
  std::vector<uint8_t> bytes;
  for (auto e : {entry(0, 0, 0, 0, 1000, 10, 5), entry(1, 1, 1, 1, 2000, 10, 5),
                 entry(2, 3, 3, 3, 3000, 10, 5), entry(2, 2, 2, 2, 4000, 64, -1),
                 entry(3, 0, 7, 0, 5000, 10, 5),   // parent 2-0-3-0 absent
                 entry(1, 1, 1, 1, 2000, 10, 5)})  // listed twice
    bytes.insert(bytes.end(), e.begin(), e.end());
  PendingChildren p;
  p.kind = PendingChildren::Kind::CopcPage;
  p.uris = {range_uri(file->uri, 50'000, bytes.size())};
  p.copc = file;
  Expansion e = read_copc_page(7, p, 1, [&](const std::string&) { return bytes; }, {});
  ASSERT_EQ(e.contents.size(), 1u);  // the page's own node
  EXPECT_EQ(fragment_field(e.contents[0], "points"), "5");
  ASSERT_EQ(e.tiles.size(), 3u);  // 1-1-1-1, 2-2-2-2 (a child page), 2-3-3-3
  EXPECT_EQ(e.tiles[0].parent, -1);
  EXPECT_DOUBLE_EQ(e.tiles[0].geometric_error, 0.5);
  EXPECT_NEAR(e.tiles[0].box.center.x, 4.0, 1e-12);  // cube [0, 8] of the root [-8, 8]
  const Tile& paged = e.tiles[1];
  ASSERT_TRUE(paged.pending);
  EXPECT_EQ(paged.pending->kind, PendingChildren::Kind::CopcPage);
  EXPECT_TRUE(paged.contents.empty());
  EXPECT_EQ(paged.parent, 0);
  EXPECT_EQ(e.tiles[2].parent, 0);
  ASSERT_EQ(e.errors.size(), 2u);
  std::string all = e.errors[0].second + e.errors[1].second;
  EXPECT_NE(all.find("3-0-7-0 has no parent"), std::string::npos) << all;
  EXPECT_NE(all.find("listed twice"), std::string::npos) << all;
  // A page that points at itself: the cycle is named, nothing is built from it.
  std::vector<uint8_t> self = entry(0, 0, 0, 0, 50'000, 32, -1);
  Expansion c = read_copc_page(0, p, 1, [&](const std::string&) { return self; }, {});
  ASSERT_EQ(c.errors.size(), 1u);
  EXPECT_NE(c.errors[0].second.find("cycle"), std::string::npos);
}

TEST(Copc, NodesDecodeToTheFilesPoints) {
  STIPPLE_REQUIRE_DATA(path, "laz/lone-star.copc.laz");
  ASSERT_TRUE(is_copc_input(path.string()));
  Tileset ts = load_tileset(path.string());
  ASSERT_TRUE(ts.copc);
  EXPECT_EQ(ts.copc->header.point_count, 518862u);
  EXPECT_NEAR(ts.copc->info.spacing, 0.318436, 1e-5);
  Fetcher fetcher = [](const std::string& u) { return fetch(u); };
  ASSERT_TRUE(expand_all(ts, fetcher, {}, 1000));
  EXPECT_EQ(ts.tiles.size(), 15u);
  // Points as the file's integer grid coordinates (exact: the float offsets from a node's
  // centre are far finer than the 0.25 mm scale) with their intensity.
  const LasHeader& h = ts.copc->header;
  auto grid = [&](const glm::dvec3& p, double intensity) {
    return std::array<int64_t, 4>{std::llround((p.x - h.offset.x) / h.scale.x),
                                  std::llround((p.y - h.offset.y) / h.scale.y),
                                  std::llround((p.z - h.offset.z) / h.scale.z), int64_t(intensity)};
  };
  std::vector<std::array<int64_t, 4>> streamed;
  for (const Tile& t : ts.tiles)
    for (const auto& c : t.contents) {
      auto bytes = fetcher(c);
      PointContent pc = decode_copc_node(*ts.copc, bytes, c);
      auto it = pc.attributes.find("intensity");
      ASSERT_NE(it, pc.attributes.end());
      for (size_t i = 0; i < pc.point_count; ++i) {
        glm::dvec3 p = pc.center + glm::dvec3(pc.positions[i]);
        for (int k = 0; k < 3; ++k)  // inside its node's cube
          ASSERT_LE(std::abs(p[k] - t.box.center[k]), t.box.half_axes[k][k] + 1e-3);
        streamed.push_back(grid(p, it->second.values[i]));
      }
    }
  LasReader reader(path);
  PointBatch batch;
  while (reader.read(batch, 1 << 16) > 0) {
  }
  std::vector<std::array<int64_t, 4>> whole;
  for (size_t i = 0; i < batch.size(); ++i)
    whole.push_back(grid(batch.positions[i], batch.intensity[i]));
  std::sort(streamed.begin(), streamed.end());
  std::sort(whole.begin(), whole.end());
  EXPECT_EQ(streamed.size(), 518862u);
  EXPECT_TRUE(streamed == whole) << "the nodes' points differ from the file's";
}

TEST(Copc, DamagedHierarchiesGiveErrorsPerNode) {
  STIPPLE_REQUIRE_COPC_WRITER();
  const fs::path dir = fs::temp_directory_path() / "stipple_copc_damaged";
  fs::create_directories(dir);
  Fetcher fetcher = [](const std::string& u) { return fetch(u); };
  for (const std::string kind : {"offset", "cycle", "orphan", "pagesize", "depth"}) {
    const fs::path f = dir / (kind + ".copc.laz");
    ASSERT_TRUE(test::write_test_copc(f, 60'000, "--depth 6 --capacity 300 --corrupt " + kind))
        << kind;
    Tileset ts = load_tileset(f.string());
    expand_all(ts, fetcher, {}, 100'000);
    ASSERT_FALSE(ts.errors.empty()) << kind << ": no error reported";
    std::string all;
    for (auto& e : ts.errors) all += e + "\n";
    EXPECT_NE(all.find(f.string()), std::string::npos) << kind << ": " << all;
    EXPECT_GT(ts.tiles.size(), 10u) << kind << ": the rest of the tree is read";
  }
}
