// `stipple clip` and `stipple profile` against an independent reader: tests/tools/check_clip.py
// and check_profile.py select the same points with laspy + numpy and compare counts, records,
// headers, CRS and CSV rows. Bad input: clear errors, non-zero exits, no output left behind.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "copc_fixture.hpp"
#include "stipple/io/las.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir() {
  const fs::path dir = fs::temp_directory_path() /
                       fmt::format("stipple-clip-{}-{}", ::getpid(),
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// Runs check_clip.py on a spec; the reference selection must match the output exactly.
void expect_matches_reference(const fs::path& dir, const std::string& spec_json) {
  const std::string py = test::copc_python();
  const fs::path spec = dir / "spec.json";
  write_text(spec, spec_json);
  const auto r = test::run_command(
      fmt::format("{} {}/tests/tools/check_clip.py {}", py, STIPPLE_SOURCE_DIR, spec.string()));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"ok\": true"), std::string::npos) << r.output;
}

// Nothing but the expected files in `dir` (no partial output, no temporaries).
size_t files_in(const fs::path& dir) {
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.is_regular_file();
  return n;
}

}  // namespace

TEST(Clip, AutzenBoxAndGroundMatchLaspy) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  STIPPLE_REQUIRE_COPC_WRITER();
  const fs::path dir = temp_dir();
  const std::string box = "636500,849000,0,637000,851000,2000";
  for (const char* name : {"out.las", "out.laz"}) {
    const auto r = test::run_stipple(fmt::format("clip {} -o {} --box {} --classes 2", las.string(),
                                                 (dir / name).string(), box));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    // The reference count for this box and class (laspy): the command says what it kept.
    EXPECT_NE(r.output.find("kept 9822 of 110000 points"), std::string::npos) << r.output;
    expect_matches_reference(
        dir, fmt::format(R"({{"inputs": ["{}"], "output": "{}", "boxes": [[{}]], "classes": [2]}})",
                         las.string(), (dir / name).string(), box));
  }
  // Read back by our own reader too: LAS 1.4, the input's format and CRS.
  io::LasReader out(dir / "out.las");
  EXPECT_EQ(out.header().version_minor, 4);
  EXPECT_EQ(out.header().point_format, 3);
  EXPECT_EQ(out.header().point_count, 9822u);
  EXPECT_EQ(out.header().crs.wkt, io::read_las_header(las).crs.wkt);
  fs::remove_all(dir);
}

TEST(Clip, RotatedBoxReturnsIntensityAndTimeMatchLaspy) {
  STIPPLE_REQUIRE_DATA(laz, "laz/autzen_trim.laz");
  STIPPLE_REQUIRE_COPC_WRITER();
  const fs::path dir = temp_dir();
  const fs::path out = dir / "out.las";
  const std::string box = "636300,849000,300,636900,849400,600,30";
  const auto r = test::run_stipple(
      fmt::format("clip {} -o {} --box {} --returns first,intermediate --intensity-range 20,200 "
                  "--gps-time-range 245381,245384.5",
                  laz.string(), out.string(), box));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  expect_matches_reference(dir, fmt::format(R"({{"inputs": ["{}"], "output": "{}", "boxes": [[{}]],
                           "returns": ["first", "intermediate"], "intensity": [20, 200],
                           "gps": [245381, 245384.5]}})",
                                            laz.string(), out.string(), box));
  fs::remove_all(dir);
}

TEST(Clip, PolygonWithHoleAndOutsideMatchLaspy) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  STIPPLE_REQUIRE_COPC_WRITER();
  const fs::path dir = temp_dir();
  const std::string outer = "[636100,848950],[637100,849000],[636600,849480],[636100,848950]";
  const std::string hole = "[636400,849050],[636800,849050],[636600,849300],[636400,849050]";
  write_text(dir / "area.geojson",
             fmt::format(R"({{"type": "FeatureCollection", "features": [{{"type": "Feature",
                 "properties": {{}}, "geometry": {{"type": "Polygon",
                 "coordinates": [[{}], [{}]]}}}}]}})",
                         outer, hole));
  for (const bool outside : {false, true}) {
    const fs::path out = dir / (outside ? "outside.las" : "inside.las");
    const auto r =
        test::run_stipple(fmt::format("clip {} -o {} --polygon {} {}", las.string(), out.string(),
                                      (dir / "area.geojson").string(), outside ? "--outside" : ""));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_matches_reference(
        dir, fmt::format(R"({{"inputs": ["{}"], "output": "{}", "polygons": [[{}], [{}]],
                             "outside": {}}})",
                         las.string(), out.string(), outer, hole, outside ? "true" : "false"));
  }
  // Inside and outside split the file.
  EXPECT_EQ(io::read_las_header(dir / "inside.las").point_count +
                io::read_las_header(dir / "outside.las").point_count,
            110000u);
  fs::remove_all(dir);
}

TEST(Clip, CopcInputMatchesLaspy) {
  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  STIPPLE_REQUIRE_COPC_WRITER();
  const fs::path dir = temp_dir();
  const fs::path out = dir / "out.laz";
  const std::string box = "515370,4918350,2300,515390,4918370,2400";
  const auto r = test::run_stipple(
      fmt::format("clip {} -o {} --box {} --returns last", copc.string(), out.string(), box));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  expect_matches_reference(dir, fmt::format(R"({{"inputs": ["{}"], "output": "{}", "boxes": [[{}]],
                           "returns": ["last"]}})",
                                            copc.string(), out.string(), box));
  // A clip is not a COPC file: the hierarchy and COPC info are not carried over.
  EXPECT_FALSE(io::read_las_header(out).copc);
  fs::remove_all(dir);
}

// Extra bytes, a user VLR and an EVLR survive, as do several inputs into one file.
TEST(Clip, ExtraBytesVlrsAndEvlrsAreKept) {
  STIPPLE_REQUIRE_COPC_WRITER();
  const fs::path dir = temp_dir();
  io::LasWriteOptions o;
  o.point_format = 8;
  o.scale = glm::dvec3(0.01);
  o.wkt = "LOCAL_CS[\"test\"]";
  io::ExtraBytesDescriptor height;
  height.data_type = 9;  // float
  height.name = "height above ground";
  o.extra_bytes = {height};
  o.vlrs.push_back({"stipple-test", 7, "user record", {1, 2, 3, 4}});
  o.vlrs.back().data_size = 4;
  o.evlrs.push_back({"stipple-test", 8, "an EVLR", std::vector<uint8_t>(70000, 9)});
  o.evlrs.back().data_size = 70000;
  o.global_encoding = 1;  // adjusted standard GPS time
  for (int file = 0; file < 2; ++file) {
    io::LasWriter writer(dir / fmt::format("in{}.las", file), o);
    io::PointBatch b;
    b.extra_bytes_per_point = 4;
    for (int i = 0; i < 1000; ++i) {
      b.positions.emplace_back(file * 100 + i * 0.1, i * 0.05, i % 17);
      b.intensity.push_back(uint16_t(i));
      b.classification.push_back(uint8_t(i % 7));
      b.return_number.push_back(uint8_t(1 + i % 3));
      b.number_of_returns.push_back(3);
      b.flags.push_back(uint8_t(i & 0xff));
      b.scan_angle.push_back(float(i % 30) - 15.0f);
      b.user_data.push_back(uint8_t(i));
      b.point_source_id.push_back(uint16_t(file + 7));
      b.gps_time.push_back(1e8 + i);
      b.rgb.emplace_back(i, 2 * i, 3 * i);
      b.nir.push_back(uint16_t(4 * i));
      const float h = float(i) * 0.25f;
      const auto* bytes = reinterpret_cast<const uint8_t*>(&h);
      b.extra_bytes.insert(b.extra_bytes.end(), bytes, bytes + 4);
    }
    writer.write(b);
    writer.close();
  }
  const fs::path out = dir / "out.laz";
  const auto r = test::run_stipple(fmt::format("clip {}/in0.las {}/in1.las -o {} --classes 1-4",
                                               dir.string(), dir.string(), out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  expect_matches_reference(
      dir, fmt::format(R"({{"inputs": ["{0}/in0.las", "{0}/in1.las"], "output": "{1}",
                           "classes": [1, 2, 3, 4]}})",
                       dir.string(), out.string()));
  const io::LasHeader h = io::read_las_header(out);
  EXPECT_EQ(h.global_encoding & 1, 1);
  ASSERT_EQ(h.extra_bytes.size(), 1u);
  EXPECT_EQ(h.extra_bytes[0].name, "height above ground");
  ASSERT_EQ(h.evlrs.size(), 1u);
  EXPECT_EQ(h.evlrs[0].data, std::vector<uint8_t>(70000, 9));
  fs::remove_all(dir);
}

// Bad input: each run fails with a message naming the problem and leaves no file behind.
TEST(Clip, BadInputFailsCleanly) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  const fs::path dir = temp_dir();
  write_text(dir / "broken.geojson", R"({"type": "FeatureCollection", "features": [)");
  write_text(dir / "lines.geojson",
             R"({"type": "Feature", "properties": {}, "geometry": {"type": "LineString",
                 "coordinates": [[0, 0], [1, 1]]}})");
  write_text(dir / "open.geojson",
             R"({"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 1]]]})");
  const std::string out = (dir / "out.las").string();
  struct Case {
    std::string args, message;
  };
  const Case cases[] = {
      {"--polygon " + (dir / "broken.geojson").string(), "broken.geojson: not valid GeoJSON"},
      {"--polygon " + (dir / "lines.geojson").string(), "holds no Polygon or MultiPolygon"},
      {"--polygon " + (dir / "open.geojson").string(), "the ring is not closed"},
      {"--polygon " + (dir / "missing.geojson").string(), "missing.geojson: no such file"},
      {"--box 637000,849000,0,636500,851000,2000", "minx 637000 is greater than maxx 636500"},
      {"--box 1,2,3", "expected 'minx,miny,minz,maxx,maxy,maxz[,yaw_degrees]'"},
      {"--classes 2,256", "class 256 is out of range (LAS classes are 0-255)"},
      {"--classes ground", "'ground' is not a class number"},
      {"--returns second", "unknown return kind 'second'"},
      {"--intensity-range 9,3", "min 9 is greater than max 3"},
  };
  for (const Case& c : cases) {
    const auto r = test::run_stipple(fmt::format("clip {} -o {} {}", las.string(), out, c.args));
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
  }
  const auto missing = test::run_stipple(
      fmt::format("clip {} -o {}/no/such/folder/out.las --classes 2", las.string(), dir.string()));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("no/such/folder"), std::string::npos) << missing.output;
  const auto wrong =
      test::run_stipple(fmt::format("clip {} -o {}/out.txt", las.string(), dir.string()));
  EXPECT_NE(wrong.exit_code, 0);
  EXPECT_NE(wrong.output.find("must be a .las or .laz file"), std::string::npos) << wrong.output;
  // Only the three polygon files written above: no output, no temporary.
  EXPECT_EQ(files_in(dir), 3u);
  EXPECT_FALSE(fs::exists(dir / "no"));
  fs::remove_all(dir);
}

TEST(Profile, CsvRowsAreTheCorridorsPoints) {
  STIPPLE_REQUIRE_DATA(laz, "laz/autzen_trim.laz");
  STIPPLE_REQUIRE_COPC_WRITER();
  const fs::path dir = temp_dir();
  const std::string line = "636100,849000,636700,849300,637100,849100";
  const auto r = test::run_stipple(
      fmt::format("profile {} --line {} --width 20 -o {}/p.png --csv {}/p.csv --las {}/p.laz",
                  laz.string(), line, dir.string(), dir.string(), dir.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto check = test::run_command(
      fmt::format("{} {}/tests/tools/check_profile.py {} {}/p.csv 20 {}", test::copc_python(),
                  STIPPLE_SOURCE_DIR, laz.string(), dir.string(), line));
  EXPECT_EQ(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("\"ok\": true"), std::string::npos) << check.output;
  // The LAS holds the same points as the CSV.
  EXPECT_NE(r.output.find("profile: 3975 of 110000 points"), std::string::npos) << r.output;
  EXPECT_EQ(io::read_las_header(dir / "p.laz").point_count, 3975u);
  // The image: the default size, points drawn in the data's colours over the background.
  const gpu::Image image = gpu::read_png(dir / "p.png");
  EXPECT_EQ(image.width, 1600u);
  EXPECT_EQ(image.height, 600u);
  // Pixels that are neither background (18, 20, 26) nor grid (60, 64, 72) are points: their
  // mean colour is the corridor's (the CSV's RGB, 8-bit values), within 20 levels (a pixel shows
  // the nearest of the points falling on it, not their mean).
  double sum[3] = {0, 0, 0}, pixels = 0;
  for (size_t i = 0; i < image.rgba.size(); i += 4) {
    const uint8_t* p = &image.rgba[i];
    if ((p[0] == 18 && p[1] == 20 && p[2] == 26) || (p[0] == 60 && p[1] == 64 && p[2] == 72))
      continue;
    for (int c = 0; c < 3; ++c) sum[c] += p[c];
    ++pixels;
  }
  EXPECT_GT(pixels, 3975.0);  // 3x3 pixels a point, overlapping
  std::ifstream csv(dir / "p.csv");
  std::string row;
  std::getline(csv, row);
  double data[3] = {0, 0, 0}, rows = 0;
  while (std::getline(csv, row)) {
    std::vector<std::string> cells;
    for (size_t at = 0, next; at != std::string::npos;
         at = next == std::string::npos ? next : next + 1)
      cells.push_back(row.substr(at, (next = row.find(',', at)) - at));
    for (int c = 0; c < 3; ++c) data[c] += std::stod(cells[size_t(11 + c)]);
    ++rows;
  }
  ASSERT_EQ(rows, 3975.0);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c] / pixels, data[c] / rows, 20.0) << "channel " << c;
  fs::remove_all(dir);
}

TEST(Profile, BadInputFailsCleanly) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  const fs::path dir = temp_dir();
  const std::string out = fmt::format("-o {0}/p.png --csv {0}/p.csv", dir.string());
  struct Case {
    std::string args, message;
  };
  const Case cases[] = {
      {"--line 1,2,3 --width 5", "expected 'x0,y0,x1,y1[,x2,y2...]'"},
      {"--line 1,2,1,2 --width 5", "the line has no length"},
      {"--line 0,0,10,10 --width 0", "--width 0: must be a positive number"},
      {"--line 0,0,10,x --width 3", "'x' is not a finite number"},
      {"--line 0,0,10,10 --width 3 --classes 300", "class 300 is out of range"},
  };
  for (const Case& c : cases) {
    const auto r = test::run_stipple(fmt::format("profile {} {} {}", las.string(), c.args, out));
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
  }
  const auto missing = test::run_stipple(
      fmt::format("profile {} --line 0,0,10,10 --width 3 -o {}/p.png --csv {}/none/p.csv",
                  las.string(), dir.string(), dir.string()));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("does not exist"), std::string::npos) << missing.output;
  EXPECT_EQ(files_in(dir), 0u);  // not even the image of the run whose CSV folder was missing
  fs::remove_all(dir);
}

// The viewer checks its files before it opens a window.
TEST(ViewFiles, BadScriptsAndMeasurementsFailCleanly) {
  const fs::path dir = temp_dir();
  write_text(dir / "script.json", R"({"events": [{"frame": 2, "tap": "warp"}]})");
  write_text(dir / "broken.geojson", "{\"type\": \"Feature\", ");
  struct Case {
    std::string args, message;
  };
  const Case cases[] = {
      {"--script " + (dir / "script.json").string(), "script.json: event 0: unknown key"},
      {"--measurements " + (dir / "broken.geojson").string(), "broken.geojson: not valid GeoJSON"},
      {"--measurements-out " + (dir / "none" / "m.geojson").string(), "does not exist"},
      {"--clip-box 1,2,3,0,5,6", "minx 1 is greater than maxx 0"},
      {"--classes 999", "class 999 is out of range"},
  };
  for (const Case& c : cases) {
    const auto r = test::run_stipple("view --scene-points 1000 " + c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
  }
  EXPECT_EQ(files_in(dir), 2u);
  fs::remove_all(dir);
}
