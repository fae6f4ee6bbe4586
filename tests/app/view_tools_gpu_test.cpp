// The viewer's tools driven by scripted input (`view --script`) under a virtual X server: clicks
// on known points of the built-in scene (its buildings' sizes are known by construction) and of
// autzen (points the test reads from the file), measurements read back from
// --measurements-out, and the viewer's exports compared with `stipple clip` / `stipple profile`.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "stipple/io/geojson.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

constexpr uint32_t kWidth = 1280, kHeight = 720;  // the panels leave the middle free
constexpr double kFov = 50.0;

// The viewer's camera for --camera eye,target (source coordinates), and where it shows a point.
struct View {
  Camera camera;
  View(const glm::dvec3& eye, const glm::dvec3& target) {
    camera.fov_y = glm::radians(kFov);
    camera.look_at(z_up_to_y_up(eye), z_up_to_y_up(target));
  }
  glm::dvec2 pixel(const glm::dvec3& p) const {
    const glm::dvec4 clip = camera.projection(double(kWidth) / kHeight) * camera.view_rotation() *
                            glm::dvec4(z_up_to_y_up(p) - camera.position, 1.0);
    return {(clip.x / clip.w + 1) * 0.5 * kWidth, (1 - clip.y / clip.w) * 0.5 * kHeight};
  }
};

// Builds a --script file: each call adds events at the next frames.
struct Script {
  std::vector<std::string> events;
  uint64_t frame = 3;  // the first frames settle the window
  void tap(const std::string& key) {
    events.push_back(fmt::format(R"({{"frame": {}, "tap": "{}"}})", frame++, key));
  }
  void click(const glm::dvec2& at) {
    events.push_back(fmt::format(R"({{"frame": {}, "move": [{}, {}]}})", frame++, at.x, at.y));
    events.push_back(fmt::format(R"({{"frame": {}, "click": "left"}})", frame++));
  }
  void drag(const glm::dvec2& from, const glm::dvec2& to) {
    events.push_back(fmt::format(R"({{"frame": {}, "move": [{}, {}]}})", frame++, from.x, from.y));
    events.push_back(fmt::format(R"({{"frame": {}, "press": "left"}})", frame++));
    for (int i = 1; i <= 3; ++i) {
      const glm::dvec2 at = from + (to - from) * (i / 3.0);
      events.push_back(fmt::format(R"({{"frame": {}, "move": [{}, {}]}})", frame++, at.x, at.y));
    }
    events.push_back(fmt::format(R"({{"frame": {}, "release": "left"}})", frame++));
  }
  std::string json() const {
    std::string list;
    for (const auto& e : events) list += (list.empty() ? "" : ",\n") + e;
    return fmt::format("{{\"events\": [\n{}\n]}}\n", list);
  }
  uint64_t last_frame() const { return frame + 3; }
};

fs::path temp_dir(const char* name) {
  const fs::path dir =
      fs::temp_directory_path() / fmt::format("stipple-tools-{}-{}", name, ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Runs the viewer in `dir` with a script; skips where no X server can be made.
test::CommandResult run_view(const fs::path& dir, const Script& script, const std::string& args) {
  std::ofstream(dir / "script.json") << script.json();
  return test::run_command(fmt::format(
      "cd {} && xvfb-run -a -s '-screen 0 1600x900x24' {} view {} --width {} --height {} --fov {} "
      "--script script.json --measurements-out measured.geojson --frames {} --screenshot "
      "shot.png --splat naive --no-edl",
      dir.string(), STIPPLE_BINARY, args, kWidth, kHeight, kFov, script.last_frame()));
}

#define STIPPLE_REQUIRE_XVFB()                                 \
  if (test::run_command("command -v xvfb-run").exit_code != 0) \
  GTEST_SKIP() << "xvfb-run is not installed"

const io::GeoFeature* feature(const io::GeoDocument& doc, const std::string& tool, int nth = 0) {
  for (const auto& f : doc.features)
    if (f.text("tool") == tool && nth-- == 0) return &f;
  return nullptr;
}

}  // namespace

// Built-in scene: a flat-roofed building, measured from above. Tolerances come from the click:
// a tool picks the nearest point within 3 pixels of the cursor, here 0.31 m on the roof (80 m
// away, 50 degrees over 720 pixels), so a vertex lands within 0.35 m of where the test aims.
TEST(ViewTools, MeasuresTheBuiltInScenesBuildings) {
  STIPPLE_REQUIRE_XVFB();
  io::SceneParams params;
  params.point_count = 150000;
  // The largest flat roof well inside the town; the roof is at base + height.
  const double town = io::scene_size(params) * 0.3;
  std::optional<io::SceneBuilding> pick;
  for (const auto& b : io::scene_buildings(params)) {
    const glm::dvec2 lo = b.min - glm::dvec2(params.origin), hi = b.max - glm::dvec2(params.origin);
    if (b.gabled ||
        std::max({std::abs(lo.x), std::abs(lo.y), std::abs(hi.x), std::abs(hi.y)}) > town)
      continue;
    if (!pick || (hi - lo).x * (hi - lo).y > (pick->max - pick->min).x * (pick->max - pick->min).y)
      pick = b;
  }
  ASSERT_TRUE(pick) << "the scene has no flat roof inside the town";
  const io::SceneBuilding b = *pick;
  const double roof = b.base + b.height;
  const glm::dvec2 c = (b.min + b.max) * 0.5;
  const double inset = 1.5;  // clear of the wall hits within 0.8 m of the edges
  const glm::dvec3 A(b.min.x + inset, b.min.y + inset, roof),
      B(b.max.x - inset, b.min.y + inset, roof), C(b.max.x - inset, b.max.y - inset, roof),
      D(b.min.x + inset, b.max.y - inset, roof);
  const double w = B.x - A.x, h = D.y - A.y;
  ASSERT_GT(w, 4.0);
  ASSERT_GT(h, 4.0);
  // Ground beside the building with nothing but ground or road within 1.5 m (no tree, no wall).
  io::PointBatch scene;
  io::generate_scene(params, 0, params.point_count, scene);
  std::optional<glm::dvec2> ground;
  for (const double out : {3.0, 4.0, 5.0})
    for (const glm::dvec2 g : {glm::dvec2(b.min.x - out, c.y), glm::dvec2(b.max.x + out, c.y),
                               glm::dvec2(c.x, b.min.y - out), glm::dvec2(c.x, b.max.y + out)}) {
      if (ground) break;
      size_t near = 0, other = 0;
      for (size_t i = 0; i < scene.size(); ++i) {
        if (glm::distance(glm::dvec2(scene.positions[i]), g) > 1.5) continue;
        ++near;
        other += scene.classification[i] != 2 && scene.classification[i] != 11;
      }
      if (near > 10 && other == 0) ground = g;
    }
  ASSERT_TRUE(ground) << "no clear ground beside the building";
  const glm::dvec3 G(ground->x, ground->y, io::scene_ground_height(params, ground->x, ground->y));
  // A second polyline to edit: E to F, then F dragged to F2.
  const glm::dvec3 E(A.x + w * 0.25, c.y, roof), F(A.x + w * 0.75, c.y, roof),
      F2(A.x + w * 0.75, A.y + h * 0.2, roof);

  const View view(glm::dvec3(c.x, c.y - 8, roof + 80), glm::dvec3(c.x, c.y, roof));
  Script s;
  auto px = [&](const glm::dvec3& p) { return view.pixel(p); };
  s.tap("2"), s.click(px(A)), s.click(px(B)), s.click(px(C)), s.tap("enter");
  s.tap("3"), s.click(px(G)), s.click(px(A));
  s.tap("4"), s.click(px(A)), s.click(px(B)), s.click(px(C)), s.click(px(D)), s.tap("enter");
  s.tap("5"), s.click(px(A)), s.click(px(B)), s.click(px(C));
  s.tap("6"), s.click(px(A)), s.click(px(B)), s.click(px(C));
  s.tap("7"), s.click(px(G)), s.click(px(A)), s.click(px(B)), s.click(px(C));
  s.tap("9"), s.click(px(glm::dvec3(c, roof)));
  s.tap("2"), s.click(px(E)), s.click(px(F)), s.tap("enter");
  s.tap("0"), s.drag(px(F), px(F2));
  s.tap("1"), s.click(px(C));

  const fs::path dir = temp_dir("scene");
  const auto r = run_view(dir, s,
                          fmt::format("--scene-points {} --camera {},{},{},{},{},{}",
                                      params.point_count, c.x, c.y - 8, roof + 80, c.x, c.y, roof));
  if (r.exit_code != 0 && r.output.find("cannot open a window") != std::string::npos)
    GTEST_SKIP() << "no X display could be made: " << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const io::GeoDocument doc = io::read_geojson(dir / "measured.geojson");
  EXPECT_EQ(doc.crs_name, "urn:ogc:def:crs:EPSG::32633");
  constexpr double kVertex = 0.35;  // metres, see above

  const auto* distance = feature(doc, "distance");
  ASSERT_TRUE(distance) << r.output;
  const auto& seg = std::get<std::vector<double>>(distance->properties.at("segments_horizontal"));
  ASSERT_EQ(seg.size(), 2u);
  EXPECT_NEAR(seg[0], w, 2 * kVertex);
  EXPECT_NEAR(seg[1], h, 2 * kVertex);
  EXPECT_NEAR(distance->number("length_3d", 0), w + h, 4 * kVertex);
  // The roof is flat: slope and horizontal lengths agree within the ranging noise.
  EXPECT_NEAR(distance->number("length_3d", 0), distance->number("length_horizontal", 0), 0.05);

  // Height: ground beside the building to its roof, against the terrain under the measured
  // ground point (ranging noise is 2 cm).
  const auto* height = feature(doc, "height");
  ASSERT_TRUE(height);
  const glm::dvec3 g = height->parts[0][0];
  EXPECT_NEAR(glm::distance(glm::dvec2(g), glm::dvec2(G)), 0.0, kVertex);
  EXPECT_NEAR(height->number("height_difference", 0),
              roof - io::scene_ground_height(params, g.x, g.y), 0.05);

  const auto* area = feature(doc, "area");
  ASSERT_TRUE(area);
  // Each side within 2 vertex errors: the area within (w + 0.7)(h + 0.7) - wh.
  const double area_tolerance = (w + 2 * kVertex) * (h + 2 * kVertex) - w * h;
  EXPECT_NEAR(area->number("area_horizontal", 0), w * h, area_tolerance);
  EXPECT_NEAR(area->number("area_3d", 0), area->number("area_horizontal", 0), 0.02 * w * h);

  const auto* angle = feature(doc, "angle");
  ASSERT_TRUE(angle);
  // A right angle, within the angle two vertex errors make over the shorter side.
  EXPECT_NEAR(angle->number("angle_degrees", 0), 90.0,
              glm::degrees(std::atan(2 * kVertex / std::min(w, h)) * 2));

  const auto* circle = feature(doc, "circle");
  ASSERT_TRUE(circle);
  // Through three corners of a rectangle: centred on it, radius half its diagonal.
  EXPECT_NEAR(circle->number("radius", 0), std::hypot(w, h) / 2, 2 * kVertex);
  const auto& centre = std::get<std::vector<double>>(circle->properties.at("center"));
  EXPECT_NEAR(centre[0], c.x, 2 * kVertex);
  EXPECT_NEAR(centre[1], c.y, 2 * kVertex);

  // Volume above the ground point's height over the roof's inset rectangle: a prism.
  const auto* volume = feature(doc, "volume");
  ASSERT_TRUE(volume);
  const double prism = w * h * (roof - volume->number("plane_z", 0));
  EXPECT_NEAR(volume->number("volume_above", 0), prism,
              area_tolerance * (roof - G.z) + 0.02 * prism);
  EXPECT_GT(volume->number("covered_fraction", 0), 0.9);

  const auto* annotation = feature(doc, "annotation");
  ASSERT_TRUE(annotation);
  EXPECT_EQ(annotation->text("label"), "Annotation 1");
  EXPECT_NEAR(annotation->parts[0][0].z, roof, 0.05);

  // The edited polyline: its end was dragged from F to F2, and its length followed.
  const auto* edited = feature(doc, "distance", 1);
  ASSERT_TRUE(edited);
  ASSERT_EQ(edited->parts[0].size(), 2u);
  EXPECT_LT(glm::distance(glm::dvec2(edited->parts[0][1]), glm::dvec2(F2)), kVertex);
  EXPECT_NEAR(edited->number("length_horizontal", 0), glm::distance(glm::dvec2(E), glm::dvec2(F2)),
              2 * kVertex);

  // Inspect: the record is the scene's own point (regenerated by index, full precision).
  const auto* inspect = feature(doc, "inspect");
  ASSERT_TRUE(inspect);
  EXPECT_EQ(inspect->text("source"), "procedural scene");
  const uint64_t index = uint64_t(inspect->number("record", -1));
  io::PointBatch one;
  io::generate_scene(params, index, 1, one);
  EXPECT_EQ(inspect->parts[0][0].x, one.positions[0].x);
  EXPECT_EQ(inspect->parts[0][0].y, one.positions[0].y);
  EXPECT_EQ(inspect->parts[0][0].z, one.positions[0].z);
  EXPECT_EQ(inspect->number("classification", -1), 6.0);  // a roof
  EXPECT_EQ(inspect->number("gps_time", 0), one.gps_time[0]);
  EXPECT_LT(glm::distance(glm::dvec2(one.positions[0]), glm::dvec2(C)), kVertex);
  // UTM 33N: about 15 degrees east, 46 north.
  EXPECT_NEAR(inspect->number("longitude", 0), 15.0, 0.1);
  EXPECT_NEAR(inspect->number("latitude", 0), 46.05, 0.1);

  // The overlays: the distance's colour (255, 217, 51) along the edited polyline in the
  // screenshot (the UI pass draws them; the first polyline lies under the area's lines).
  const gpu::Image shot = gpu::read_png(dir / "shot.png");
  size_t yellow = 0;
  const glm::dvec2 a = px(glm::dvec3(edited->parts[0][0])),
                   bb = px(glm::dvec3(edited->parts[0][1]));
  for (int k = 5; k < 95; ++k) {
    const glm::dvec2 p = a + (bb - a) * (k / 100.0);
    const uint8_t* q =
        &shot.rgba[(size_t(std::lround(p.y)) * shot.width + size_t(std::lround(p.x))) * 4];
    yellow += q[0] > 200 && q[1] > 170 && q[2] < 110;
  }
  EXPECT_GT(yellow, 60u);
  if (!HasFailure()) fs::remove_all(dir);  // kept for a look when something failed
}

namespace {

// Autzen's points, read by our reader (the same records the viewer reads back).
struct AutzenPoints {
  io::PointBatch batch;
  explicit AutzenPoints(const fs::path& path) {
    io::LasReader reader(path);
    while (reader.read(batch, 1 << 16)) {
    }
  }
};

// Points the picker must return when the cursor is on them: inside the free middle of the
// window (clear of both panels), and nearest to the camera by 0.05 ft among every point within
// 1.5 times the pick cone (so no other point can win: positions are drawn to 1e-4 ft).
std::vector<size_t> unambiguous_points(const AutzenPoints& pts, const View& view,
                                       const std::vector<uint8_t>* allowed = nullptr) {
  const glm::dvec3 eye = y_up_to_z_up(view.camera.position);
  const double tan_cone = 1.5 * 3.0 * 2.0 * std::tan(glm::radians(kFov) / 2) / kHeight;
  std::vector<size_t> out;
  const auto& p = pts.batch.positions;
  for (size_t i = 0; i < p.size() && out.size() < 12; i += 13) {
    if (allowed && !(*allowed)[i]) continue;
    const glm::dvec2 px = view.pixel(p[i]);
    if (px.x < 400 || px.x > 820 || px.y < 60 || px.y > 680) continue;
    const glm::dvec3 dir = glm::normalize(p[i] - eye);
    const double t_i = glm::dot(p[i] - eye, dir);
    bool nearest = true;
    for (size_t j = 0; j < p.size() && nearest; ++j) {
      if (j == i || (allowed && !(*allowed)[j])) continue;
      const glm::dvec3 w = p[j] - eye;
      const double t = glm::dot(w, dir);
      if (t <= 0 || t > t_i + 0.05) continue;
      nearest = glm::length(w - t * dir) > tan_cone * t;
    }
    if (nearest) out.push_back(i);
  }
  return out;
}

}  // namespace

// Autzen (feet, Oregon Lambert): two points the test reads from the file, clicked from above
// (86 degrees down: the orbit camera keeps its pitch within 89).
// The tools snap a click to the record the picker finds, read again in full precision, so the
// measured distance and height are those of the two records exactly (1e-6 ft).
TEST(ViewTools, MeasuresAutzenBetweenRecordsExactly) {
  STIPPLE_REQUIRE_XVFB();
  STIPPLE_REQUIRE_DATA(laz, "laz/autzen_trim.laz");
  const AutzenPoints pts(laz);
  const glm::dvec3 target(636590, 849216, 430), eye(636590, 849170, 1130);
  const View view(eye, target);
  const std::vector<size_t> candidates = unambiguous_points(pts, view);
  ASSERT_GE(candidates.size(), 2u);
  const size_t pi = candidates.front();
  size_t qi = candidates.back();
  for (size_t c : candidates)  // the farthest from the first
    if (glm::distance(pts.batch.positions[c], pts.batch.positions[pi]) >
        glm::distance(pts.batch.positions[qi], pts.batch.positions[pi]))
      qi = c;
  const glm::dvec3 P = pts.batch.positions[pi], Q = pts.batch.positions[qi];
  Script s;
  s.tap("1"), s.click(view.pixel(P));
  s.tap("2"), s.click(view.pixel(P)), s.click(view.pixel(Q)), s.tap("enter");
  s.tap("3"), s.click(view.pixel(P)), s.click(view.pixel(Q));
  const fs::path dir = temp_dir("autzen");
  const auto r = run_view(dir, s,
                          fmt::format("{} --camera {},{},{},{},{},{}", laz.string(), eye.x, eye.y,
                                      eye.z, target.x, target.y, target.z));
  if (r.exit_code != 0 && r.output.find("cannot open a window") != std::string::npos)
    GTEST_SKIP() << "no X display could be made: " << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const io::GeoDocument doc = io::read_geojson(dir / "measured.geojson");

  const auto* inspect = feature(doc, "inspect");
  ASSERT_TRUE(inspect);
  EXPECT_EQ(uint64_t(inspect->number("record", -1)), pi);
  EXPECT_EQ(inspect->parts[0][0].x, P.x);
  EXPECT_EQ(inspect->parts[0][0].y, P.y);
  EXPECT_EQ(inspect->parts[0][0].z, P.z);
  EXPECT_EQ(inspect->number("intensity", -1), pts.batch.intensity[pi]);
  EXPECT_EQ(inspect->number("classification", -1), pts.batch.classification[pi]);
  EXPECT_EQ(inspect->number("gps_time", -1), pts.batch.gps_time[pi]);
  EXPECT_EQ(inspect->number("red", -1), pts.batch.rgb[pi].r);
  EXPECT_EQ(inspect->number("point_source_id", -1), pts.batch.point_source_id[pi]);
  EXPECT_EQ(inspect->text("unit"), "");  // records carry no unit; measurements do
  // Autzen Stadium, Eugene, Oregon.
  EXPECT_NEAR(inspect->number("longitude", 0), -123.07, 0.02);
  EXPECT_NEAR(inspect->number("latitude", 0), 44.06, 0.02);

  const auto* distance = feature(doc, "distance");
  ASSERT_TRUE(distance);
  EXPECT_EQ(distance->text("unit"), "foot");
  EXPECT_NEAR(distance->number("length_3d", 0), glm::distance(P, Q), 1e-6);
  EXPECT_NEAR(distance->number("length_horizontal", 0), glm::distance(glm::dvec2(P), glm::dvec2(Q)),
              1e-6);
  const auto* height = feature(doc, "height");
  ASSERT_TRUE(height);
  EXPECT_NEAR(height->number("height_difference", 0), Q.z - P.z, 1e-9);
  if (!HasFailure()) fs::remove_all(dir);
}

// The viewer's exports run `stipple clip` / `stipple profile`'s code with what is shown: the
// clip (X) and the profile (R) equal the command line's outputs for the same region, filters
// and line.
TEST(ViewTools, ExportsMatchTheCommandLine) {
  STIPPLE_REQUIRE_XVFB();
  STIPPLE_REQUIRE_DATA(laz, "laz/autzen_trim.laz");
  const AutzenPoints pts(laz);
  const glm::dvec3 target(636590, 849216, 430), eye(636590, 849170, 1130);
  const View view(eye, target);
  const std::string box = "636300,849000,300,636900,849400,600,20";
  const pc::ClipBox clip_box = pc::parse_box(box, "--box");
  std::vector<uint8_t> shown(pts.batch.size());
  for (size_t i = 0; i < shown.size(); ++i)
    shown[i] = pts.batch.classification[i] == 2 && clip_box.contains(pts.batch.positions[i]);
  // The profile's ends: points the filters show, so that the clicks find them.
  const std::vector<size_t> ends = unambiguous_points(pts, view, &shown);
  ASSERT_GE(ends.size(), 2u);
  Script s;
  s.tap("8"), s.click(view.pixel(pts.batch.positions[ends.front()]));
  s.click(view.pixel(pts.batch.positions[ends.back()])), s.tap("enter");
  s.tap("x"), s.tap("r");
  const fs::path dir = temp_dir("export");
  const auto r =
      run_view(dir, s,
               fmt::format("{} --camera {},{},{},{},{},{} --clip-box {} --classes 2", laz.string(),
                           eye.x, eye.y, eye.z, target.x, target.y, target.z, box));
  if (r.exit_code != 0 && r.output.find("cannot open a window") != std::string::npos)
    GTEST_SKIP() << "no X display could be made: " << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;

  // The clip: the same points, records equal field by field, as `stipple clip` writes them.
  const auto cli = test::run_stipple(
      fmt::format("clip {} -o {}/cli.laz --box {} --classes 2", laz.string(), dir.string(), box));
  ASSERT_EQ(cli.exit_code, 0) << cli.output;
  io::LasReader a(dir / "clip.laz"), b(dir / "cli.laz");
  EXPECT_GT(a.header().point_count, 1000u);
  ASSERT_EQ(a.header().point_count, b.header().point_count);
  EXPECT_EQ(a.header().crs.wkt, b.header().crs.wkt);
  io::PointBatch pa, pb;
  while (a.read(pa, 1 << 16)) {
  }
  while (b.read(pb, 1 << 16)) {
  }
  EXPECT_EQ(pa.positions, pb.positions);
  EXPECT_EQ(pa.gps_time, pb.gps_time);
  EXPECT_EQ(pa.intensity, pb.intensity);
  EXPECT_EQ(pa.classification, pb.classification);

  // The profile: its line and width from the measurements, the CSV equal byte for byte.
  const io::GeoDocument doc = io::read_geojson(dir / "measured.geojson");
  const auto* profile = feature(doc, "profile");
  ASSERT_TRUE(profile) << r.output;
  std::string line;
  for (const glm::dvec3& v : profile->parts[0])
    line += fmt::format("{}{},{}", line.empty() ? "" : ",", v.x, v.y);
  const double width = profile->number("width", 0);
  EXPECT_GT(width, 0);
  const auto ref = test::run_stipple(
      fmt::format("profile {} --line {} --width {} --csv {}/cli.csv --box {} --classes 2",
                  laz.string(), line, width, dir.string(), box));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;
  auto slurp = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string viewer_csv = slurp(dir / "profile.csv"), cli_csv = slurp(dir / "cli.csv");
  EXPECT_GT(std::count(cli_csv.begin(), cli_csv.end(), '\n'), 10);
  EXPECT_EQ(viewer_csv, cli_csv);
  EXPECT_TRUE(fs::exists(dir / "profile.png"));
  if (!HasFailure()) fs::remove_all(dir);
}

// `view --measurements FILE`: plain GeoJSON from elsewhere (no "tool" properties) loads as
// measurements in the source CRS, is drawn, can be edited, and is saved back: the line's
// untouched vertex and the polygon and label keep their coordinates to the last bit, the
// dragged vertex follows the cursor and the lengths follow it.
TEST(ViewTools, LoadsMeasurementsDrawsEditsAndSavesThem) {
  STIPPLE_REQUIRE_XVFB();
  io::SceneParams params;
  params.point_count = 150000;
  const double ox = params.origin.x, oy = params.origin.y;
  auto ground = [&](double x, double y) {
    return glm::dvec3(x, y, io::scene_ground_height(params, x, y));
  };
  // Inside the free middle of the window from 120 m up (about 0.16 m a pixel).
  const glm::dvec3 A = ground(ox - 25.125, oy - 15.5), B = ground(ox + 20.25, oy - 15.5),
                   B2 = ground(ox + 20.25, oy + 8.0), label = ground(ox + 5.0625, oy + 20.0);
  const double g = io::scene_ground_height(params, ox, oy);
  const fs::path dir = temp_dir("load");
  std::ofstream(dir / "in.geojson") << fmt::format(
      R"({{"type": "FeatureCollection", "features": [
  {{"type": "Feature", "properties": {{}},
    "geometry": {{"type": "LineString", "coordinates": [[{:.17g}, {:.17g}, {:.17g}],
                                                      [{:.17g}, {:.17g}, {:.17g}]]}}}},
  {{"type": "Feature", "properties": {{"label": "yard"}},
    "geometry": {{"type": "Polygon", "coordinates": [[[{}, {}, {g}], [{}, {}, {g}], [{}, {}, {g}],
                                                    [{}, {}, {g}], [{}, {}, {g}]]]}}}},
  {{"type": "Feature", "properties": {{"label": "Gate 3"}},
    "geometry": {{"type": "Point", "coordinates": [{:.17g}, {:.17g}, {:.17g}]}}}}]}})",
      A.x, A.y, A.z, B.x, B.y, B.z, ox - 20, oy + 5, ox, oy + 5, ox, oy + 15, ox - 20, oy + 15,
      ox - 20, oy + 5, label.x, label.y, label.z, fmt::arg("g", g));

  const View view(glm::dvec3(ox, oy - 8, g + 120), glm::dvec3(ox, oy, g));
  Script s;
  s.tap("0"), s.drag(view.pixel(B), view.pixel(B2));
  const auto r = run_view(dir, s,
                          fmt::format("--scene-points {} --measurements in.geojson --camera "
                                      "{},{},{},{},{},{}",
                                      params.point_count, ox, oy - 8, g + 120, ox, oy, g));
  if (r.exit_code != 0 && r.output.find("cannot open a window") != std::string::npos)
    GTEST_SKIP() << "no X display could be made: " << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const io::GeoDocument doc = io::read_geojson(dir / "measured.geojson");
  EXPECT_EQ(doc.crs_name, "urn:ogc:def:crs:EPSG::32633");

  const auto* line = feature(doc, "distance");
  ASSERT_TRUE(line) << r.output;
  ASSERT_EQ(line->parts[0].size(), 2u);
  EXPECT_EQ(line->parts[0][0], A);  // untouched: exact
  const glm::dvec3 moved = line->parts[0][1];
  // The dragged vertex snaps to the point under the cursor: within 0.5 m of B2 horizontally
  // (3 pixels of pick cone, nearly straight down).
  EXPECT_LT(glm::distance(glm::dvec2(moved), glm::dvec2(B2)), 0.5);
  EXPECT_NEAR(line->number("length_horizontal", 0), glm::distance(glm::dvec2(A), glm::dvec2(moved)),
              1e-9);
  EXPECT_NEAR(line->number("length_3d", 0), glm::distance(A, moved), 1e-9);

  const auto* area = feature(doc, "area");
  ASSERT_TRUE(area);
  EXPECT_EQ(area->text("label"), "yard");
  EXPECT_NEAR(area->number("area_horizontal", 0), 200.0, 1e-6);  // 20 m by 10 m
  EXPECT_NEAR(area->number("area_3d", 0), 200.0, 1e-6);          // flat: every vertex at g
  ASSERT_GE(area->parts[0].size(), 4u);
  EXPECT_EQ(area->parts[0][0], glm::dvec3(ox - 20, oy + 5, g));

  const auto* note = feature(doc, "annotation");
  ASSERT_TRUE(note);
  EXPECT_EQ(note->text("label"), "Gate 3");
  EXPECT_EQ(note->parts[0][0], label);

  // Drawn: the distance's colour (255, 217, 51) along the edited line in the screenshot.
  const gpu::Image shot = gpu::read_png(dir / "shot.png");
  size_t yellow = 0;
  const glm::dvec2 a = view.pixel(A), b = view.pixel(moved);
  for (int k = 5; k < 95; ++k) {
    const glm::dvec2 p = a + (b - a) * (k / 100.0);
    const uint8_t* q =
        &shot.rgba[(size_t(std::lround(p.y)) * shot.width + size_t(std::lround(p.x))) * 4];
    yellow += q[0] > 200 && q[1] > 170 && q[2] < 110;
  }
  EXPECT_GT(yellow, 60u);
  if (!HasFailure()) fs::remove_all(dir);
}
