// Pointlets and the pointlet cache (seed 002, III-A): every input point exactly once, k as eq. 1,
// boxes that hold their points, shuffled pointlets, LAS and LAZ alike, one run or many alike,
// reuse while the sources are unchanged, rebuilds otherwise, and clear errors for damage.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "scene_las.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/math/geo.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/pointcloud/pointlet_lod.hpp"
#include "stipple/pointcloud/pointlets.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
  fs::path d =
      fs::temp_directory_path() / ("stipple-pointlets-" + name + "-" + std::to_string(getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// (lattice position, rgba, attributes) of every point, sorted: the multiset of a cloud.
using Key = std::tuple<int64_t, int64_t, int64_t, uint32_t, uint32_t>;

std::vector<Key> cache_points(const pc::PointletCache& cache) {
  std::vector<Key> out;
  const auto& s = cache.info().scale;
  for (uint32_t i = 0; i < cache.pointlets().size(); ++i) {
    const auto& e = cache.pointlets()[i];
    for (const auto& r : cache.read_verified(i)) {
      const glm::dvec3 p = cache.position(e, r);
      out.emplace_back(std::llround(p.x / s.x), std::llround(p.y / s.y), std::llround(p.z / s.z),
                       r.rgba, r.attributes);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Key> source_points(const fs::path& path, const glm::dvec3& s) {
  io::LasReader reader(path);
  io::PointBatch b;
  std::vector<Key> out;
  while (true) {
    b.clear();
    if (reader.read(b, 50000) == 0) break;
    for (size_t i = 0; i < b.size(); ++i)
      out.emplace_back(std::llround(b.positions[i].x / s.x), std::llround(b.positions[i].y / s.y),
                       std::llround(b.positions[i].z / s.z),
                       pc::batch_rgba(b, i, reader.header().rgb_bits), pc::batch_attributes(b, i));
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<uint8_t> bytes_of(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST(Pointlets, SizeFollowsEquationOne) {
  // k = 2^floor(log2(n / m))
  EXPECT_EQ(pc::pointlet_size(110000, 1000), 64u);                 // n/m = 110 -> 2^6
  EXPECT_EQ(pc::pointlet_size(1'000'000'000, 100'000), 8192u);     // 10000 -> 2^13
  EXPECT_EQ(pc::pointlet_size(18'000'000'000, 100'000), 131072u);  // 180000 -> 2^17
  EXPECT_EQ(pc::pointlet_size(1 << 20, 1 << 10), 1024u);           // exact powers
  EXPECT_EQ(pc::pointlet_size(500, 1000), 1u);                     // fewer points than pointlets
}

TEST(Pointlets, HilbertFromMortonEqualsSkilling) {
  std::mt19937 rng(5);
  for (int i = 0; i < 200000; ++i) {
    const uint32_t x = rng() & 1023, y = rng() & 1023, z = rng() & 1023;
    const uint32_t morton = uint32_t(pc::morton_key(x, y, z));
    ASSERT_EQ(pc::hilbert_from_morton(morton),
              uint32_t(pc::hilbert_key(x << 11, y << 11, z << 11) >> 33))
        << x << "," << y << "," << z;
  }
  // A Hilbert curve: consecutive indices are neighbouring cells (an 8^3 corner exhaustively).
  std::vector<std::array<int, 3>> cell(1 << 9);
  for (int x = 0; x < 8; ++x)
    for (int y = 0; y < 8; ++y)
      for (int z = 0; z < 8; ++z) {
        const uint32_t h =
            pc::hilbert_from_morton(uint32_t(pc::morton_key(x << 7, y << 7, z << 7)));
        cell[h >> 21] = {x, y, z};
      }
  for (size_t i = 1; i < cell.size(); ++i) {
    int d = 0;
    for (int a = 0; a < 3; ++a) d += std::abs(cell[i][a] - cell[i - 1][a]);
    ASSERT_EQ(d, 1) << "cells " << i - 1 << " and " << i;
  }
}

TEST(Pointlets, EveryPointOnceInBoxesOfKShuffled) {
  fs::path dir = fresh_dir("once");
  fs::path las = test::write_scene_las(dir / "scene.las", 60000);
  pc::PointletBuildOptions o;
  o.pointlets = 500;  // k = 2^floor(log2(120)) = 64
  o.progress = false;
  auto stats = pc::build_pointlet_cache({las}, dir / "scene.pointlets", o);
  EXPECT_EQ(stats.runs, 1u);
  pc::PointletCache cache = pc::PointletCache::open(dir / "scene.pointlets");
  const auto& info = cache.info();
  EXPECT_EQ(info.point_count, 60000u);
  EXPECT_EQ(info.pointlet_points, 64u);
  EXPECT_EQ(info.pointlet_count, (60000u + 63) / 64);
  EXPECT_TRUE(info.attributes.has_rgb);
  // Exactly the source's points (positions on the LAS lattice, colours, attributes).
  EXPECT_EQ(cache_points(cache), source_points(las, info.scale));
  // Boxes contain their points; a pointlet's first half spans most of its box (shuffled, not
  // in curve order, where the first half would cover about half).
  double half_share = 0;
  for (uint32_t i = 0; i < cache.pointlets().size(); ++i) {
    const auto& e = cache.pointlets()[i];
    auto records = cache.read_verified(i);
    Aabb half;
    for (size_t r = 0; r < records.size(); ++r) {
      const glm::dvec3 p = cache.position(e, records[r]);
      for (int a = 0; a < 3; ++a) {
        ASSERT_GE(p[a], e.min[a]) << "pointlet " << i;
        ASSERT_LE(p[a], e.max[a]) << "pointlet " << i;
      }
      if (r < records.size() / 2) half.extend(p);
    }
    const double full = (e.max[0] - e.min[0]) * (e.max[1] - e.min[1]);
    if (full > 0 && !half.empty()) half_share += half.size().x * half.size().y / full;
  }
  half_share /= double(cache.pointlets().size());
  EXPECT_GT(half_share, 0.7) << "the first half of a pointlet covers " << half_share
                             << " of its box";
  // Hilbert pointlets are compact: mean extent well under the scene's size.
  auto m = pc::pointlet_metrics(cache.pointlets());
  EXPECT_LT(m.mean_extent,
            0.1 * std::max(info.source_bounds.size().x, info.source_bounds.size().y));
  fs::remove_all(dir);
}

TEST(Pointlets, LasAndLazAndManyRunsGiveTheSamePointlets) {
  fs::path dir = fresh_dir("same");
  fs::path las = test::write_scene_las(dir / "scene.las", 150000);
  fs::path laz = test::write_scene_las(dir / "scene.laz", 150000, true);
  pc::PointletBuildOptions o;
  o.pointlets = 1000;
  o.progress = false;
  pc::build_pointlet_cache({las}, dir / "las.pointlets", o);
  pc::build_pointlet_cache({laz}, dir / "laz.pointlets", o);
  o.memory_budget = 65536 * 24;  // runs of 65,536 points: three runs on disk, merged
  auto stats = pc::build_pointlet_cache({las}, dir / "runs.pointlets", o);
  EXPECT_EQ(stats.runs, 3u);
  EXPECT_LE(stats.peak_run_bytes, o.memory_budget);
  // The runs went to disk compressed (byte planes through zstd), and came back whole (below).
  EXPECT_EQ(stats.run_bytes, 150000u * 24);
  EXPECT_GT(stats.run_disk_bytes, 0u);
  EXPECT_LT(stats.run_disk_bytes, stats.run_bytes / 2);
  auto a = bytes_of(dir / "las.pointlets"), b = bytes_of(dir / "laz.pointlets"),
       c = bytes_of(dir / "runs.pointlets");
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.size(), c.size());
  // Points and table are identical; the headers differ only in the sources named.
  const size_t body = pc::kPointletHeaderBytes;
  EXPECT_TRUE(std::equal(a.begin() + body, a.end(), b.begin() + body));
  EXPECT_TRUE(std::equal(a.begin() + body, a.end(), c.begin() + body));
  // No run file is left behind.
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().string().find(".run-"), std::string::npos) << e.path();
  fs::remove_all(dir);
}

// FNV-1a of a cache's body (the points and the table, not the header that names the sources).
uint64_t body_digest(const fs::path& cache) {
  const auto bytes = bytes_of(cache);
  uint64_t h = 1469598103934665603ull;
  for (size_t i = pc::kPointletHeaderBytes; i < bytes.size(); ++i)
    h = (h ^ bytes[i]) * 1099511628211ull;
  return h;
}

// The cache's content is fixed: a faster builder must give the very same points and pointlets
// (order, shuffles, boxes and CRCs) as the first one did, for LAS and LAZ, in one run or in
// several runs on disk, and when a single curve cell holds more points than one run (the
// merge's fallback). The digests were taken from the comparison-sort builder.
TEST(Pointlets, ContentIsThatOfTheFirstBuilder) {
  fs::path dir = fresh_dir("golden");
  fs::path las = test::write_scene_las(dir / "scene.las", 150000);
  fs::path laz = test::write_scene_las(dir / "scene.laz", 150000, true);
  pc::PointletBuildOptions o;
  o.pointlets = 1000;
  o.progress = false;
  o.threads = 2;
  pc::build_pointlet_cache({las}, dir / "las.pointlets", o);
  pc::build_pointlet_cache({laz}, dir / "laz.pointlets", o);
  o.memory_budget = 20000 * 24;  // runs of 65,536 points (the least): three on disk
  const auto runs = pc::build_pointlet_cache({las}, dir / "runs.pointlets", o);
  EXPECT_EQ(runs.runs, 3u);
  o.threads = 3;
  pc::build_pointlet_cache({las}, dir / "runs3.pointlets", o);
  // The cache's points written by pwrite() (file systems without fallocate or mapping), not
  // through mappings: the same bytes.
  ::setenv("STIPPLE_CACHE_WRITE", "pwrite", 1);
  pc::build_pointlet_cache({las}, dir / "pwrite.pointlets", o);
  ::unsetenv("STIPPLE_CACHE_WRITE");
  pc::PointletCache cache = pc::PointletCache::open(dir / "las.pointlets");
  EXPECT_EQ(cache.info().point_count, 150000u);
  EXPECT_EQ(cache.info().pointlet_points, 128u);
  EXPECT_EQ(cache.info().pointlet_count, 1172u);
  uint64_t crcs = 0;
  for (const auto& e : cache.pointlets()) crcs = crcs * 31 + e.crc;
  EXPECT_EQ(crcs, 0xae9ed5d545748687ull);
  const uint64_t expected = 0x8e45ae54a0860ab9ull;
  EXPECT_EQ(body_digest(dir / "las.pointlets"), expected);
  EXPECT_EQ(body_digest(dir / "laz.pointlets"), expected);
  EXPECT_EQ(body_digest(dir / "runs.pointlets"), expected);
  EXPECT_EQ(body_digest(dir / "runs3.pointlets"), expected);
  EXPECT_EQ(body_digest(dir / "pwrite.pointlets"), expected);

  // 100,000 points at one place among 60,000 spread ones: one curve cell holds more points than
  // a run, so the merge cannot cut it into windows.
  io::SceneParams scene;
  fs::path dense = dir / "dense.las";
  {
    io::LasWriteOptions w;
    w.version_minor = 4;
    w.point_format = 7;
    w.scale = {0.001, 0.001, 0.001};
    w.offset = {scene.origin.x, scene.origin.y, 0.0};
    io::LasWriter writer(dense, w);
    io::PointBatch b;
    io::generate_scene(scene, 0, 60000, b);
    writer.write(b);
    for (uint64_t first = 0; first < 100000; first += 10000) {
      b.clear();
      io::generate_scene(scene, 60000 + first, 10000, b);
      for (auto& p : b.positions) p = scene.origin + glm::dvec3(5.0, 5.0, 1.0);
      writer.write(b);
    }
    writer.close();
  }
  o.threads = 2;
  o.memory_budget = uint64_t(1) << 30;
  pc::build_pointlet_cache({dense}, dir / "dense1.pointlets", o);
  o.memory_budget = 20000 * 24;
  EXPECT_GT(pc::build_pointlet_cache({dense}, dir / "dense3.pointlets", o).runs, 1u);
  EXPECT_EQ(body_digest(dir / "dense1.pointlets"), 0x615d4265c5b2866eull);
  EXPECT_EQ(body_digest(dir / "dense3.pointlets"), 0x615d4265c5b2866eull);
  fs::remove_all(dir);
}

// A survey's tiles are one cache, with the points and pointlets of the merged file (the tiles
// one after another); a header naming more sources than 4096 bytes hold grows by pages.
TEST(Pointlets, TilesAreOneCacheEqualToTheMergedFile) {
  fs::path dir = fresh_dir("tiles");
  fs::path las = test::write_scene_las(dir / "scene.las", 60000);
  pc::PointletBuildOptions o;
  o.pointlets = 200;
  o.progress = false;
  o.threads = 2;
  auto body = [](const fs::path& path) {
    const auto cache = pc::PointletCache::open(path);
    const auto bytes = bytes_of(path);
    return std::vector<uint8_t>(bytes.begin() + ptrdiff_t(cache.info().points_offset), bytes.end());
  };
  {
    const auto tiles = test::split_las_into_tiles(las, dir / "four", 2, 2, dir / "merged4.las");
    ASSERT_EQ(tiles.size(), 4u);
    pc::build_pointlet_cache(tiles, dir / "tiles4.pointlets", o);
    pc::build_pointlet_cache({dir / "merged4.las"}, dir / "merged4.pointlets", o);
    const auto cache = pc::PointletCache::open(dir / "tiles4.pointlets");
    EXPECT_EQ(cache.info().point_count, 60000u);
    EXPECT_EQ(cache.info().sources.size(), 4u);
    EXPECT_EQ(cache.info().points_offset, pc::kPointletHeaderBytes);
    EXPECT_EQ(cache_points(cache), source_points(las, cache.info().scale));
    EXPECT_TRUE(body(dir / "tiles4.pointlets") == body(dir / "merged4.pointlets"));
  }
  {
    // 10 x 10 tiles: more than the 64 sources a cache once held.
    const auto tiles = test::split_las_into_tiles(las, dir / "many", 10, 10, dir / "merged.las");
    ASSERT_GT(tiles.size(), 64u);
    pc::build_pointlet_cache(tiles, dir / "tiles.pointlets", o);
    pc::build_pointlet_cache({dir / "merged.las"}, dir / "merged.pointlets", o);
    const auto cache = pc::PointletCache::open(dir / "tiles.pointlets");
    EXPECT_EQ(cache.info().sources.size(), tiles.size());
    EXPECT_EQ(cache.info().sources.back().path, fs::absolute(tiles.back()).string());
    EXPECT_GT(cache.info().points_offset, pc::kPointletHeaderBytes);
    EXPECT_EQ(cache.info().points_offset % pc::kPointletHeaderBytes, 0u);
    EXPECT_TRUE(cache.matches(tiles, o));
    EXPECT_TRUE(body(dir / "tiles.pointlets") == body(dir / "merged.pointlets"));
  }
  fs::remove_all(dir);
}

TEST(Pointlets, ReusedWhileUnchangedRebuiltWhenChangedOrDamaged) {
  fs::path dir = fresh_dir("reuse");
  fs::path las = test::write_scene_las(dir / "scene.las", 20000);
  fs::path caches = dir / "caches";
  pc::PointletBuildOptions o;
  o.pointlets = 100;
  o.progress = false;
  bool built = false;
  auto first = pc::open_pointlet_cache({las}, caches, o, &built);
  EXPECT_TRUE(built);
  const fs::path path = pc::pointlet_cache_path({las}, caches, o);
  EXPECT_EQ(path.parent_path(), caches);
  pc::open_pointlet_cache({las}, caches, o, &built);
  EXPECT_FALSE(built) << "an unchanged source must reuse the cache";
  // Another m is another cache.
  pc::PointletBuildOptions other = o;
  other.pointlets = 50;
  EXPECT_NE(pc::pointlet_cache_path({las}, caches, other), path);
  // A changed source (new mtime) rebuilds.
  fs::last_write_time(las, fs::last_write_time(las) + std::chrono::seconds(5));
  pc::open_pointlet_cache({las}, caches, o, &built);
  EXPECT_TRUE(built);
  // Truncated, or a flipped byte in the points' table: rebuilt, not used.
  fs::resize_file(path, fs::file_size(path) - 10);
  EXPECT_THROW(pc::PointletCache::open(path), Error);
  pc::open_pointlet_cache({las}, caches, o, &built);
  EXPECT_TRUE(built);
  {
    std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
    f.seekp(std::streamoff(fs::file_size(path) - 30));
    f.put('\x7f');
  }
  pc::open_pointlet_cache({las}, caches, o, &built);
  EXPECT_TRUE(built);
  // A build killed mid-way leaves only its temporary, which is never taken for the cache.
  std::ofstream(path.string() + ".partial-99999-0") << "half a cache";
  pc::open_pointlet_cache({las}, caches, o, &built);
  EXPECT_FALSE(built);
  fs::remove_all(dir);
}

TEST(Pointlets, DamageGivesClearErrors) {
  fs::path dir = fresh_dir("damage");
  fs::path las = test::write_scene_las(dir / "scene.las", 5000);
  pc::PointletBuildOptions o;
  o.pointlets = 10;
  o.progress = false;
  pc::build_pointlet_cache({las}, dir / "c.pointlets", o);
  const auto good = bytes_of(dir / "c.pointlets");
  auto expect_error = [&](std::vector<uint8_t> bytes, const std::string& phrase) {
    try {
      pc::PointletCache::from_memory(std::move(bytes), "damaged.pointlets");
      ADD_FAILURE() << "expected an error with '" << phrase << "'";
    } catch (const Error& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("damaged.pointlets"), std::string::npos) << m;
      EXPECT_NE(m.find(phrase), std::string::npos) << m;
    }
  };
  expect_error({good.begin(), good.begin() + 100}, "shorter than its header");
  auto bad = good;
  bad[0] = 'X';
  expect_error(bad, "bad magic");
  bad = good;
  bad[8] = 2;  // version
  expect_error(bad, "version 2");
  bad = good;
  bad[20] ^= 1;  // point count: the header checksum catches it
  expect_error(bad, "checksum");
  bad = good;
  bad[bad.size() - 5] ^= 0x40;  // the table
  expect_error(bad, "table's checksum");
  bad = good;
  bad.resize(bad.size() + 64);
  expect_error(bad, "its header says");
  bad = good;
  bad[pc::kPointletHeaderBytes + 3] ^= 1;  // a point: found when that pointlet is verified
  auto cache = pc::PointletCache::from_memory(bad, "damaged.pointlets");
  EXPECT_THROW(cache.read_verified(0), Error);
  std::vector<pc::PointletRecord> out;
  EXPECT_THROW(cache.read(uint32_t(cache.pointlets().size()), 0, 1, out), Error);
  EXPECT_THROW(cache.read(0, 0, uint32_t(cache.pointlets()[0].count + 1), out), Error);
  fs::remove_all(dir);
}

TEST(Pointlets, AFailedBuildLeavesNothing) {
  fs::path dir = fresh_dir("failed");
  fs::path las = test::write_scene_las(dir / "scene.las", 30000);
  // The file claims more points than it holds: the build stops with an error naming it.
  fs::resize_file(las, fs::file_size(las) - 1000 * 36);
  pc::PointletBuildOptions o;
  o.pointlets = 100;
  o.progress = false;
  o.memory_budget = 65536 * 24;
  EXPECT_THROW(pc::build_pointlet_cache({las}, dir / "c.pointlets", o), Error);
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename(), "scene.las") << "left behind: " << e.path();
  fs::remove_all(dir);
}

// Lon/lat input: the cache holds metres of a local east-north-up frame at the centre of the
// bounds (as the in-memory path draws them), each point within one step of its exact image.
TEST(Pointlets, GeographicInputGoesToALocalEnuFrame) {
  STIPPLE_REQUIRE_DATA(path, "las/epsg_4326.las");
  fs::path dir = fresh_dir("geographic");
  pc::PointletBuildOptions o;
  o.pointlets = 100;
  o.progress = false;
  pc::build_pointlet_cache({path}, dir / "geo.pointlets", o);
  pc::PointletCache cache = pc::PointletCache::open(dir / "geo.pointlets");
  const auto& info = cache.info();
  const io::LasHeader header = io::read_las_header(path);
  ASSERT_TRUE(info.geographic);
  EXPECT_NEAR(info.enu_origin.x, (header.min.x + header.max.x) / 2, 1e-9);
  EXPECT_NEAR(info.enu_origin.y, (header.min.y + header.max.y) / 2, 1e-9);
  EXPECT_EQ(info.point_count, header.point_count);
  // Metres: the file spans about 2.2 km east-west and 1.2 km north-south.
  EXPECT_GT(info.source_bounds.size().x, 2000.0);
  EXPECT_LT(info.source_bounds.size().x, 2600.0);
  EXPECT_GT(info.source_bounds.size().y, 1000.0);
  EXPECT_LT(info.source_bounds.size().y, 1400.0);
  EXPECT_LT(info.scale.x, 0.02);  // 1e-7 degrees are about 1 cm
  std::vector<glm::dvec3> cached;
  for (uint32_t i = 0; i < cache.pointlets().size(); ++i)
    for (const auto& r : cache.read_verified(i))
      cached.push_back(cache.position(cache.pointlets()[i], r));
  ASSERT_EQ(cached.size(), header.point_count);
  const geo::LocalEnu enu(info.enu_origin);
  io::LasReader reader(path);
  io::PointBatch b;
  reader.read(b, header.point_count);
  ASSERT_EQ(b.size(), header.point_count);
  const double tolerance = glm::length(info.scale);
  for (size_t i = 0; i < b.size(); ++i) {
    const glm::dvec3 exact = enu.from_geodetic(b.positions[i]);
    double best = 1e30;
    for (const glm::dvec3& c : cached) best = std::min(best, glm::length(c - exact));
    ASSERT_LE(best, tolerance) << "point " << i;
  }
  fs::remove_all(dir);
}

TEST(Pointlets, RefusesMixedGeographicAndProjectedInputs) {
  STIPPLE_REQUIRE_DATA(geographic, "las/epsg_4326.las");
  STIPPLE_REQUIRE_DATA(projected, "las/autzen_trim.las");
  fs::path dir = fresh_dir("mixed");
  pc::PointletBuildOptions o;
  o.progress = false;
  try {
    pc::build_pointlet_cache({geographic, projected}, dir / "mixed.pointlets", o);
    ADD_FAILURE() << "mixed inputs were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("one cache holds one kind"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / "mixed.pointlets"));
  fs::remove_all(dir);
}

// Pointlets of one point (k = 1: fewer than twice --pointlets points) have empty boxes; eq. 2's
// weight was then 0 / 0 for each, no pointlet got a point and `render --virtual` of a
// 110,000-point file wrote an empty image. Their LoD boxes now have a floor: every visible
// single point is drawn while the bucket holds them all, and a pointlet with a real extent
// keeps its box (and so the seed's weight) exactly.
TEST(Pointlets, SinglePointPointletsAreDrawn) {
  std::vector<pc::PointletEntry> table;
  for (int i = 0; i < 400; ++i) {
    pc::PointletEntry e;
    e.min[0] = e.max[0] = (i % 20) * 5.0;
    e.min[1] = e.max[1] = (i / 20) * 5.0;
    e.min[2] = e.max[2] = 1.0;
    e.first = uint64_t(i);
    e.count = 1;
    table.push_back(e);
  }
  pc::PointletEntry wide;  // a real pointlet: 10 m x 10 m x 2 m
  wide.min[0] = 20.0;
  wide.min[1] = 20.0;
  wide.min[2] = 0.0;
  wide.max[0] = 30.0;
  wide.max[1] = 30.0;
  wide.max[2] = 2.0;
  wide.first = 400;
  wide.count = 64;
  table.push_back(wide);

  const glm::dvec3 origin(50.0, 1.0, -50.0);  // Y up: the boxes' centre
  const auto boxes = pc::pointlet_boxes(table, origin);
  ASSERT_EQ(boxes.size(), table.size());
  for (size_t i = 0; i + 1 < boxes.size(); ++i) ASSERT_GT(boxes[i].lo[3], 0.0f) << i;
  EXPECT_NEAR(boxes.back().lo[3], 0.5 * std::sqrt(10.0 * 10.0 + 10.0 * 10.0 + 2.0 * 2.0), 1e-4);

  Aabb box;
  box.extend(z_up_to_y_up(glm::dvec3(0, 0, 0)));
  box.extend(z_up_to_y_up(glm::dvec3(100, 100, 2)));
  const Camera camera = frame_box(box, 16.0 / 9.0);
  std::vector<uint32_t> sizes;
  for (const auto& e : table) sizes.push_back(e.count);
  const auto counts =
      pc::pointlet_lod_cpu(boxes, sizes, sizes, origin, camera, 640, 360, 1'000'000);
  for (size_t i = 0; i + 1 < counts.size(); ++i) EXPECT_EQ(counts[i], 1u) << "pointlet " << i;
  EXPECT_EQ(counts.back(), 64u);

  // A cloud of coincident points has no extent at all: still drawn.
  std::vector<pc::PointletEntry> same(3, table[0]);
  for (size_t i = 0; i < same.size(); ++i) same[i].first = i;
  const auto same_boxes = pc::pointlet_boxes(same, origin);
  const std::vector<uint32_t> ones(3, 1);
  EXPECT_EQ(pc::pointlet_lod_cpu(same_boxes, ones, ones, origin, camera, 640, 360, 1'000'000),
            ones);
}

// A build followed by another thread (the viewer's background build): the report ends at phase
// 3 with every point counted, the cache is byte for byte the unreported one (its single run is
// written in pieces then) and also with runs on disk, pointlet_cache_current tells a current
// cache from a missing or outdated one, and a cancelled build throws and leaves no cache.
TEST(Pointlets, ReportedBuildCountsItsPointsAndCanBeCancelled) {
  fs::path dir = fresh_dir("report");
  fs::path las = test::write_scene_las(dir / "scene.las", 150000);
  pc::PointletBuildOptions o;
  o.pointlets = 1000;
  o.progress = false;
  EXPECT_FALSE(pc::pointlet_cache_current({las}, dir / "plain", o));
  fs::create_directories(dir / "plain");
  pc::open_pointlet_cache({las}, dir / "plain", o);
  EXPECT_TRUE(pc::pointlet_cache_current({las}, dir / "plain", o));
  const fs::path plain = pc::pointlet_cache_path({las}, dir / "plain", o);

  for (const uint64_t budget : {uint64_t(1) << 30, uint64_t(65536) * 24}) {  // one run, three
    pc::PointletBuildOptions r = o;
    r.memory_budget = budget;
    r.report = std::make_shared<pc::PointletBuildProgress>();
    EXPECT_EQ(r.report->fraction(), 0.0);
    const fs::path reported = dir / "reported.pointlets";
    pc::build_pointlet_cache({las}, reported, r);
    EXPECT_EQ(r.report->phase.load(), 3u);
    EXPECT_EQ(r.report->done.load(), 150000u);
    EXPECT_EQ(r.report->total.load(), 150000u);
    EXPECT_EQ(r.report->fraction(), 1.0);
    const auto a = bytes_of(plain), b = bytes_of(reported);
    ASSERT_EQ(a.size(), b.size()) << budget;
    EXPECT_TRUE(std::equal(a.begin() + pc::kPointletHeaderBytes, a.end(),
                           b.begin() + pc::kPointletHeaderBytes))
        << budget;
    fs::remove(reported);

    r.report = std::make_shared<pc::PointletBuildProgress>();
    r.report->cancel = true;
    EXPECT_THROW(pc::build_pointlet_cache({las}, reported, r), Error) << budget;
    EXPECT_FALSE(fs::exists(reported));
  }
  // Newer sources: the cache is no longer current.
  fs::last_write_time(las, fs::last_write_time(las) + std::chrono::seconds(5));
  EXPECT_FALSE(pc::pointlet_cache_current({las}, dir / "plain", o));
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename() != "scene.las" && e.path().filename() != "plain")
      left.push_back(e.path().string());
  EXPECT_TRUE(left.empty()) << left.front();
  fs::remove_all(dir);
}
