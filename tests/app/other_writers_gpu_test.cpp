// Files with the properties that files from other writers showed (issue 21): each test writes
// its input with the property named, runs `stipple`, and checks the image, the exit status or
// the printed text.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <functional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "las_bytes.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir() {
  fs::path dir =
      fs::temp_directory_path() / ("stipple-writers-" + std::to_string(::getpid()) + "-" +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

const uint8_t kBackground[3] = {18, 20, 26};  // render's default (0.07, 0.08, 0.1)

// Where an image differs from the background: pixel count and bounding box.
struct Covered {
  size_t pixels = 0;
  uint32_t x0 = ~0u, y0 = ~0u, x1 = 0, y1 = 0;
  double cx() const { return 0.5 * (x0 + x1); }
  double cy() const { return 0.5 * (y0 + y1); }
};

Covered covered(const gpu::Image& image, int tolerance = 2) {
  Covered c;
  for (uint32_t y = 0; y < image.height; ++y)
    for (uint32_t x = 0; x < image.width; ++x) {
      const uint8_t* p = &image.rgba[(size_t(y) * image.width + x) * 4];
      bool bg = true;
      for (int k = 0; k < 3; ++k) bg = bg && std::abs(p[k] - kBackground[k]) <= tolerance;
      if (bg) continue;
      ++c.pixels;
      c.x0 = std::min(c.x0, x), c.y0 = std::min(c.y0, y);
      c.x1 = std::max(c.x1, x), c.y1 = std::max(c.y1, y);
    }
  return c;
}

size_t occurrences(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// A b3dm (batched 3D model) tile around a glb of one triangle: meshes, no points.
test::Bytes triangle_glb() {
  std::vector<float> positions = {0, 0, 0, 10, 0, 0, 0, 10, 0};
  test::Bytes bin;
  test::append(bin, positions);
  nlohmann::json j = {
      {"asset", {{"version", "2.0"}}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews", {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", bin.size()}}}},
      {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}}}},
      {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}, {"mode", 4}}}}}}},
      {"nodes", {{{"mesh", 0}}}},
      {"scenes", {{{"nodes", {0}}}}},
      {"scene", 0}};
  return test::make_glb(j, bin);
}

test::Bytes b3dm_tile() {
  test::Bytes glb = triangle_glb();
  test::Bytes ftj = test::json_bytes({{"BATCH_LENGTH", 0}});
  while ((28 + ftj.size()) % 8) ftj.push_back(' ');
  test::Bytes out = {'b', '3', 'd', 'm'};
  test::put_u32(out, 1);
  test::put_u32(out, uint32_t(28 + ftj.size() + glb.size()));
  test::put_u32(out, uint32_t(ftj.size()));
  for (int i = 0; i < 3; ++i) test::put_u32(out, 0);
  out.insert(out.end(), ftj.begin(), ftj.end());
  out.insert(out.end(), glb.begin(), glb.end());
  return out;
}

// A pnts tile of n points on a 10 x 10 grid from (x0, 0, 0), one colour, the feature table
// extended with `extra` semantics.
test::Bytes grid_tile(uint32_t n, float x0, std::array<uint8_t, 3> rgb,
                      const nlohmann::json& extra = nlohmann::json::object()) {
  std::vector<float> pos;
  test::Bytes colours;
  for (uint32_t i = 0; i < n; ++i) {
    pos.insert(pos.end(), {x0 + float(i % 10), float(i / 10 % 10), 0.0f});
    colours.insert(colours.end(), rgb.begin(), rgb.end());
  }
  test::Bytes bin;
  test::append(bin, pos);
  const size_t rgb_at = bin.size();
  bin.insert(bin.end(), colours.begin(), colours.end());
  nlohmann::json ft = {
      {"POINTS_LENGTH", n}, {"POSITION", {{"byteOffset", 0}}}, {"RGB", {{"byteOffset", rgb_at}}}};
  ft.update(extra);
  return test::make_pnts(ft, bin);
}

// tileset.json with one child per content, side by side along x (20 m apart, 10 m boxes); a
// content without bytes is not written (a missing file).
void write_flat_tileset(const fs::path& dir,
                        const std::vector<std::pair<std::string, test::Bytes>>& contents) {
  nlohmann::json children = nlohmann::json::array();
  for (size_t i = 0; i < contents.size(); ++i) {
    if (!contents[i].second.empty()) test::write_file(dir / contents[i].first, contents[i].second);
    const double x = 5.0 + 20.0 * double(i);
    children.push_back({{"boundingVolume", {{"box", {x, 5, 0, 5, 0, 0, 0, 5, 0, 0, 0, 1}}}},
                        // An external tileset is read only where the view refines into it.
                        {"geometricError", contents[i].first.ends_with(".json") ? 100 : 0},
                        {"content", {{"uri", contents[i].first}}}});
  }
  const double half = 10.0 * double(contents.size());
  test::write_json(dir / "tileset.json",
                   {{"asset", {{"version", "1.0"}}},
                    {"geometricError", 1000},
                    {"root",
                     {{"boundingVolume", {{"box", {half, 5, 0, half, 0, 0, 0, 5, 0, 0, 0, 1}}}},
                      {"geometricError", 1000},  // always refined to the children
                      {"refine", "ADD"},
                      {"children", children}}}});
}

}  // namespace

// Item 1: zero extent (one point, or every point at one location) used to give a blank image
// reported as a success; it is framed as a few metres around the location now, and drawn.
TEST(OtherWriters, ZeroExtentCloudIsFramedAndDrawn) {
  const fs::path dir = temp_dir();
  for (size_t n : {size_t(1), size_t(500)}) {
    test::LasFile f;
    f.point_format = 2;
    f.scale = {0.001, 0.001, 0.001};
    for (size_t i = 0; i < n; ++i) {
      test::LasPoint p;
      p.x = 512345.678, p.y = 5123456.789, p.z = 321.5;
      p.r = 65535;  // red
      f.points.push_back(p);
    }
    const fs::path las = dir / fmt::format("at-one-place-{}.las", n);
    const fs::path png = dir / fmt::format("at-one-place-{}.png", n);
    test::write_las(las, f);
    // (One colour for every point is no colour for --color auto: ask for it.)
    auto r = test::run_stipple(fmt::format("render {} -o {} --width 160 --height 100 --color rgb",
                                           las.string(), png.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(fmt::format("rendered {} points", n)), std::string::npos) << r.output;
    const gpu::Image image = gpu::read_png(png);
    const Covered c = covered(image);
    // A point marker of several pixels, red, in the middle of the image.
    EXPECT_GE(c.pixels, 9u) << n;
    EXPECT_LT(c.pixels, 400u) << n;
    EXPECT_NEAR(c.cx(), 80.0, 16.0) << n;
    EXPECT_NEAR(c.cy(), 50.0, 10.0) << n;
    const auto stats = test::coverage_stats(image, kBackground);
    EXPECT_GT(stats.mean[0], 2.0 * stats.mean[1]) << n;
  }
}

// Item 6: a tile's problem used to be printed twice (by the streamer and by the plugin), and once
// per tile; each kind is printed once now, with a count of the tiles not named. Content that is
// not points (b3dm) is said once, by the load (which reads the first contents' headers), and not
// again by its tiles.
TEST(OtherWriters, TileProblemsAreReportedOnce) {
  const fs::path dir = temp_dir();
  const nlohmann::json unknown = {{"FOO", {{"byteOffset", 0}}}};
  write_flat_tileset(dir, {{"m0.b3dm", b3dm_tile()},
                           {"m1.b3dm", b3dm_tile()},
                           {"m2.b3dm", b3dm_tile()},
                           {"p0.pnts", grid_tile(100, 60.0f, {200, 50, 50}, unknown)},
                           {"p1.pnts", grid_tile(100, 80.0f, {200, 50, 50}, unknown)},
                           {"missing.json", {}}});
  const fs::path png = dir / "out.png";
  auto r = test::run_stipple(fmt::format("render {} -o {} --width 160 --height 100",
                                         (dir / "tileset.json").string(), png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("rendered 200 points"), std::string::npos) << r.output;
  EXPECT_EQ(occurrences(r.output, "b3dm (batched 3D models)"), 1u) << r.output;
  EXPECT_EQ(occurrences(r.output, "unknown semantic FOO ignored"), 1u) << r.output;
  EXPECT_NE(r.output.find("1 more tiles had the problems above"), std::string::npos) << r.output;
  // A broken external tileset: recorded by the reader, printed by the plugin, once.
  EXPECT_EQ(occurrences(r.output, "missing.json: cannot open"), 1u) << r.output;

  r = test::run_stipple("info " + (dir / "tileset.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(occurrences(r.output, "b3dm (batched 3D models)"), 1u) << r.output;
  EXPECT_NE(r.output.find("3 of 5 contents are b3dm (batched 3D models)"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("FOO ignored (and 1 more tiles)"), std::string::npos) << r.output;
  EXPECT_EQ(occurrences(r.output, "unknown semantic FOO ignored"), 1u) << r.output;
  EXPECT_EQ(occurrences(r.output, "missing.json: cannot open"), 1u) << r.output;
}

// Item 2: a tileset without point content (a triangle-only glb, or b3dm) used to give a fully
// transparent PNG and "rendered 0 points" with exit 0, and `info` saw no problem. It is an
// error now, as for LAS, with the reason; a view with nothing in it is the background colour.
TEST(OtherWriters, TilesetWithoutPointsIsAnError) {
  const fs::path dir = temp_dir();
  struct Case {
    std::string name;
    test::Bytes bytes;
    std::string reason;
  };
  for (const Case& c :
       {Case{"mesh.glb", triangle_glb(), "glb meshes, which stipple does not draw"},
        Case{"mesh.b3dm", b3dm_tile(), "b3dm (batched 3D models), which stipple does not draw"}}) {
    SCOPED_TRACE(c.name);
    const fs::path tiles = dir / c.name;
    write_flat_tileset(tiles, {{c.name, c.bytes}});
    const fs::path png = dir / (c.name + ".png");
    auto r = test::run_stipple(fmt::format("render {} -o {} --width 160 --height 100",
                                           (tiles / "tileset.json").string(), png.string()));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find((tiles / "tileset.json").string() +
                            ": nothing to render: the tiles in view hold no points"),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find(c.reason), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(png));

    r = test::run_stipple("info " + (tiles / "tileset.json").string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("problem: nothing to render"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(c.reason), std::string::npos) << r.output;
  }

  // Points, but none in view: the background colour (it was transparent), and a warning.
  const fs::path tiles = dir / "points";
  write_flat_tileset(tiles, {{"p.pnts", grid_tile(100, 0.0f, {255, 0, 0})}});
  const fs::path png = dir / "away.png";
  auto r = test::run_stipple(
      fmt::format("render {} -o {} --width 64 --height 48 --camera 0,0,1000,0,0,2000",
                  (tiles / "tileset.json").string(), png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("no tile with points is in view"), std::string::npos) << r.output;
  const gpu::Image image = gpu::read_png(png);
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i) {
    ASSERT_EQ(image.rgba[i * 4 + 3], 255) << i;
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(image.rgba[i * 4 + k], kBackground[k], 1) << i;
  }
}

// Item 7: "nothing to render: the input holds no points" named no file (the README promises
// that errors name the file); render and tile name every input now.
TEST(OtherWriters, NoPointsErrorNamesTheFiles) {
  const fs::path dir = temp_dir();
  test::LasFile f;  // a valid header, no points
  const fs::path a = dir / "empty-a.las", b = dir / "empty-b.las";
  test::write_las(a, f);
  test::write_las(b, f);
  const fs::path png = dir / "out.png";
  auto r = test::run_stipple(fmt::format("render {} -o {}", a.string(), png.string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(a.string() + ": nothing to render: the input holds no points"),
            std::string::npos)
      << r.output;
  r = test::run_stipple(fmt::format("render {} {} -o {}", a.string(), b.string(), png.string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(a.string() + ", " + b.string() +
                          ": nothing to render: the inputs hold no points"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(png));
  r = test::run_stipple(
      fmt::format("tile {} --crs EPSG:32633 -o {}", a.string(), (dir / "tiles").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(a.string() + ": nothing to tile"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "tiles" / "tileset.json"));
}

namespace {

// LAS 1.4 format 6 with 3 extra bytes a point, described by `vlrs` Extra Bytes VLRs.
test::LasFile extra_bytes_file(const std::vector<std::vector<uint8_t>>& vlrs) {
  test::LasFile f;
  f.version_minor = 4;
  f.point_format = 6;
  f.extra_bytes_per_point = 3;
  for (const auto& payload : vlrs) f.vlrs.push_back({"LASF_Spec", 4, payload, "Extra Bytes"});
  f.points = test::grid_points(400, 1000.0, 2000.0, 20.0);
  for (size_t i = 0; i < f.points.size(); ++i)
    f.points[i].extra = {uint8_t(i), uint8_t(i >> 8), uint8_t(i % 7)};
  return f;
}

}  // namespace

// Item 5: two Extra Bytes VLRs (a uint16 and a uint8) described one attribute only, and a
// warning that the descriptors cover 1 byte of 3 was printed (twice by render). All such VLRs
// together describe the record now; a header warning is printed once per run.
TEST(OtherWriters, SeveralExtraBytesVlrsDescribeTheRecordTogether) {
  const fs::path dir = temp_dir();
  const fs::path las = dir / "two-vlrs.las";
  test::write_las(las, extra_bytes_file({test::extra_bytes_descriptor(3, "amplitude"),
                                         test::extra_bytes_descriptor(1, "flags")}));
  auto r = test::run_stipple("info " + las.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("extra bytes: amplitude (uint16), flags (uint8)"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  r = test::run_stipple("info --json " + las.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  ASSERT_EQ(j["extra_bytes"].size(), 2u) << r.output;
  EXPECT_EQ(j["extra_bytes"][1]["name"], "flags");
  const fs::path png = dir / "two-vlrs.png";
  r = test::run_stipple(
      fmt::format("render {} -o {} --width 64 --height 48", las.string(), png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;

  // Descriptors that really do not cover the record: said once, though render reads the
  // header several times.
  const fs::path short_las = dir / "short.las";
  test::write_las(short_las, extra_bytes_file({test::extra_bytes_descriptor(3, "amplitude")}));
  r = test::run_stipple(
      fmt::format("render {} -o {} --width 64 --height 48", short_las.string(), png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(occurrences(r.output, "the Extra Bytes VLRs describe 2 bytes but records carry 3"), 1u)
      << r.output;
}

// Item 8: info printed scales with 6 significant digits (0.001 and 0.0010000001 alike), a zero
// offset stored as -0 as "-0.000000", an empty system identifier as "   / Software", and kept
// the spaces some writers pad strings with.
TEST(OtherWriters, InfoPrintsHeaderFieldsExactly) {
  const fs::path dir = temp_dir();
  test::LasFile f;
  f.scale = {0.001, 0.0010000001, 0.01};
  f.offset = {-0.0, 250000.5, 0.0};
  f.system_identifier = "";
  f.generating_software = "Writer 2.1      ";  // padded with spaces, not NULs
  f.vlrs.push_back({"LASF_Projection ", 9999, {1, 2, 3}, "padded user id  "});
  f.points = test::grid_points(16, 1000.0, 2000.0, 10.0);
  f.offset[1] = 0.0;  // the points need an offset they fit with
  const fs::path las = dir / "fields.las";
  test::write_las(las, f);
  auto r = test::run_stipple("info --vlrs " + las.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("  scale:      0.001 0.0010000001 0.01\n"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("  offset:     0 0 0\n"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("-0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  software:   Writer 2.1\n"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("    VLR  LASF_Projection   9999       3 bytes  padded user id\n"),
            std::string::npos)
      << r.output;
  r = test::run_stipple("info --json " + las.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  EXPECT_EQ(j["generating_software"], "Writer 2.1");
  EXPECT_EQ(j["system_identifier"], "");
  EXPECT_EQ(j["scale"][1].get<double>(), 0.0010000001);
  EXPECT_FALSE(std::signbit(j["offset"][0].get<double>()));
  EXPECT_EQ(j["vlrs"][0]["user_id"], "LASF_Projection");
}

namespace {

const char* kUtm33Wkt =
    "PROJCS[\"WGS 84 / UTM zone 33N\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\","
    "6378137,298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],"
    "PROJECTION[\"Transverse_Mercator\"],PARAMETER[\"latitude_of_origin\",0],PARAMETER["
    "\"central_meridian\",15],PARAMETER[\"scale_factor\",0.9996],PARAMETER[\"false_easting\","
    "500000],PARAMETER[\"false_northing\",0],UNIT[\"metre\",1],AUTHORITY[\"EPSG\",\"32633\"]]";

// As some writers put it: the VERTCS nested inside the PROJCS (not valid WKT1; PROJ reads the
// projected part without its id), the PROJCS's own AUTHORITY before it.
const char* kNestedVertcsWkt =
    "PROJCS[\"NAD83(HARN) / New Mexico Central (ftUS)\",GEOGCS[\"NAD83(HARN)\",DATUM["
    "\"NAD83_High_Accuracy_Reference_Network\",SPHEROID[\"GRS 1980\",6378137,298.257222101,"
    "AUTHORITY[\"EPSG\",\"7019\"]],TOWGS84[0,0,0,0,0,0,0],AUTHORITY[\"EPSG\",\"6152\"]],PRIMEM["
    "\"Greenwich\",0,AUTHORITY[\"EPSG\",\"8901\"]],UNIT[\"degree\",0.0174532925199433,AUTHORITY["
    "\"EPSG\",\"9122\"]],AUTHORITY[\"EPSG\",\"4152\"]],PROJECTION[\"Transverse_Mercator\"],"
    "PARAMETER[\"latitude_of_origin\",31],PARAMETER[\"central_meridian\",-106.25],PARAMETER["
    "\"scale_factor\",0.9999],PARAMETER[\"false_easting\",1640416.667],PARAMETER["
    "\"false_northing\",0],UNIT[\"US survey foot\",0.3048006096012192,AUTHORITY[\"EPSG\","
    "\"9003\"]],AXIS[\"X\",EAST],AXIS[\"Y\",NORTH],AUTHORITY[\"EPSG\",\"2903\"],VERTCS[\"North "
    "American Vertical Datum of 1988\",VERT_DATUM[\"North American Vertical Datum 1988\",2005,"
    "AUTHORITY[\"EPSG\",\"5103\"]],UNIT[\"US survey foot\",1.0],AXIS[\"Gravity-related height\","
    "UP],AUTHORITY[\"EPSG\",\"5703\"]]]";

const char* kWgs84Wkt =
    "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],PRIMEM["
    "\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433],AUTHORITY[\"EPSG\",\"4326\"]]";

test::LasVlr wkt_vlr(const std::string& wkt) {
  std::vector<uint8_t> bytes(wkt.begin(), wkt.end());
  bytes.push_back(0);
  return {"LASF_Projection", 2112, bytes, "OGC WKT"};
}

// LAS 1.4 format 6 with the WKT bit set as given, the VLRs given, 16 points near (x, y).
fs::path crs_file(const fs::path& path, bool wkt_bit, std::vector<test::LasVlr> vlrs,
                  double x = 500000.0, double y = 4500000.0) {
  test::LasFile f;
  f.version_minor = 4;
  f.point_format = 6;
  f.global_encoding = wkt_bit ? 16 : 0;
  f.vlrs = std::move(vlrs);
  f.points = test::grid_points(16, x, y, 10.0);
  test::write_las(path, f);
  return path;
}

}  // namespace

// Item 9: CRS labels. With a WKT and GeoTIFF keys the EPSG code came from the keys while the
// name and unit came from the WKT; a blank WKT was a "custom CRS"; a WKT that PROJ reads only in
// part lost its EPSG code; latitudes of millions passed as degrees.
TEST(OtherWriters, CrsLabelsComeFromOneSource) {
  const fs::path dir = temp_dir();
  const test::LasVlr keys = {"LASF_Projection", 34735,
                             test::geokey_directory({{1024, 1}, {3072, 2903}}), "GeoTIFF"};
  // WKT bit set: the WKT (UTM 33N, metres) decides; the keys (New Mexico, US feet) disagree.
  auto r = test::run_stipple(
      "info " + crs_file(dir / "both-bit.las", true, {wkt_vlr(kUtm33Wkt), keys}).string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("CRS:        EPSG:32633 (WGS 84 / UTM zone 33N), unit metre\n"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("the WKT says EPSG:32633 and the GeoTIFF keys EPSG:2903: the WKT is "
                          "used (the header's WKT bit is set)"),
            std::string::npos)
      << r.output;
  // WKT bit clear: the keys decide, name and unit with them.
  r = test::run_stipple(
      "info " + crs_file(dir / "both-nobit.las", false, {wkt_vlr(kUtm33Wkt), keys}).string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("CRS:        EPSG:2903 (NAD83(HARN) / New Mexico Central (ftUS)), unit "
                          "US survey foot (from the GeoTIFF keys)"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("the GeoTIFF keys are used (the header's WKT bit is clear)"),
            std::string::npos)
      << r.output;

  // A WKT VLR of blanks: no CRS, said so.
  r = test::run_stipple("info " + crs_file(dir / "blank.las", true, {wkt_vlr("  \n ")}).string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("CRS:        none (the WKT VLR holds no text)\n"), std::string::npos)
      << r.output;

  // The nested VERTCS: the PROJCS's AUTHORITY, the VERTCS's, the unit of the PROJCS.
  r = test::run_stipple("info " +
                        crs_file(dir / "nested.las", true, {wkt_vlr(kNestedVertcsWkt)}).string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("CRS:        EPSG:2903 (NAD83(HARN) / New Mexico Central (ftUS)) + "
                          "vertical EPSG:5703, unit US survey foot\n"),
            std::string::npos)
      << r.output;

  // Geographic by its WKT, projected by its numbers: info says so, render and tile refuse it.
  const fs::path lonlat = crs_file(dir / "not-degrees.las", true, {wkt_vlr(kWgs84Wkt)});
  r = test::run_stipple("info " + lonlat.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string problem =
      lonlat.string() + ": the CRS (EPSG:4326) is geographic, but the coordinates reach latitude";
  EXPECT_NE(r.output.find("problem:    " + problem), std::string::npos) << r.output;
  r = test::run_stipple(fmt::format("render {} -o {}", lonlat.string(), (dir / "x.png").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("error: " + problem), std::string::npos) << r.output;
  r = test::run_stipple(fmt::format("tile {} -o {}", lonlat.string(), (dir / "t").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("error: " + problem), std::string::npos) << r.output;
  // Real degrees pass.
  r = test::run_stipple(
      "info " + crs_file(dir / "degrees.las", true, {wkt_vlr(kWgs84Wkt)}, 15.5, 47.25).string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("problem"), std::string::npos) << r.output;
}

// Item 4: RGB fields present but all 0 (some writers fill them so): `auto` took RGB and drew a
// black cloud on the dark background. A sample of one colour is taken as no colour now, said
// so, and auto falls back to elevation; --color rgb still shows it.
TEST(OtherWriters, UniformRgbIsNotTakenForColour) {
  const fs::path dir = temp_dir();
  for (uint16_t value : {uint16_t(0), uint16_t(65535)}) {
    SCOPED_TRACE(value);
    test::LasFile f;
    f.points = test::grid_points(2500, 1000.0, 2000.0, 50.0);
    for (auto& p : f.points) p.r = p.g = p.b = value;
    const fs::path las = dir / fmt::format("rgb-{}.las", value);
    test::write_las(las, f);
    const fs::path png = dir / fmt::format("rgb-{}.png", value);
    auto r = test::run_stipple(
        fmt::format("render {} -o {} --width 160 --height 100", las.string(), png.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(fmt::format("the RGB of the first 2500 points is {0},{0},{0} for "
                                        "every one: --color auto colours by elevation",
                                        value)),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("(elevation colour"), std::string::npos) << r.output;
    // The elevation ramp: coloured, neither black nor grey.
    const auto ramp = test::coverage_stats(gpu::read_png(png), kBackground);
    EXPECT_GT(ramp.coverage, 0.2);
    const double spread = std::max({ramp.mean[0], ramp.mean[1], ramp.mean[2]}) -
                          std::min({ramp.mean[0], ramp.mean[1], ramp.mean[2]});
    EXPECT_GT(spread, 20.0);

    r = test::run_stipple(fmt::format("render {} -o {} --width 160 --height 100 --color rgb",
                                      las.string(), png.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("(rgb colour"), std::string::npos) << r.output;
    const auto rgb = test::coverage_stats(gpu::read_png(png), kBackground);
    EXPECT_NEAR(rgb.mean[0], rgb.mean[2], 2.0);  // grey: black or white, shaded by EDL

    r = test::run_stipple("info " + las.string());
    EXPECT_NE(r.output.find(
                  fmt::format("RGB (one colour, {0},{0},{0}, in the first 2500 points)", value)),
              std::string::npos)
        << r.output;
  }
}

// Item 3: the summary line named "elevation colour" for every tileset while the image showed
// RGB. It names the mode the tiles were drawn in, on both renderers.
TEST(OtherWriters, TilesetSummaryNamesTheColourDrawn) {
  const fs::path dir = temp_dir();
  const fs::path rgb = dir / "rgb", plain = dir / "plain";
  write_flat_tileset(rgb, {{"a.pnts", grid_tile(100, 0.0f, {255, 0, 0})},
                           {"b.pnts", grid_tile(100, 20.0f, {255, 0, 0})}});
  // No colour: positions only.
  std::vector<float> pos;
  for (int i = 0; i < 100; ++i) pos.insert(pos.end(), {float(i % 10), float(i / 10), float(i % 3)});
  test::Bytes bin;
  test::append(bin, pos);
  write_flat_tileset(
      plain, {{"c.pnts",
               test::make_pnts({{"POINTS_LENGTH", 100}, {"POSITION", {{"byteOffset", 0}}}}, bin)}});
  for (const char* renderer : {"billboard", "compute"}) {
    SCOPED_TRACE(renderer);
    const fs::path png = dir / (std::string(renderer) + ".png");
    auto r =
        test::run_stipple(fmt::format("render {} -o {} --width 160 --height 100 --renderer {}",
                                      (rgb / "tileset.json").string(), png.string(), renderer));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("rendered 200 points (rgb colour"), std::string::npos) << r.output;
    const auto stats = test::coverage_stats(gpu::read_png(png), kBackground);
    EXPECT_GT(stats.mean[0], 3.0 * stats.mean[1]);  // red, as the summary says
    r = test::run_stipple(fmt::format("render {} -o {} --width 160 --height 100 --renderer {}",
                                      (plain / "tileset.json").string(), png.string(), renderer));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("rendered 100 points (elevation colour"), std::string::npos)
        << r.output;
  }
}

namespace {

// A pnts tile of 100 points on a 10 x 10 grid from (x0, 0, 0), coloured per point by `rgba`
// (RGBA semantic) or by one CONSTANT_RGBA.
test::Bytes rgba_tile(float x0, const std::function<std::array<uint8_t, 4>(int)>& rgba,
                      bool constant) {
  std::vector<float> pos;
  test::Bytes colours;
  for (int i = 0; i < 100; ++i) {
    pos.insert(pos.end(), {x0 + float(i % 10), float(i / 10), 0.0f});
    const auto c = rgba(i);
    colours.insert(colours.end(), c.begin(), c.end());
  }
  test::Bytes bin;
  test::append(bin, pos);
  nlohmann::json ft = {{"POINTS_LENGTH", 100}, {"POSITION", {{"byteOffset", 0}}}};
  if (constant) {
    const auto c = rgba(0);
    ft["CONSTANT_RGBA"] = {c[0], c[1], c[2], c[3]};
  } else {
    ft["RGBA"] = {{"byteOffset", bin.size()}};
    bin.insert(bin.end(), colours.begin(), colours.end());
  }
  return test::make_pnts(ft, bin);
}

// A glb of one POINTS primitive (100 points from (x0, 0, 0)) with COLOR_0 VEC4 `rgba(i)` (floats)
// and a material of the given alphaMode (none: glTF's default, OPAQUE).
test::Bytes rgba_glb(float x0, const std::function<std::array<float, 4>(int)>& rgba,
                     const std::string& alpha_mode) {
  std::vector<float> pos, col;
  for (int i = 0; i < 100; ++i) {
    // glTF is Y-up: the grid lies in x/-z (the tile's x/y).
    pos.insert(pos.end(), {x0 + float(i % 10), 0.0f, -float(i / 10)});
    const auto c = rgba(i);
    col.insert(col.end(), c.begin(), c.end());
  }
  test::Bytes bin;
  test::append(bin, pos);
  test::append(bin, col);
  nlohmann::json prim = {{"attributes", {{"POSITION", 0}, {"COLOR_0", 1}}}, {"mode", 0}};
  nlohmann::json j = {
      {"asset", {{"version", "2.0"}}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews",
       {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 1200}},
        {{"buffer", 0}, {"byteOffset", 1200}, {"byteLength", 1600}}}},
      {"accessors",
       {{{"bufferView", 0},
         {"componentType", 5126},
         {"count", 100},
         {"type", "VEC3"},
         {"min", {x0, 0, -9}},
         {"max", {x0 + 9, 0, 0}}},
        {{"bufferView", 1}, {"componentType", 5126}, {"count", 100}, {"type", "VEC4"}}}},
      {"nodes", {{{"mesh", 0}}}},
      {"scenes", {{{"nodes", {0}}}}},
      {"scene", 0}};
  if (!alpha_mode.empty()) {
    j["materials"] = {{{"alphaMode", alpha_mode}}};
    prim["material"] = 0;
  }
  j["meshes"] = {{{"primitives", {prim}}}};
  return test::make_glb(j, bin);
}

test::Bytes rgba_glb(float x0, std::array<float, 4> rgba, const std::string& alpha_mode) {
  return rgba_glb(
      x0, [rgba](int) { return rgba; }, alpha_mode);
}

// A pnts tile of two 20 x 20 layers over 10 x 10 m (0.5 m apart), 3 m apart in height, each
// point coloured by `rgba(top, x)` (RGBA semantic).
test::Bytes layered_tile(const std::function<std::array<uint8_t, 4>(bool, float)>& rgba) {
  std::vector<float> pos;
  test::Bytes colours;
  for (int layer = 0; layer < 2; ++layer)
    for (int i = 0; i < 400; ++i) {
      const float x = 0.25f + 0.5f * float(i % 20), y = 0.25f + 0.5f * float(i / 20);
      pos.insert(pos.end(), {x, y, layer == 1 ? 3.0f : 0.0f});
      const auto c = rgba(layer == 1, x);
      colours.insert(colours.end(), c.begin(), c.end());
    }
  test::Bytes bin;
  test::append(bin, pos);
  nlohmann::json ft = {{"POINTS_LENGTH", 800},
                       {"POSITION", {{"byteOffset", 0}}},
                       {"RGBA", {{"byteOffset", bin.size()}}}};
  bin.insert(bin.end(), colours.begin(), colours.end());
  return test::make_pnts(ft, bin);
}

struct Rendered {
  test::CommandResult run;
  gpu::Image image;
};

// `stipple render` of dir/tileset.json at 160 x 100 with the renderer and backend given (and
// `env`, variables to set first).
Rendered render_tileset(const fs::path& dir, const std::string& name, const std::string& backend,
                        const std::string& renderer, const std::string& extra = "",
                        const std::string& env = "") {
  const fs::path png = dir / (name + ".png");
  Rendered r;
  r.run = test::run_command(fmt::format(
      "{} {} render {} -o {} --width 160 --height 100 --backend {} --renderer {} {}", env,
      STIPPLE_BINARY, (dir / "tileset.json").string(), png.string(), backend, renderer, extra));
  if (r.run.exit_code == 0) r.image = gpu::read_png(png);
  return r;
}

// Whether channel value v lies between the background's and the colour's (inclusive, with a
// tolerance of `tol`).
bool between(int v, int background, int colour, int tol) {
  return v >= std::min(background, colour) - tol && v <= std::max(background, colour) + tol;
}

// Covered pixels (differing from the background) whose colour is not between the background
// and `rgb` in some channel.
size_t outside(const gpu::Image& image, std::array<uint8_t, 3> rgb, int tol) {
  size_t n = 0;
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i) {
    const uint8_t* p = &image.rgba[i * 4];
    bool bg = true, in = true;
    for (int k = 0; k < 3; ++k) {
      bg = bg && std::abs(p[k] - kBackground[k]) <= 2;
      in = in && between(p[k], kBackground[k], rgb[k], tol);
    }
    n += !bg && !in;
  }
  return n;
}

}  // namespace

// Issue 44 (item 10 before it): alpha was a threshold at 0.5, so a tile whose points were all
// under half opacity (Cesium's translucent samples: alpha 0.2) rendered nothing and failed. It
// is blended now in the RGB mode, on both renderers and both WebGPU implementations: each
// property's tile renders, covers about what the same tile at full opacity covers, and every
// covered pixel lies between the background and the points' colour, nearer the background.
class TranslucentTiles : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {};

TEST_P(TranslucentTiles, EveryAlphaPropertyIsBlended) {
  const auto& [backend, renderer] = GetParam();
  const std::array<uint8_t, 3> rgb = {240, 120, 30};
  struct Case {
    std::string name;
    std::function<test::Bytes(uint8_t alpha)> tile;  // the tile at this alpha
    std::string file;
  };
  const std::vector<Case> cases = {
      {"rgba",
       [&](uint8_t a) {
         return rgba_tile(
             0.0f,
             [&](int) {
               return std::array<uint8_t, 4>{rgb[0], rgb[1], rgb[2], a};
             },
             false);
       },
       "t.pnts"},
      {"constant",
       [&](uint8_t a) {
         return rgba_tile(
             0.0f,
             [&](int) {
               return std::array<uint8_t, 4>{rgb[0], rgb[1], rgb[2], a};
             },
             true);
       },
       "t.pnts"},
      // glb colours are linear: these floats are the sRGB bytes above.
      {"glb-blend",
       [&](uint8_t a) {
         return rgba_glb(0.0f, {0.8714f, 0.1878f, 0.0130f, float(a) / 255.0f}, "BLEND");
       },
       "t.glb"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path dir = temp_dir() / c.name;
    const fs::path opaque_dir = dir / "opaque", translucent_dir = dir / "translucent";
    write_flat_tileset(opaque_dir, {{c.file, c.tile(255)}});
    write_flat_tileset(translucent_dir, {{c.file, c.tile(51)}});  // alpha 0.2
    const Rendered opaque = render_tileset(opaque_dir, "o", backend, renderer);
    const Rendered translucent = render_tileset(translucent_dir, "t", backend, renderer);
    ASSERT_EQ(opaque.run.exit_code, 0) << opaque.run.output;
    ASSERT_EQ(translucent.run.exit_code, 0) << translucent.run.output;
    EXPECT_NE(translucent.run.output.find("rendered 100 points"), std::string::npos)
        << translucent.run.output;
    const auto o = test::coverage_stats(opaque.image, kBackground);
    const auto t = test::coverage_stats(translucent.image, kBackground);
    ASSERT_GT(o.covered, 200u);
    // The same discs: coverage within 15% of the opaque render's.
    EXPECT_NEAR(t.coverage, o.coverage, 0.15 * o.coverage);
    // Colours between the background and the points' (4 levels of rounding), and nearer the
    // background: one layer at 0.2 is a fifth of the way, overlapping discs a little more.
    EXPECT_EQ(outside(translucent.image, rgb, 4), 0u);
    EXPECT_GT(t.mean[0], kBackground[0] + 0.1 * (rgb[0] - kBackground[0]));
    EXPECT_LT(t.mean[0], kBackground[0] + 0.7 * (rgb[0] - kBackground[0]));
    EXPECT_GT(o.mean[0], kBackground[0] + 0.7 * (rgb[0] - kBackground[0]));
  }
}

// Colour modes other than RGB replace the colour and draw every point opaque: the translucent
// tile's image is the opaque tile's, pixel for pixel.
TEST_P(TranslucentTiles, OtherColourModesDrawOpaque) {
  const auto& [backend, renderer] = GetParam();
  const fs::path dir = temp_dir();
  auto tile = [](uint8_t a) {
    return rgba_tile(
        0.0f,
        [a](int i) {
          return std::array<uint8_t, 4>{200, 50, uint8_t(i), a};
        },
        false);
  };
  write_flat_tileset(dir / "opaque", {{"t.pnts", tile(255)}});
  write_flat_tileset(dir / "translucent", {{"t.pnts", tile(51)}});
  const Rendered opaque =
      render_tileset(dir / "opaque", "o", backend, renderer, "--color elevation");
  const Rendered translucent =
      render_tileset(dir / "translucent", "t", backend, renderer, "--color elevation");
  ASSERT_EQ(opaque.run.exit_code, 0) << opaque.run.output;
  ASSERT_EQ(translucent.run.exit_code, 0) << translucent.run.output;
  EXPECT_GT(test::coverage_stats(opaque.image, kBackground).coverage, 0.02);
  EXPECT_EQ(test::differing_fraction(opaque.image, translucent.image, 0), 0.0);
}

// Depth: opaque points in front hide translucent ones behind them; translucent points in front
// tint the opaque ones behind. Seen from above: over the left half the top layer is opaque blue
// and the bottom one translucent red, over the right half the top layer translucent red and the
// bottom one opaque blue.
TEST_P(TranslucentTiles, OpaqueInFrontHidesTranslucentInFrontTints) {
  const auto& [backend, renderer] = GetParam();
  const fs::path dir = temp_dir();
  const std::array<uint8_t, 4> blue = {30, 60, 250, 255}, red = {250, 20, 20, 102};
  write_flat_tileset(dir, {{"layers.pnts", layered_tile([&](bool top, float x) {
                              const bool left = x < 5.0f;
                              return top == left ? blue : red;
                            })}});
  // Also the variants: billboards without splat blending (and so without a resolve pass);
  // the compute rasterizer with HQS and with its display as a compute pass.
  std::vector<std::pair<std::string, std::string>> variants = {{"", ""}};
  if (renderer == "billboard") variants.push_back({"--splat naive", ""});
  if (renderer == "compute") {
    variants.push_back({"--hqs", ""});
    variants.push_back({"", "STIPPLE_DISPLAY_PASS=compute"});
  }
  for (const auto& [extra, env] : variants) {
    SCOPED_TRACE(extra + env);
    const Rendered r =
        render_tileset(dir, "layers", backend, renderer,
                       "--no-edl --azimuth 0 --elevation 89 --point-size 6 " + extra, env);
    ASSERT_EQ(r.run.exit_code, 0) << r.run.output;
    const Covered c = covered(r.image);
    ASSERT_GT(c.pixels, 1000u);
    // Mean colour of the covered pixels in columns [x0, x1).
    auto mean = [&r, &c](uint32_t x0, uint32_t x1) {
      std::array<double, 3> sum{0, 0, 0};
      size_t n = 0;
      for (uint32_t y = c.y0; y <= c.y1; ++y)
        for (uint32_t x = x0; x < x1; ++x) {
          const uint8_t* p = &r.image.rgba[(size_t(y) * r.image.width + x) * 4];
          bool bg = true;
          for (int k = 0; k < 3; ++k) bg = bg && std::abs(p[k] - kBackground[k]) <= 2;
          if (bg) continue;
          for (int k = 0; k < 3; ++k) sum[k] += p[k];
          ++n;
        }
      for (double& v : sum) v /= double(std::max<size_t>(n, 1));
      return sum;
    };
    // The left and right thirds of the covered box.
    const uint32_t third = (c.x1 - c.x0) / 3;
    const auto left = mean(c.x0, c.x0 + third), right = mean(c.x1 - third, c.x1 + 1);
    // Left: the opaque blue hides the red behind it.
    EXPECT_LT(left[0], 45.0);
    EXPECT_GT(left[2], 230.0);
    // Right: the red (alpha 0.4, overlapping discs a little more) over the blue: both show,
    // neither fully.
    EXPECT_GT(right[0], 30.0 + 0.2 * (250 - 30));
    EXPECT_LT(right[0], 30.0 + 0.75 * (250 - 30));
    EXPECT_LT(right[2], 250.0 - 0.2 * (250 - 20));
    EXPECT_GT(right[2], 250.0 - 0.75 * (250 - 20));
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, TranslucentTiles,
                         ::testing::Combine(::testing::Values("dawn", "wgpu"),
                                            ::testing::Values("billboard", "compute")),
                         [](const auto& info) {
                           return std::get<0>(info.param) + "_" + std::get<1>(info.param);
                         });

// A glb's COLOR_0 alpha counts only under BLEND (blended) or MASK (its cutoff: drawn opaque or
// not at all); glTF ignores it under OPAQUE. Fully transparent pnts points are not drawn, and
// the output says so once.
TEST(OtherWriters, MaskKeepsItsCutoffOpaqueIgnoresAlpha) {
  const fs::path dir = temp_dir();
  auto halves = [](int i) -> std::array<uint8_t, 4> {
    return i % 10 < 5 ? std::array<uint8_t, 4>{255, 0, 0, 0}     // red, transparent
                      : std::array<uint8_t, 4>{0, 255, 0, 255};  // green, opaque
  };
  write_flat_tileset(dir, {{"halves.pnts", rgba_tile(0.0f, halves, false)},
                           // Under MASK (cutoff 0.5): red at 0.2 cut, blue at 0.8 opaque.
                           {"mask.glb", rgba_glb(
                                            20.0f,
                                            [](int i) -> std::array<float, 4> {
                                              return i % 10 < 5
                                                         ? std::array<float, 4>{1, 0, 0, 0.2f}
                                                         : std::array<float, 4>{0, 0, 1, 0.8f};
                                            },
                                            "MASK")},
                           {"magenta.glb", rgba_glb(40.0f, {1, 0, 1, 0.2f}, "")}});
  const fs::path png = dir / "alpha.png";
  auto r = test::run_stipple(fmt::format("render {} -o {} --width 320 --height 120 --no-edl",
                                         (dir / "tileset.json").string(), png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Drawn: 50 green, 50 blue, 100 magenta (OPAQUE ignores alpha).
  EXPECT_NE(r.output.find("rendered 200 points"), std::string::npos) << r.output;
  EXPECT_EQ(occurrences(r.output, "alpha 0: fully transparent points are not drawn"), 1u)
      << r.output;
  const gpu::Image image = gpu::read_png(png);
  size_t red = 0, green = 0, blue = 0, magenta = 0;
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i) {
    const int p[3] = {image.rgba[i * 4], image.rgba[i * 4 + 1], image.rgba[i * 4 + 2]};
    red += p[0] > 60 && p[1] < 60 && p[2] < 60;
    // Opaque: the full colour, not blended with the background.
    green += p[0] < 30 && p[1] > 240 && p[2] < 40;
    blue += p[0] < 30 && p[1] < 30 && p[2] > 240;
    magenta += p[0] > 240 && p[1] < 30 && p[2] > 240;
  }
  EXPECT_GT(green, 50u);
  EXPECT_GT(blue, 50u);
  EXPECT_GT(magenta, 50u);
  EXPECT_EQ(red, 0u);
}

namespace {

// n^3 points filling a cube of `size` metres from (x0, y0, z0), one colour.
std::vector<test::LasPoint> cube_points(int n, double x0, double y0, double z0, double size) {
  std::vector<test::LasPoint> out;
  for (int i = 0; i < n * n * n; ++i) {
    test::LasPoint p;
    p.x = x0 + size * (i % n) / (n - 1);
    p.y = y0 + size * (i / n % n) / (n - 1);
    p.z = z0 + size * (i / (n * n)) / (n - 1);
    p.r = 65535, p.g = 40000;
    out.push_back(p);
  }
  return out;
}

bool touches_border(const Covered& c, const gpu::Image& image) {
  return c.x0 == 0 || c.y0 == 0 || c.x1 + 1 >= image.width || c.y1 + 1 >= image.height;
}

// How much of the image the data spans along its binding dimension: 0.9 when the point centres
// touch the 5% margins, a little more with the points' own size.
double fill(const Covered& c, const gpu::Image& image) {
  return std::max(double(c.x1 - c.x0 + 1) / image.width, double(c.y1 - c.y0 + 1) / image.height);
}

}  // namespace

// Item 11: the default framing fitted the bounding box's corners, which left data small (a
// 1000-point cube tileset whose root box is loose filled a quarter of the image height; autzen,
// whose box holds air above the ground, about half) and let some small clouds touch the image
// edge. It fits the points' projected extent now, with a margin, for LAS and tilesets alike.
// Tolerances: the data spans over 80% of the image along its binding dimension (0.9 exactly
// framed; the old framing gave about 25% for the tileset), no covered pixel lies on the border
// row or column, and the LAS and tileset renders of the same points are centred within 4 px.
TEST(OtherWriters, FramingFillsTheImageWithAMargin) {
  const fs::path dir = temp_dir();
  const uint32_t w = 160, h = 100;
  // A 10 m cube of 1000 points as LAS...
  test::LasFile f;
  f.scale = {0.001, 0.001, 0.001};
  f.points = cube_points(10, 500000.0, 5000000.0, 100.0, 10.0);
  const fs::path las = dir / "cube.las";
  test::write_las(las, f);
  auto r = test::run_stipple(fmt::format("render {} -o {} --width {} --height {}", las.string(),
                                         (dir / "las.png").string(), w, h));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const gpu::Image las_image = gpu::read_png(dir / "las.png");
  const Covered las_cover = covered(las_image);
  EXPECT_FALSE(touches_border(las_cover, las_image));
  EXPECT_GT(fill(las_cover, las_image), 0.8);

  // ... and as a tileset whose boxes are four times the data (as octree roots are).
  std::vector<float> pos;
  test::Bytes rgb;
  for (const auto& p : f.points) {
    pos.insert(pos.end(), {float(p.x - 500000.0), float(p.y - 5000000.0), float(p.z - 100.0)});
    rgb.insert(rgb.end(), {255, 156, 0});
  }
  test::Bytes bin;
  test::append(bin, pos);
  const size_t rgb_at = bin.size();
  bin.insert(bin.end(), rgb.begin(), rgb.end());
  test::write_file(dir / "tiles" / "cube.pnts", test::make_pnts({{"POINTS_LENGTH", pos.size() / 3},
                                                                 {"POSITION", {{"byteOffset", 0}}},
                                                                 {"RGB", {{"byteOffset", rgb_at}}}},
                                                                bin));
  const nlohmann::json loose = {5, 5, 5, 20, 0, 0, 0, 20, 0, 0, 0, 20};
  test::write_json(dir / "tiles" / "tileset.json", {{"asset", {{"version", "1.0"}}},
                                                    {"geometricError", 100},
                                                    {"root",
                                                     {{"boundingVolume", {{"box", loose}}},
                                                      {"geometricError", 0},
                                                      {"refine", "ADD"},
                                                      {"content", {{"uri", "cube.pnts"}}}}}});
  r = test::run_stipple(fmt::format("render {} -o {} --width {} --height {}",
                                    (dir / "tiles" / "tileset.json").string(),
                                    (dir / "tiles.png").string(), w, h));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const gpu::Image tiles_image = gpu::read_png(dir / "tiles.png");
  const Covered tiles_cover = covered(tiles_image);
  EXPECT_FALSE(touches_border(tiles_cover, tiles_image));
  EXPECT_GT(fill(tiles_cover, tiles_image), 0.8);
  // The same points, the same framing (within the points' own size).
  EXPECT_NEAR(tiles_cover.cx(), las_cover.cx(), 4.0);
  EXPECT_NEAR(tiles_cover.cy(), las_cover.cy(), 4.0);

  // A small cloud in a small image: big points stay inside the margin.
  test::LasFile small;
  small.points = test::grid_points(9, 1000.0, 2000.0, 2.0);
  test::write_las(dir / "small.las", small);
  r = test::run_stipple(fmt::format("render {} -o {} --width 48 --height 32 --point-size 12",
                                    (dir / "small.las").string(), (dir / "small.png").string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const gpu::Image small_image = gpu::read_png(dir / "small.png");
  EXPECT_FALSE(touches_border(covered(small_image), small_image));
}

// autzen: its box holds the air above the trees, and its data filled about 60% of the image; it
// spans over 80% now (same tolerance as above), off the border.
TEST(OtherWriters, AutzenFillsTheImage) {
  STIPPLE_REQUIRE_DATA(path, "las/autzen_trim.las");
  const fs::path png = temp_dir() / "autzen.png";
  auto r = test::run_stipple(
      fmt::format("render {} -o {} --width 320 --height 180", path.string(), png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const gpu::Image image = gpu::read_png(png);
  const Covered c = covered(image);
  EXPECT_FALSE(touches_border(c, image));
  EXPECT_GT(fill(c, image), 0.8);
}
