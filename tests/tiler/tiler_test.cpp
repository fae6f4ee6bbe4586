// stipple tile: decodes the tiler's own glb/pnts output (a small reader below) and checks point
// conservation, positions against PROJ, bounds, spacing per level, out-of-core chunking,
// atomic output, peak memory of a child `stipple tile`, and the Khronos glTF validator.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <unordered_map>

#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/glb_points.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/pnts.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/tiler/geo_frame.hpp"
#include "stipple/tiler/tiler.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace stipple;

namespace {

fs::path data_dir() {
  if (const char* env = std::getenv("STIPPLE_DATA_DIR")) return env;
  return fs::path(STIPPLE_SOURCE_DIR "/../shared/data");
}

fs::path temp_dir() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("stipple_tiler_test_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

std::vector<uint8_t> slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

struct Decoded {
  glm::dvec3 ecef;
  glm::dvec3 local;
  uint16_t intensity;
  uint8_t classification;
};

template <typename T>
T at(const std::vector<uint8_t>& b, size_t off) {
  T v;
  std::memcpy(&v, b.data() + off, sizeof(T));
  return v;
}

// Local-frame positions of a glb tile (node TRS, then glTF Y-up -> 3D Tiles Z-up).
std::vector<Decoded> decode_glb(const std::vector<uint8_t>& b) {
  uint32_t jlen = at<uint32_t>(b, 12);
  json g = json::parse(std::string(b.begin() + 20, b.begin() + 20 + jlen));
  const size_t bin = 20 + jlen + 8;
  const json& node = g["nodes"][0];
  glm::dvec3 t(0), s(1);
  if (node.contains("translation"))
    t = {node["translation"][0], node["translation"][1], node["translation"][2]};
  if (node.contains("scale")) s = {node["scale"][0], node["scale"][1], node["scale"][2]};
  const json& attrs = g["meshes"][0]["primitives"][0]["attributes"];
  EXPECT_EQ(g["meshes"][0]["primitives"][0]["mode"], 0);
  auto view_of = [&](const char* name, size_t& stride, int& type, size_t& count) {
    const json& a = g["accessors"][int(attrs[name])];
    const json& v = g["bufferViews"][int(a["bufferView"])];
    type = a["componentType"];
    count = a["count"];
    size_t elem = type == 5126 ? 4 : type == 5123 ? 2 : 1;
    stride = v.value("byteStride", elem * (std::string(a["type"]) == "VEC3" ? 3 : 1));
    return bin + size_t(v.value("byteOffset", 0)) + size_t(a.value("byteOffset", 0));
  };
  // Intensity and classification are found through EXT_structural_metadata, as a client would:
  // primitive -> property attribute -> attribute name, with the class's component type.
  const json& meta = g["extensions"]["EXT_structural_metadata"];
  const json& pa =
      meta["propertyAttributes"][int(g["meshes"][0]["primitives"][0]["extensions"]
                                      ["EXT_structural_metadata"]["propertyAttributes"][0])];
  const json& cls = meta["schema"]["classes"][std::string(pa["class"])]["properties"];
  auto attribute_of = [&](const char* property, int component_type) {
    EXPECT_EQ(cls[property]["componentType"], component_type == 5123 ? "UINT16" : "UINT8");
    return std::string(pa["properties"][property]["attribute"]);
  };
  const std::string intensity = attribute_of("intensity", 5123);
  const std::string classification = attribute_of("classification", 5121);
  size_t stride, count, istride, icount, cstride, ccount;
  int type, itype, ctype;
  size_t off = view_of("POSITION", stride, type, count);
  size_t ioff = view_of(intensity.c_str(), istride, itype, icount);
  size_t coff = view_of(classification.c_str(), cstride, ctype, ccount);
  EXPECT_EQ(itype, 5123);
  EXPECT_EQ(ctype, 5121);
  EXPECT_EQ(icount, count);
  EXPECT_EQ(ccount, count);
  std::vector<Decoded> out(count);
  for (size_t i = 0; i < count; ++i) {
    glm::dvec3 p;
    for (int k = 0; k < 3; ++k)
      p[k] = type == 5126 ? double(at<float>(b, off + i * stride + 4 * k))
                          : double(at<uint16_t>(b, off + i * stride + 2 * k));
    p = p * s + t;
    out[i].local = {p.x, -p.z, p.y};
    out[i].intensity = at<uint16_t>(b, ioff + i * istride);
    out[i].classification = b[coff + i * cstride];
  }
  return out;
}

std::vector<Decoded> decode_pnts(const std::vector<uint8_t>& b) {
  EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "pnts");
  uint32_t fj = at<uint32_t>(b, 12), fb = at<uint32_t>(b, 16), bj = at<uint32_t>(b, 20);
  json ft = json::parse(std::string(b.begin() + 28, b.begin() + 28 + fj));
  json bt = json::parse(std::string(b.begin() + 28 + fj + fb, b.begin() + 28 + fj + fb + bj));
  const size_t fbin = 28 + fj, bbin = 28 + fj + fb + bj;
  EXPECT_EQ(fbin % 8, 0u);
  EXPECT_EQ(bbin % 8, 0u);
  size_t n = ft["POINTS_LENGTH"];
  glm::dvec3 rtc(ft["RTC_CENTER"][0], ft["RTC_CENTER"][1], ft["RTC_CENTER"][2]);
  std::vector<Decoded> out(n);
  for (size_t i = 0; i < n; ++i) {
    glm::dvec3 p;
    if (ft.contains("POSITION_QUANTIZED")) {
      glm::dvec3 o(ft["QUANTIZED_VOLUME_OFFSET"][0], ft["QUANTIZED_VOLUME_OFFSET"][1],
                   ft["QUANTIZED_VOLUME_OFFSET"][2]);
      glm::dvec3 s(ft["QUANTIZED_VOLUME_SCALE"][0], ft["QUANTIZED_VOLUME_SCALE"][1],
                   ft["QUANTIZED_VOLUME_SCALE"][2]);
      for (int k = 0; k < 3; ++k)
        p[k] = at<uint16_t>(b, fbin + int(ft["POSITION_QUANTIZED"]["byteOffset"]) + 6 * i + 2 * k);
      p = p * s / 65535.0 + o;
    } else {
      for (int k = 0; k < 3; ++k)
        p[k] = at<float>(b, fbin + int(ft["POSITION"]["byteOffset"]) + 12 * i + 4 * k);
    }
    out[i].local = p + rtc;
    out[i].intensity = at<uint16_t>(b, bbin + int(bt["INTENSITY"]["byteOffset"]) + 2 * i);
    out[i].classification = b[bbin + int(bt["CLASSIFICATION"]["byteOffset"]) + i];
  }
  return out;
}

struct Tileset {
  std::vector<Decoded> points;
  std::map<int, std::set<double>> errors_by_depth;
  size_t tiles = 0, outside = 0;
};

// Reads every tile; checks each content lies in its tile's box (tolerance `tol` metres).
Tileset read_tileset(const fs::path& dir, double tol) {
  Tileset ts;
  json j = json::parse(slurp(dir / "tileset.json"));
  const json& tr = j["root"]["transform"];
  glm::dmat4 m;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) m[c][r] = tr[c * 4 + r];
  std::function<void(const json&, int)> walk = [&](const json& t, int depth) {
    ts.errors_by_depth[depth].insert(double(t["geometricError"]));
    EXPECT_EQ(t["refine"], "ADD");
    const json& box = t["boundingVolume"]["box"];
    if (t.contains("content")) {
      ++ts.tiles;
      auto bytes = slurp(dir / std::string(t["content"]["uri"]));
      std::string uri = t["content"]["uri"];
      auto pts = uri.ends_with(".glb") ? decode_glb(bytes) : decode_pnts(bytes);
      for (Decoded& d : pts) {
        for (int k = 0; k < 3; ++k)
          if (std::abs(d.local[k] - double(box[k])) > double(box[3 + 4 * k]) + tol) ++ts.outside;
        d.ecef = glm::dvec3(m * glm::dvec4(d.local, 1.0));
        ts.points.push_back(d);
      }
    }
    if (t.contains("children"))
      for (const json& c : t["children"]) walk(c, depth + 1);
  };
  walk(j["root"], 0);
  return ts;
}

// Source points of a LAS file in ECEF (PROJ, as the tiler's own EcefTransform does).
// Every point of `las` in ECEF, through its CRS or `crs` (the tiler's --crs) when given.
std::vector<Decoded> source_ecef(const fs::path& las, const std::string& crs = "") {
  io::LasReader reader(las);
  io::PointBatch batch;
  while (reader.read(batch, 1 << 16) > 0) {
  }
  tiler::EcefTransform t(tiler::source_crs_definition(reader.header(), crs));
  std::vector<glm::dvec3> p = batch.positions;
  t.transform(p.data(), p.size());
  std::vector<Decoded> out(p.size());
  for (size_t i = 0; i < p.size(); ++i)
    out[i] = {p[i], {}, batch.intensity[i], batch.classification[i]};
  return out;
}

// Every output point matches a distinct source point within `tol` metres with equal attributes.
size_t count_matched(const std::vector<Decoded>& src, const std::vector<Decoded>& got, double tol) {
  const double cell = 0.25;
  auto key = [&](const glm::dvec3& p, int dx, int dy, int dz) {
    int64_t x = int64_t(std::floor(p.x / cell)) + dx, y = int64_t(std::floor(p.y / cell)) + dy,
            z = int64_t(std::floor(p.z / cell)) + dz;
    return uint64_t(x * 73856093) ^ uint64_t(y * 19349663) ^ uint64_t(z * 83492791);
  };
  std::unordered_multimap<uint64_t, size_t> grid;
  for (size_t i = 0; i < src.size(); ++i) grid.emplace(key(src[i].ecef, 0, 0, 0), i);
  std::vector<uint8_t> used(src.size(), 0);
  size_t matched = 0;
  for (const Decoded& g : got) {
    bool found = false;
    for (int dx = -1; dx <= 1 && !found; ++dx)
      for (int dy = -1; dy <= 1 && !found; ++dy)
        for (int dz = -1; dz <= 1 && !found; ++dz) {
          auto [b, e] = grid.equal_range(key(g.ecef, dx, dy, dz));
          for (auto it = b; it != e; ++it) {
            const Decoded& s = src[it->second];
            if (!used[it->second] && glm::length(s.ecef - g.ecef) <= tol &&
                s.intensity == g.intensity && s.classification == g.classification) {
              used[it->second] = 1, found = true, ++matched;
              break;
            }
          }
        }
  }
  return matched;
}

void expect_spacing_halves(const Tileset& ts) {
  double root = *ts.errors_by_depth.at(0).begin();
  for (auto& [depth, errors] : ts.errors_by_depth) {
    ASSERT_EQ(errors.size(), 1u) << "depth " << depth;
    EXPECT_NEAR(*errors.begin(), root / double(1 << depth), 1e-9 * root);
  }
}

fs::path generated_las(uint64_t points, const std::string& name) {
  fs::path p = temp_dir() / name;
  if (fs::exists(p)) return p;
  io::SceneParams scene;
  scene.point_count = points;
  io::LasWriteOptions o;
  o.point_format = 7;
  o.scale = glm::dvec3(0.001);
  o.offset = glm::floor(scene.origin / 1000.0) * 1000.0;
  o.wkt = "";
  o.compress = p.extension() == ".laz";
  io::LasWriter w(p, o);
  for (uint64_t first = 0; first < points; first += 1 << 20) {
    io::PointBatch b;
    io::generate_scene(scene, first, std::min<uint64_t>(1 << 20, points - first), b);
    w.write(b);
  }
  w.close();
  return p;
}

TEST(Tiler, AutzenGlbHoldsEveryPointAtItsEcefPosition) {
  fs::path las = data_dir() / "las/autzen_trim.las";
  if (!fs::exists(las)) GTEST_SKIP() << "test data " << las << " not found";
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "autzen_glb").string();
  o.max_node_points = 10000;  // several levels even for 110k points
  tiler::TileStats s = tiler::build_tileset(o);
  EXPECT_EQ(s.points, 110000u);
  EXPECT_GE(s.depth, 2);
  const double tol = 0.01 * 0.3048;  // LAS scale: 0.01 ft
  Tileset ts = read_tileset(o.output, tol);
  ASSERT_EQ(ts.points.size(), 110000u);
  EXPECT_EQ(ts.outside, 0u);
  expect_spacing_halves(ts);
  EXPECT_EQ(count_matched(source_ecef(las), ts.points, tol), 110000u);
  json j = json::parse(slurp(fs::path(o.output) / "tileset.json"));
  EXPECT_EQ(j["asset"]["version"], "1.1");
  EXPECT_FALSE(fs::exists(fs::path(o.output) / ".tmp"));
}

// The profile (issue 22): every phase in order, their walls adding up to the run, one CPU time
// per thread (the caller and each worker), the reading phase reads the input's bytes, the
// index phase writes the tiles, and the steps where the work ran; the JSON carries the same.
TEST(Tiler, ProfileCoversEveryPhaseAndThread) {
  fs::path las = data_dir() / "las/autzen_trim.las";
  if (!fs::exists(las)) GTEST_SKIP() << "test data " << las << " not found";
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "autzen_profile").string();
  o.threads = 2;
  o.sample_threads = true;
  o.max_memory = 8 << 20;  // out of core: count and distribution passes, chunk files
  tiler::TileStats s = tiler::build_tileset(o);
  ASSERT_EQ(s.threads, 2u);
  std::vector<std::string> names;
  double walls = 0;
  for (const tiler::PhaseProfile& p : s.phases) {
    names.push_back(p.name);
    walls += p.wall;
    EXPECT_EQ(p.thread_cpu.size(), 3u) << p.name;
    EXPECT_GE(p.wall, 0.0);
    EXPECT_LE(p.one_thread, p.wall + 0.01) << p.name;
  }
  EXPECT_NEAR(walls, s.seconds, 0.05);
  auto phase = [&](const std::string& n) -> const tiler::PhaseProfile& {
    auto it = std::find(names.begin(), names.end(), n);
    EXPECT_NE(it, names.end()) << n;
    return s.phases.at(size_t(it - names.begin()));
  };
  const uint64_t las_bytes = fs::file_size(las);
  EXPECT_GE(phase("read+decode+transform+count").bytes_read, las_bytes * 9 / 10);
  const auto& index = phase("index+sample+encode+write");
  EXPECT_GT(index.bytes_written, 110000u * 20);               // glb: more than 20 bytes a point
  EXPECT_GT(index.thread_cpu[1] + index.thread_cpu[2], 0.0);  // the workers did the indexing
  ASSERT_EQ(s.steps.size(), tiler::step_count);
  EXPECT_EQ(s.steps[size_t(tiler::Step::ReadDecode)].bytes >= 110000u * 34, true);
  EXPECT_GT(s.steps[size_t(tiler::Step::Sample)].cpu, 0.0);
  EXPECT_GT(s.steps[size_t(tiler::Step::Encode)].cpu, 0.0);
  EXPECT_GT(s.steps[size_t(tiler::Step::Write)].bytes, 110000u * 20);
  json j = json::parse(tiler::stats_json(s));
  EXPECT_EQ(j["points"], 110000);
  ASSERT_EQ(j["phases"].size(), s.phases.size());
  EXPECT_EQ(j["phases"][1]["name"], "read+decode+transform+count");
  EXPECT_EQ(j["phases"][1]["threadCpu"].size(), 3u);
  EXPECT_TRUE(j["steps"].contains("distribute"));
  EXPECT_NE(tiler::profile_table(s).find("| index+sample+encode+write |"), std::string::npos);
}

TEST(Tiler, AutzenPntsHoldsEveryPoint) {
  fs::path las = data_dir() / "las/autzen_trim.las";
  if (!fs::exists(las)) GTEST_SKIP() << "test data " << las << " not found";
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "autzen_pnts").string();
  o.format = tiler::Format::Pnts;
  o.max_node_points = 10000;
  tiler::build_tileset(o);
  const double tol = 0.01 * 0.3048;
  Tileset ts = read_tileset(o.output, tol);
  ASSERT_EQ(ts.points.size(), 110000u);
  EXPECT_EQ(ts.outside, 0u);
  expect_spacing_halves(ts);
  EXPECT_EQ(count_matched(source_ecef(las), ts.points, tol), 110000u);
  json j = json::parse(slurp(fs::path(o.output) / "tileset.json"));
  EXPECT_EQ(j["asset"]["version"], "1.0");
}

// Out of core, uncompressed LAS takes the re-read path (count pass, then distribution pass) and
// LAZ the staged path (one pass to a staging file): both must place every point exactly once.
class TilerOutOfCore : public testing::TestWithParam<const char*> {};

TEST_P(TilerOutOfCore, ChunksLoseAndDuplicateNothing) {
  fs::path las = generated_las(400000, std::string("gen400k.") + GetParam());
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / (std::string("gen_chunks_") + GetParam())).string();
  o.crs = "EPSG:32633";  // the generated file carries no WKT here: --crs path
  o.max_memory = 4 << 20;
  o.max_node_points = 20000;
  o.threads = 2;
  tiler::TileStats s = tiler::build_tileset(o);
  EXPECT_GT(s.chunks, 1u);
  Tileset ts = read_tileset(o.output, 0.001);
  ASSERT_EQ(ts.points.size(), 400000u);
  EXPECT_EQ(ts.outside, 0u);
  expect_spacing_halves(ts);
  EXPECT_EQ(count_matched(source_ecef(las, "EPSG:32633"), ts.points, 0.001), 400000u);
}

INSTANTIATE_TEST_SUITE_P(Tiler, TilerOutOfCore, testing::Values("las", "laz"));

// The upper levels as a task graph (issue 22): with a cap small enough for several parents to
// fit the budget at once, the parents above the chunk roots are built on the workers, and every
// point ends in exactly one tile inside its box, with the spacing halving level by level. (Which
// points a parent keeps is not compared with one thread's: with a cap this small most nodes
// hold more cells than the cap, and the even subset then kept follows the order in which the
// distribution appended the points, which the threads decide.)
TEST(Tiler, UpperLevelsBuiltOnTheWorkersLoseNothing) {
  fs::path las = generated_las(400000, "gen400k.las");
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "gen_upper_levels").string();
  o.crs = "EPSG:32633";
  o.max_memory = 4 << 20;
  o.max_node_points = 500;  // a parent of full kids needs 360 kB: two fit the budget's quarter
  o.threads = 4;
  tiler::TileStats s = tiler::build_tileset(o);
  EXPECT_GT(s.chunks, 8u);
  const auto upper = std::find_if(s.phases.begin(), s.phases.end(),
                                  [](const auto& p) { return p.name == "upper levels"; });
  ASSERT_NE(upper, s.phases.end());
  ASSERT_EQ(upper->thread_cpu.size(), 5u);
  double workers = 0;
  for (size_t t = 1; t < upper->thread_cpu.size(); ++t) workers += upper->thread_cpu[t];
  EXPECT_GT(workers, 0.0) << "the upper levels ran on the calling thread only";
  Tileset ts = read_tileset(o.output, 0.001);
  ASSERT_EQ(ts.points.size(), 400000u);
  EXPECT_EQ(ts.outside, 0u);
  expect_spacing_halves(ts);
  EXPECT_EQ(count_matched(source_ecef(las, "EPSG:32633"), ts.points, 0.001), 400000u);
}

// Split tiling: N parts (--subset I/N) merged hold every source point exactly once, with the
// spacing rules of one run, on each reading path (in memory; out of core re-read LAS and staged
// LAZ) and both part shapes (octree nodes for 8, columns for 16).
struct SplitCase {
  const char* input;  // "autzen" or a generated file's extension
  uint32_t parts;
};
void PrintTo(const SplitCase& c, std::ostream* os) {
  *os << c.input << ", " << c.parts << " parts";
}
class TilerSplit : public testing::TestWithParam<SplitCase> {};

TEST_P(TilerSplit, MergedPartsHoldEveryPointOnce) {
  const SplitCase c = GetParam();
  const bool autzen = std::string(c.input) == "autzen";
  fs::path las = autzen ? data_dir() / "las/autzen_trim.las"
                        : generated_las(400000, std::string("gen400k.") + c.input);
  if (!fs::exists(las)) GTEST_SKIP() << "test data " << las << " not found";
  const std::string name = fmt::format("split_{}_{}", c.input, c.parts);
  std::vector<std::string> parts;
  uint64_t part_points = 0;
  for (uint32_t i = 0; i < c.parts; ++i) {
    tiler::TileOptions o;
    o.inputs = {las.string()};
    o.output = (temp_dir() / fmt::format("{}_part{}", name, i)).string();
    if (!autzen) o.crs = "EPSG:32633", o.max_memory = 4 << 20;
    o.max_node_points = autzen ? 2000 : 20000;
    o.threads = 2;
    o.force = true;
    o.subset_index = i, o.subset_count = c.parts;
    part_points += tiler::build_tileset(o).points;
    parts.push_back(o.output);
  }
  const uint64_t total = autzen ? 110000 : 400000;
  EXPECT_EQ(part_points, total);
  tiler::MergeOptions m;
  m.parts = parts;
  m.output = (temp_dir() / name).string();
  m.force = true;
  EXPECT_EQ(tiler::merge_parts(m).points, total);
  const double tol = autzen ? 0.01 * 0.3048 : 0.001;
  Tileset ts = read_tileset(m.output, tol);
  ASSERT_EQ(ts.points.size(), total);
  EXPECT_EQ(ts.outside, 0u);
  expect_spacing_halves(ts);
  std::vector<Decoded> src;
  if (autzen) {
    src = source_ecef(las);
  } else {
    tiler::EcefTransform t("EPSG:32633");
    io::LasReader reader(las);
    io::PointBatch b;
    while (reader.read(b, 1 << 16) > 0) {
    }
    std::vector<glm::dvec3> p = b.positions;
    t.transform(p.data(), p.size());
    for (size_t i = 0; i < p.size(); ++i)
      src.push_back({p[i], {}, b.intensity[i], b.classification[i]});
  }
  EXPECT_EQ(count_matched(src, ts.points, tol), total);
  // A part missing: refused, naming it.
  m.parts.pop_back();
  m.output = (temp_dir() / (name + "_short")).string();
  try {
    tiler::merge_parts(m);
    ADD_FAILURE() << "a merge with a part missing succeeded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fmt::format("missing {}/{}", c.parts - 1, c.parts)),
              std::string::npos)
        << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(Tiler, TilerSplit,
                         testing::Values(SplitCase{"autzen", 8}, SplitCase{"autzen", 16},
                                         SplitCase{"las", 16}, SplitCase{"laz", 8}),
                         [](const testing::TestParamInfo<SplitCase>& info) {
                           return fmt::format("{}_{}parts", info.param.input, info.param.parts);
                         });

// A merge refuses parts whose part.json was altered out of the tiling's ranges (cube edge, root
// spacing, precision), parts of different inputs, colour or levels, and a tile file that two
// parts hold (the second used to replace the first silently); each error names the part.
TEST(TilerMerge, RefusesInconsistentOrOutOfRangeParts) {
  fs::path las = generated_las(30000, "gen30k.las");
  const fs::path root = temp_dir() / "merge_checks";
  fs::remove_all(root);
  fs::create_directories(root);
  std::vector<std::string> parts;
  for (uint32_t i = 0; i < 4; ++i) {
    tiler::TileOptions o;
    o.inputs = {las.string()};
    o.output = (root / fmt::format("part{}", i)).string();
    o.crs = "EPSG:32633";
    o.max_node_points = 2000;
    o.threads = 1;
    o.force = true;
    o.subset_index = i, o.subset_count = 4;
    tiler::build_tileset(o);
    parts.push_back(o.output);
  }
  tiler::MergeOptions m;
  m.parts = parts;
  m.force = true;
  m.threads = 1;
  m.output = (root / "merged").string();
  ASSERT_EQ(tiler::merge_parts(m).points, 30000u);

  // Runs the merge on copies of the parts with part `which` edited; returns the error.
  int run = 0;
  auto merge_edited = [&](uint32_t which, const std::function<void(nlohmann::json&)>& edit,
                          const std::function<void(const fs::path&)>& touch = {}) {
    const fs::path dir = root / fmt::format("case{}", run++);
    tiler::MergeOptions e = m;
    e.parts.clear();
    for (uint32_t i = 0; i < 4; ++i) {
      const fs::path to = dir / fmt::format("part{}", i);
      fs::create_directories(to);
      fs::copy(parts[i], to, fs::copy_options::recursive);
      if (i == which) {
        nlohmann::json j = nlohmann::json::parse(std::ifstream(to / "part.json"));
        edit(j);
        std::ofstream(to / "part.json") << j.dump();
        if (touch) touch(to);
      }
      e.parts.push_back(to.string());
    }
    e.output = (dir / "merged").string();
    try {
      tiler::merge_parts(e);
    } catch (const Error& err) {
      EXPECT_FALSE(fs::exists(e.output)) << "a failed merge left " << e.output;
      return std::string(err.what());
    }
    return std::string("merged");
  };
  auto expect_error = [](const std::string& what, const std::string& part,
                         const std::string& message) {
    EXPECT_NE(what.find(part), std::string::npos) << what;
    EXPECT_NE(what.find(message), std::string::npos) << what;
  };
  // Out of range in the first part read (the others are compared with it).
  expect_error(merge_edited(0, [](auto& j) { j["cube"][3] = 0.0; }), "part0", "out of range");
  expect_error(merge_edited(0, [](auto& j) { j["cube"][3] = 1e300; }), "part0", "out of range");
  expect_error(merge_edited(0, [](auto& j) { j["cube"][0] = -1e12; }), "part0", "out of range");
  expect_error(merge_edited(0, [](auto& j) { j["root_spacing"] = 0.0; }), "part0",
               "root spacing 0 is out of range");
  expect_error(merge_edited(0, [](auto& j) { j["root_spacing"] = -3.0; }), "part0", "out of range");
  expect_error(merge_edited(0, [](auto& j) { j["root_spacing"] = 1e-30; }), "part0",
               "out of range");
  expect_error(merge_edited(0, [](auto& j) { j["precision"] = 0.0; }), "part0",
               "precision 0 is out of range");
  // A part of other inputs, colour or levels than the first.
  expect_error(merge_edited(2, [](auto& j) { j["inputs"][0] = "/elsewhere/other.las"; }), "part2",
               "its inputs differ");
  expect_error(merge_edited(2, [](auto& j) { j["rgb"] = !j["rgb"].template get<bool>(); }), "part2",
               "its rgb differs");
  expect_error(
      merge_edited(3, [](auto& j) { j["gps_time"] = !j["gps_time"].template get<bool>(); }),
      "part3", "its gps_time differs");
  expect_error(
      merge_edited(1, [](auto& j) { j["max_level"] = j["max_level"].template get<int>() + 1; }),
      "part1", "its max_level differs");
  expect_error(merge_edited(1, [](auto& j) { j["level"] = j["level"].template get<int>() + 1; }),
               "part1", "its level differs");
  // A tile file of part 0 also in part 3: refused, not overwritten.
  std::string taken;
  for (const auto& f : fs::directory_iterator(fs::path(parts[0]) / "tiles"))
    if (f.is_regular_file()) taken = f.path().filename().string();
  ASSERT_FALSE(taken.empty());
  expect_error(merge_edited(
                   3, [](auto&) {},
                   [&](const fs::path& part) { std::ofstream(part / "tiles" / taken) << "other"; }),
               "part3", "tile file " + taken + " is in another part too");
  // The unedited copies still merge.
  EXPECT_EQ(merge_edited(1, [](auto&) {}), "merged");
  fs::remove_all(root);
}

TEST(Tiler, InputWithoutCrsIsRefused) {
  fs::path las = generated_las(400000, "gen400k.las");
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "nocrs").string();
  EXPECT_THROW(tiler::build_tileset(o), Error);
  EXPECT_FALSE(fs::exists(o.output));
}

TEST(Tiler, FailureMidwayLeavesNoOutput) {
  fs::path las = data_dir() / "las/autzen_trim.las";
  if (!fs::exists(las)) GTEST_SKIP() << "test data " << las << " not found";
  // A copy cut short: the header promises more points than the file holds.
  fs::path cut = temp_dir() / "cut.las";
  auto bytes = slurp(las);
  bytes.resize(bytes.size() * 2 / 3);
  std::ofstream(cut, std::ios::binary)
      .write(reinterpret_cast<char*>(bytes.data()), std::streamsize(bytes.size()));
  tiler::TileOptions o;
  o.inputs = {las.string(), cut.string()};
  o.output = (temp_dir() / "failed").string();
  EXPECT_THROW(tiler::build_tileset(o), Error);
  EXPECT_FALSE(fs::exists(o.output));
  for (auto& e : fs::directory_iterator(temp_dir()))
    EXPECT_EQ(e.path().filename().string().find("failed.partial"), std::string::npos) << e.path();
  // An existing output is refused without --force, replaced with it.
  o.inputs = {las.string()};
  fs::create_directories(o.output);
  EXPECT_THROW(tiler::build_tileset(o), Error);
  o.force = true;
  EXPECT_NO_THROW(tiler::build_tileset(o));
  EXPECT_TRUE(fs::exists(fs::path(o.output) / "tileset.json"));
}

TEST(Tiler, GlbPassesKhronosValidator) {
  fs::path node_prefix = fs::path(STIPPLE_SOURCE_DIR) / ".deps/node";
  if (!fs::exists(node_prefix / "node_modules/gltf-validator") ||
      std::system("node --version >/dev/null 2>&1") != 0)
    GTEST_SKIP()
        << "gltf-validator not installed (scripts/setup.sh --deps installs it into .deps/node)";
  fs::path las = data_dir() / "las/autzen_trim.las";
  if (!fs::exists(las)) GTEST_SKIP() << "test data " << las << " not found";
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "autzen_validate").string();
  o.max_node_points = 10000;
  tiler::build_tileset(o);
  std::string cmd = "node " STIPPLE_SOURCE_DIR "/tests/tools/validate_glb.js " +
                    node_prefix.string() + " " + o.output + "/tiles/*.glb";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

TEST(Tiler, PeakMemoryStaysUnderBudget) {
#if defined(__SANITIZE_ADDRESS__)
#define STIPPLE_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define STIPPLE_TEST_ASAN 1
#endif
#endif
#ifdef STIPPLE_TEST_ASAN
  GTEST_SKIP() << "peak RSS under AddressSanitizer counts shadow memory and the quarantine";
#endif
  // A child `stipple tile` with --max-memory 48M on an input of 10x that (14M points, 500 MB).
  const uint64_t points = 14'000'000;
  fs::path las = generated_las(points, "gen14m.las");
  ASSERT_GE(fs::file_size(las), 10ull * (48 << 20));
  fs::path small = generated_las(100'000, "gen100k.las");
  fs::path out = temp_dir() / "mem";
  // Peak RSS of one child `stipple tile` (wait4 gives this child's own, where RUSAGE_CHILDREN
  // would include earlier children).
  auto peak_rss_mb = [&](const fs::path& input) {
    fs::remove_all(out);
    std::string bin = STIPPLE_BINARY, in = input.string(), output = out.string();
    std::vector<std::string> args = {bin,          "tile",         in,   "-o", output, "--crs",
                                     "EPSG:32633", "--max-memory", "48M"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_t pid = fork();
    if (pid == 0) {
      execv(bin.c_str(), argv.data());
      _exit(127);
    }
    rusage r{};
    int status = 0;
    if (pid <= 0 || wait4(pid, &status, 0, &r) != pid || !WIFEXITED(status) ||
        WEXITSTATUS(status) != 0)
      return -1.0;
    return double(r.ru_maxrss) / 1024.0;
  };
  const double baseline_mb = peak_rss_mb(small);
  const double peak_mb = peak_rss_mb(las);
  ASSERT_GT(baseline_mb, 0.0);
  ASSERT_GT(peak_mb, 0.0);
  std::printf("peak RSS of stipple tile: %.1f MB on 14M points, %.1f MB on 100k (budget 48 MB)\n",
              peak_mb, baseline_mb);
  // --max-memory budgets the memory that grows with the input; the process baseline (binary,
  // shared libraries, one PROJ database context per thread: ~14 MB for `stipple --version`) is
  // measured by tiling a 100k-point input with the same settings, and comes on top.
  EXPECT_LT(peak_mb - baseline_mb, 48.0);
  fs::remove_all(out);
  fs::remove(las);
  fs::remove(small);
}

}  // namespace

namespace {

// Largest distance between source_to_local and PROJ point by point, for points spread over
// `extent` (source units) around `centre` with heights in [zlo, zhi].
double lattice_error(const std::string& crs, const glm::dvec3& centre, double extent, double zlo,
                     double zhi, double tolerance, tiler::LatticeStats& stats) {
  tiler::EcefTransform t(crs);
  glm::dvec3 c = centre;
  t.transform(&c, 1);
  tiler::LocalFrame frame = tiler::make_local_frame(c);
  std::vector<glm::dvec3> src(200000);
  uint64_t state = 12345;
  auto rnd = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) / double(1ull << 53);
  };
  for (auto& p : src)
    p = {centre.x + (rnd() - 0.5) * extent, centre.y + (rnd() - 0.5) * extent,
         zlo + rnd() * (zhi - zlo)};
  std::vector<glm::dvec3> fast(src.size()), exact = src;
  tiler::source_to_local(t, frame, src.data(), src.size(), fast.data(), tolerance, &stats);
  t.transform(exact.data(), exact.size());
  double worst = 0;
  for (size_t i = 0; i < src.size(); ++i)
    worst = std::max(worst, glm::length(frame.to_local(exact[i]) - fast[i]));
  return worst;
}

}  // namespace

// The lattice transform stays within its tolerance of PROJ point by point, in metres, feet and
// degrees, and really interpolates (PROJ runs on far fewer nodes than points).
TEST(TilerLattice, MatchesProjWithinTolerance) {
  struct Case {
    const char* crs;
    glm::dvec3 centre;
    double extent, zlo, zhi;
  } cases[] = {
      {"EPSG:32633", {500000, 6650000, 0}, 1000, -100, 2500},  // UTM metres, 60 N
      {"EPSG:2992", {4235000, 868000, 0}, 3000, 300, 900},     // Oregon Lambert, feet
      {"EPSG:4326", {10.7, 59.9, 0}, 0.01, 0, 600},            // degrees
      {"EPSG:32601", {166100, 100000, 0}, 1000, 0, 100},       // UTM zone edge, near equator
  };
  for (const Case& c : cases) {
    tiler::LatticeStats stats;
    double err = lattice_error(c.crs, c.centre, c.extent, c.zlo, c.zhi, 1e-4, stats);
    EXPECT_LE(err, 1e-4) << c.crs;
    EXPECT_EQ(stats.exact_points, 0u) << c.crs;
    EXPECT_LT(stats.nodes * 4, stats.points) << c.crs;
  }
}

// A batch spread too widely for the lattice, or a tolerance the lattice cannot meet, is
// transformed point by point: exact, never worse.
TEST(TilerLattice, FallsBackToExact) {
  tiler::LatticeStats wide;
  EXPECT_LE(lattice_error("EPSG:32633", {500000, 6650000, 0}, 400000, 0, 100, 1e-4, wide), 1e-6);
  EXPECT_EQ(wide.exact_points, wide.points);
  tiler::LatticeStats strict;
  EXPECT_LE(lattice_error("EPSG:32633", {500000, 6650000, 0}, 3000, 0, 100, 1e-12, strict), 1e-6);
  EXPECT_EQ(strict.exact_points, strict.points);
}

// The glb output's EXT_structural_metadata property attributes decode (through stipple's own
// glb reader, as any client would) to the source's intensities and GPS times: gps_time is the
// float32 _GPS_TIME plus the property's offset.
TEST(Tiler, GlbMetadataCarriesIntensityAndGpsTime) {
  fs::path las = generated_las(400000, "gen400k.las");
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "gen_metadata").string();
  o.crs = "EPSG:32633";
  o.max_node_points = 20000;
  tiler::build_tileset(o);
  io::LasReader reader(las);
  io::PointBatch src;
  while (reader.read(src, 1 << 16) > 0) {
  }
  ASSERT_FALSE(src.gps_time.empty());
  std::vector<double> want_gps = src.gps_time, got_gps;
  std::vector<double> want_int(src.intensity.begin(), src.intensity.end()), got_int;
  for (const auto& f : fs::directory_iterator(fs::path(o.output) / "tiles")) {
    std::vector<uint8_t> bytes = slurp(f.path());
    io::PointContent c = io::decode_glb_points(bytes, f.path().string());
    for (const char* k : {"intensity", "classification", "return_number", "gps_time"})
      ASSERT_TRUE(c.attributes.count(k)) << f.path() << " lacks " << k;
    EXPECT_EQ(c.attributes["intensity"].values, c.attributes["_INTENSITY"].values);
    got_int.insert(got_int.end(), c.attributes["intensity"].values.begin(),
                   c.attributes["intensity"].values.end());
    got_gps.insert(got_gps.end(), c.attributes["gps_time"].values.begin(),
                   c.attributes["gps_time"].values.end());
  }
  std::sort(want_int.begin(), want_int.end());
  std::sort(got_int.begin(), got_int.end());
  EXPECT_EQ(got_int, want_int);
  ASSERT_EQ(got_gps.size(), want_gps.size());
  std::sort(want_gps.begin(), want_gps.end());
  std::sort(got_gps.begin(), got_gps.end());
  // Float32 relative to a tile's earliest time: at most 2^-23 of the span per value, and sorting
  // two sequences whose elements differ by at most e keeps them within e.
  const double tol = std::max(1e-6, (want_gps.back() - want_gps.front()) * std::ldexp(1.0, -23));
  double worst = 0;
  for (size_t i = 0; i < want_gps.size(); ++i)
    worst = std::max(worst, std::abs(got_gps[i] - want_gps[i]));
  EXPECT_LE(worst, tol);
}

// glTF defines COLOR_0 as linear: the glb output holds the LAS sRGB colours through the sRGB
// transfer function (a client that encodes them for display again then shows the source
// colours), in 16 bits so that every 8-bit value comes back exactly. Read raw, without
// stipple's reader, and decoded here with the transfer function written out.
TEST(Tiler, GlbColor0IsLinear) {
  fs::path las = generated_las(100000, "gen100k.las");
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "gen_linear_color").string();
  o.crs = "EPSG:32633";
  o.max_node_points = 20000;
  tiler::build_tileset(o);
  io::LasReader reader(las);
  io::PointBatch src;
  while (reader.read(src, 1 << 16) > 0) {
  }
  ASSERT_FALSE(src.rgb.empty());
  const int shift = reader.header().rgb_bits == 8 ? 0 : 8;
  std::vector<uint32_t> want, got;
  double linear_sum = 0, srgb_sum = 0;
  for (const auto& c : src.rgb)
    want.push_back(uint32_t(c.x >> shift) | uint32_t(c.y >> shift) << 8 |
                   uint32_t(c.z >> shift) << 16);
  auto encode = [](double l) {
    double e = l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1 / 2.4) - 0.055;
    return uint32_t(std::lround(e * 255));
  };
  for (const auto& f : fs::directory_iterator(fs::path(o.output) / "tiles")) {
    std::vector<uint8_t> b = slurp(f.path());
    uint32_t jlen = at<uint32_t>(b, 12);
    json g = json::parse(std::string(b.begin() + 20, b.begin() + 20 + jlen));
    const size_t bin = 20 + jlen + 8;
    const json& a = g["accessors"][int(g["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"])];
    ASSERT_EQ(a["componentType"], 5123);
    ASSERT_EQ(a["type"], "VEC3");
    ASSERT_TRUE(a.value("normalized", false));
    const json& v = g["bufferViews"][int(a["bufferView"])];
    const size_t stride = v.value("byteStride", 6);
    const size_t base = bin + size_t(v.value("byteOffset", 0)) + size_t(a.value("byteOffset", 0));
    for (size_t i = 0; i < size_t(a["count"]); ++i) {
      uint32_t rgb = 0;
      for (int k = 0; k < 3; ++k) {
        const double l = at<uint16_t>(b, base + i * stride + 2 * k) / 65535.0;
        rgb |= encode(l) << (8 * k);
        linear_sum += l;
      }
      got.push_back(rgb);
    }
  }
  for (uint32_t c : want) srgb_sum += ((c & 255) + (c >> 8 & 255) + (c >> 16 & 255)) / 255.0;
  std::sort(want.begin(), want.end());
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, want);
  // Stored linear, not encoded: the mean is well below the sRGB mean for mid-tone colours.
  EXPECT_LT(linear_sum, srgb_sum * 0.8);
}

// pnts GPS time is FLOAT seconds after the tile's earliest time (extras.offsets.GPS_TIME): glTF
// has no float64, so converters to 3D Tiles 1.1 (3d-tiles-tools) refuse DOUBLE. The decoder
// adds the offset back: every source time within float32's resolution over the data's span.
TEST(Tiler, PntsGpsTimeIsFloatPlusOffset) {
  fs::path las = generated_las(100000, "gen100k.las");
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.output = (temp_dir() / "gen_pnts_gps").string();
  o.crs = "EPSG:32633";
  o.format = tiler::Format::Pnts;
  o.max_node_points = 20000;
  tiler::build_tileset(o);
  io::LasReader reader(las);
  io::PointBatch src;
  while (reader.read(src, 1 << 16) > 0) {
  }
  std::vector<double> want = src.gps_time, got;
  for (const auto& f : fs::directory_iterator(fs::path(o.output) / "tiles")) {
    std::vector<uint8_t> bytes = slurp(f.path());
    const uint32_t ft = at<uint32_t>(bytes, 12), ftb = at<uint32_t>(bytes, 16),
                   bt = at<uint32_t>(bytes, 20);
    json table =
        json::parse(std::string(bytes.begin() + 28 + ft + ftb, bytes.begin() + 28 + ft + ftb + bt));
    EXPECT_EQ(table["GPS_TIME"]["componentType"], "FLOAT") << f.path();
    EXPECT_TRUE(table["extras"]["offsets"]["GPS_TIME"].is_number()) << f.path();
    io::PointContent c = io::decode_pnts(bytes, f.path().string());
    const auto& v = c.attributes.at("GPS_TIME").values;
    got.insert(got.end(), v.begin(), v.end());
  }
  std::sort(want.begin(), want.end());
  std::sort(got.begin(), got.end());
  ASSERT_EQ(got.size(), want.size());
  const double tol = std::max(1e-6, (want.back() - want.front()) * std::ldexp(1.0, -23));
  double worst = 0;
  for (size_t i = 0; i < want.size(); ++i) worst = std::max(worst, std::abs(got[i] - want[i]));
  EXPECT_LE(worst, tol);
}

// Every --compress option keeps every point and attribute: glb with EXT_meshopt_compression and
// pnts with 3DTILES_draco_point_compression decode (stipple's readers, which follow the
// extensions' specifications) to the source's intensities, classes, colours exactly and GPS
// times within float32 resolution, in fewer bytes than the uncompressed output. Draco for glb
// (no point primitives in KHR_draco_mesh_compression) and meshopt for pnts are refused.
TEST(Tiler, CompressedOutputsKeepEveryPoint) {
  fs::path las = generated_las(100000, "gen100k.las");
  io::LasReader reader(las);
  io::PointBatch src;
  while (reader.read(src, 1 << 16) > 0) {
  }
  const int shift = reader.header().rgb_bits == 8 ? 0 : 8;
  std::vector<uint64_t> want;  // intensity, class, colour packed per point
  for (size_t i = 0; i < src.size(); ++i)
    want.push_back(uint64_t(src.intensity[i]) << 48 | uint64_t(src.classification[i]) << 40 |
                   uint64_t(src.rgb[i].x >> shift) << 16 | uint64_t(src.rgb[i].y >> shift) << 8 |
                   uint64_t(src.rgb[i].z >> shift));
  std::sort(want.begin(), want.end());
  std::vector<double> want_gps = src.gps_time;
  std::sort(want_gps.begin(), want_gps.end());
  auto tile_bytes = [](const fs::path& dir) {
    uint64_t n = 0;
    for (const auto& f : fs::directory_iterator(dir / "tiles")) n += fs::file_size(f.path());
    return n;
  };
  for (auto [format, compression] :
       {std::pair{tiler::Format::Glb, "meshopt"}, std::pair{tiler::Format::Pnts, "draco"}}) {
    tiler::TileOptions o;
    o.inputs = {las.string()};
    o.crs = "EPSG:32633";
    o.format = format;
    o.max_node_points = 20000;
    o.output = (temp_dir() / (std::string("plain_") + compression)).string();
    tiler::build_tileset(o);
    const uint64_t plain = tile_bytes(o.output);
    o.compression = compression;
    o.output = (temp_dir() / (std::string("packed_") + compression)).string();
    tiler::build_tileset(o);
    const uint64_t packed = tile_bytes(o.output);
    EXPECT_LT(packed, plain * 3 / 4) << compression;
    std::vector<uint64_t> got;
    std::vector<double> got_gps;
    for (const auto& f : fs::directory_iterator(fs::path(o.output) / "tiles")) {
      std::vector<uint8_t> bytes = slurp(f.path());
      io::PointContent c = format == tiler::Format::Glb
                               ? io::decode_glb_points(bytes, f.path().string())
                               : io::decode_pnts(bytes, f.path().string());
      EXPECT_EQ(c.format, format == tiler::Format::Glb ? "glb" : "pnts+draco");
      auto values = [&](std::initializer_list<const char*> keys) {
        for (const char* k : keys)
          if (c.attributes.count(k)) return c.attributes.at(k).values;
        ADD_FAILURE() << f.path() << " lacks " << *keys.begin();
        return std::vector<double>(c.point_count, 0.0);
      };
      const auto intensity = values({"intensity", "INTENSITY"});
      const auto cls = values({"classification", "CLASSIFICATION"});
      const auto gps = values({"gps_time", "GPS_TIME"});
      ASSERT_EQ(c.rgba.size(), c.point_count);
      for (size_t i = 0; i < c.point_count; ++i) {
        const uint32_t rgba = c.rgba[i];
        got.push_back(uint64_t(intensity[i]) << 48 | uint64_t(cls[i]) << 40 |
                      uint64_t(rgba & 255) << 16 | uint64_t(rgba >> 8 & 255) << 8 |
                      uint64_t(rgba >> 16 & 255));
      }
      got_gps.insert(got_gps.end(), gps.begin(), gps.end());
    }
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, want) << compression;
    std::sort(got_gps.begin(), got_gps.end());
    ASSERT_EQ(got_gps.size(), want_gps.size());
    const double tol = std::max(1e-6, (want_gps.back() - want_gps.front()) * std::ldexp(1.0, -23));
    double worst = 0;
    for (size_t i = 0; i < want_gps.size(); ++i)
      worst = std::max(worst, std::abs(got_gps[i] - want_gps[i]));
    EXPECT_LE(worst, tol) << compression;
  }
  tiler::TileOptions bad;
  bad.inputs = {las.string()};
  bad.crs = "EPSG:32633";
  bad.output = (temp_dir() / "refused").string();
  bad.compression = "draco";
  EXPECT_THROW(tiler::build_tileset(bad), Error);
  bad.format = tiler::Format::Pnts;
  bad.compression = "meshopt";
  EXPECT_THROW(tiler::build_tileset(bad), Error);
  EXPECT_FALSE(fs::exists(bad.output));
}

// --implicit: 3D Tiles 1.1 implicit octree. Read back through stipple's tileset reader (which
// follows the implicit tiling specification: subtree files, Morton-ordered availability), the
// tree holds one tile per content file written, at the file's level and key, with the
// geometric error halving per level, across child subtrees (two levels a subtree).
TEST(Tiler, ImplicitOctreeNamesEveryTile) {
  fs::path las = generated_las(100000, "gen100k.las");
  tiler::TileOptions o;
  o.inputs = {las.string()};
  o.crs = "EPSG:32633";
  o.max_node_points = 1500;
  o.implicit = true;
  o.subtree_levels = 2;
  o.output = (temp_dir() / "implicit").string();
  tiler::TileStats stats = tiler::build_tileset(o);
  ASSERT_GE(stats.depth, 3) << "too shallow to need child subtrees";
  json j = json::parse(slurp(fs::path(o.output) / "tileset.json"));
  EXPECT_EQ(j["asset"]["version"], "1.1");
  EXPECT_EQ(j["root"]["implicitTiling"]["subdivisionScheme"], "OCTREE");
  EXPECT_FALSE(j["root"].contains("children"));
  std::set<std::string> files;
  for (const auto& f : fs::directory_iterator(fs::path(o.output) / "tiles"))
    files.insert(f.path().filename().string());
  size_t subtrees = 0;
  for (const auto& f : fs::directory_iterator(fs::path(o.output) / "subtrees")) {
    (void)f;
    ++subtrees;
  }
  EXPECT_GT(subtrees, 1u);
  io::TilesetOptions options;
  io::Tileset ts = io::load_tileset((fs::path(o.output) / "tileset.json").string(), options);
  ASSERT_TRUE(io::expand_all(
      ts, [](const std::string& u) { return io::fetch(u); }, options, 1000000));
  EXPECT_TRUE(ts.errors.empty()) << ts.errors.front();
  EXPECT_EQ(ts.subtrees, subtrees);
  std::set<std::string> named;
  const double root_error = ts.tiles[0].geometric_error;
  for (const auto& t : ts.tiles)
    for (const auto& c : t.contents) {
      const std::string name = fs::path(c).filename().string();
      EXPECT_TRUE(named.insert(name).second) << name << " named twice";
      const int level = std::stoi(name.substr(0, name.find('-')));
      EXPECT_NEAR(t.geometric_error, root_error / double(1 << level), 1e-12) << name;
    }
  EXPECT_EQ(named, files);
}
