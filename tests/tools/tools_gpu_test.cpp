// The tools' API without any UI, as the window and the page drive it: clicks at view pixels pick
// the built-in scene's points into measurements whose values follow from the picked points, the
// overlay puts them back where they were clicked, pointer input clicks and drags vertices, clip
// shapes reach the draw settings, measurements round-trip through GeoJSON text, and a profile is
// drawn from the points in its corridor.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <glm/geometric.hpp>

#include "stipple/core/error.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/tools/tools.hpp"
#include "test_util.hpp"

using namespace stipple;
using namespace stipple::tools;

namespace {

constexpr double kWidth = 320, kHeight = 240;

struct ToolsScene {
  Engine engine;
  Registry& main() { return engine.main(); }
  ViewPoint at(double x, double y) const { return {{x, y}, {kWidth, kHeight}}; }
  ToolsState& state() { return engine.main().resource<ToolsState>(); }
};

// The built-in scene (40,000 points) framed from above at an angle, drawn once.
void build(ToolsScene& s) {
  Engine& engine = s.engine;
  engine.add_plugins(TimePlugin{}, TransformPlugin{}, CameraPlugin{});
  engine.add_plugin(GpuPlugin{});
  engine.add_plugin(RenderGraphPlugin{});
  pc::PointCloudPlugin points;
  points.inputs.scene.point_count = 40000;
  points.inputs.progress = false;
  points.settings.render.point_size = 3.0f;
  engine.add_plugin(std::move(points));
  engine.add_plugin(HeadlessTargetPlugin{uint32_t(kWidth), uint32_t(kHeight), "", 0});
  engine.add_plugin(ToolsCorePlugin{});
  Registry& main = engine.main();
  const Aabb bounds = main.resource<pc::SceneInfo>().world_bounds;
  main.emplace<Camera>(main.create(), frame_box(bounds, kWidth / kHeight, 30.0, 60.0));
  engine.run(1);
}

const Camera& camera_of(Registry& main) {
  const Camera* camera = nullptr;
  main.view<Camera>().each([&](const Camera& c) { camera = &c; });
  return *camera;
}

}  // namespace

TEST(ToolsApi, ClicksMeasureWhatIsUnderTheCursorAndTheOverlayShowsItThere) {
  ToolsScene s;
  build(s);
  Registry& main = s.main();
  EXPECT_FALSE(click(main, s.at(160, 120)));  // no tool yet
  set_tool(main, Tool::Distance);
  ASSERT_TRUE(click(main, s.at(120, 130))) << s.state().message;
  ASSERT_TRUE(click(main, s.at(200, 110))) << s.state().message;
  ASSERT_TRUE(click(main, s.at(230, 150))) << s.state().message;
  finish(main);
  ASSERT_EQ(s.state().items.size(), 1u);
  const Measurement& m = s.state().items[0];
  ASSERT_TRUE(m.complete);
  ASSERT_EQ(m.points.size(), 3u);
  EXPECT_NEAR(m.values.length_3d,
              glm::distance(m.points[0], m.points[1]) + glm::distance(m.points[1], m.points[2]),
              1e-9);
  EXPECT_GT(m.values.length_3d, 0.0);
  // Each picked point is drawn within the pick cone (3 pixels) of where it was clicked.
  const Overlay o = overlay(main, {kWidth, kHeight});
  ASSERT_EQ(o.dots.size(), 3u);
  const glm::dvec2 clicked[] = {{120, 130}, {200, 110}, {230, 150}};
  for (int v = 0; v < 3; ++v) {
    EXPECT_EQ(o.dots[size_t(v)].item, 0);
    EXPECT_EQ(o.dots[size_t(v)].vertex, v);
    EXPECT_LT(glm::distance(o.dots[size_t(v)].at, clicked[v]), 3.5) << v;
  }
  EXPECT_EQ(o.lines.size(), 2u);
  // Segment labels (a polyline of more than two points) and the total's.
  ASSERT_EQ(o.labels.size(), 3u);
  EXPECT_NE(o.labels.back().text.find(fmt::format("{:.3f}", m.values.length_3d)), std::string::npos)
      << o.labels.back().text;
  // Inspect keeps the record of the point under the cursor (the scene's points are made again
  // by index: full precision).
  set_tool(main, Tool::Inspect);
  ASSERT_TRUE(click(main, s.at(160, 120)));
  ASSERT_TRUE(s.state().inspected);
  EXPECT_TRUE(s.state().inspected->from_source);
  EXPECT_FALSE(s.state().inspected->fields.empty());
  // Behind the camera nothing is drawn; off the data nothing is picked.
  EXPECT_FALSE(click(main, s.at(-500, -500)));
  EXPECT_EQ(s.state().message, "no point under the cursor");
  (void)camera_of(main);
}

TEST(ToolsApi, PointerInputClicksDragsVerticesAndFinishesWithTheRightButton) {
  ToolsScene s;
  build(s);
  Registry& main = s.main();
  set_tool(main, Tool::Area);
  for (const glm::dvec2 p : {glm::dvec2(110, 100), glm::dvec2(210, 100), glm::dvec2(200, 170)}) {
    pointer_down(main, s.at(p.x, p.y), Button::Left);
    EXPECT_FALSE(pointer_holds(main));       // nothing to grab while drawing
    pointer_move(main, s.at(p.x + 1, p.y));  // within a click's tolerance
    pointer_up(main, s.at(p.x + 1, p.y), Button::Left);
  }
  ASSERT_EQ(s.state().items.size(), 1u);
  EXPECT_FALSE(s.state().items[0].complete);
  pointer_down(main, s.at(50, 50), Button::Right);
  pointer_up(main, s.at(51, 50), Button::Right);
  ASSERT_TRUE(s.state().items[0].complete);
  const double area = s.state().items[0].values.area_horizontal;
  EXPECT_GT(area, 0.0);
  // A press on the second vertex grabs it; moving past the tolerance drags it; the release puts
  // it down and the area follows.
  const glm::dvec3 before = s.state().items[0].points[1];
  const Overlay o = overlay(main, {kWidth, kHeight});
  const glm::dvec2 v1 = o.dots[1].at;
  pointer_down(main, s.at(v1.x + 2, v1.y), Button::Left);
  EXPECT_TRUE(pointer_holds(main));
  pointer_move(main, s.at(v1.x + 40, v1.y + 30));
  pointer_up(main, s.at(v1.x + 40, v1.y + 30), Button::Left);
  EXPECT_FALSE(pointer_holds(main));
  ASSERT_EQ(s.state().items.size(), 1u);  // a drag adds nothing
  EXPECT_GT(glm::distance(s.state().items[0].points[1], before), 0.0);
  EXPECT_NE(s.state().items[0].values.area_horizontal, area);
  // Undo and cancel while drawing; remove.
  set_tool(main, Tool::Height);
  ASSERT_TRUE(click(main, s.at(150, 120)));
  EXPECT_EQ(s.state().items.size(), 2u);
  undo_point(main);
  EXPECT_EQ(s.state().items.size(), 1u);
  remove(main, 0);
  EXPECT_TRUE(s.state().items.empty());
}

TEST(ToolsApi, ClipShapesReachTheDrawSettingsAndMeasurementsRoundTripAsGeoJson) {
  ToolsScene s;
  build(s);
  Registry& main = s.main();
  set_tool(main, Tool::ClipBox);
  for (const glm::dvec2 p : {glm::dvec2(120, 110), glm::dvec2(200, 110), glm::dvec2(190, 160)})
    ASSERT_TRUE(click(main, s.at(p.x, p.y))) << s.state().message;
  ASSERT_TRUE(s.state().items[0].complete);  // three clicks make a box
  set_tool(main, Tool::Height);
  ASSERT_TRUE(click(main, s.at(100, 140)));
  ASSERT_TRUE(click(main, s.at(200, 125)));
  s.engine.update();  // tools_sync
  const auto& settings = main.resource<pc::PointDrawSettings>();
  EXPECT_EQ(settings.render.clip.boxes.size(), 1u);
  const std::string text = measurements_geojson(s.state());
  EXPECT_NE(text.find("\"clip_box\""), std::string::npos) << text;
  const ToolsState saved = s.state();
  clear(main);
  EXPECT_TRUE(s.state().items.empty());
  add_measurements(main, text, "link");
  ASSERT_EQ(s.state().items.size(), saved.items.size());
  for (size_t i = 0; i < saved.items.size(); ++i) {
    EXPECT_EQ(s.state().items[i].tool, saved.items[i].tool);
    ASSERT_EQ(s.state().items[i].points.size(), saved.items[i].points.size());
    for (size_t k = 0; k < saved.items[i].points.size(); ++k)
      EXPECT_LT(glm::distance(s.state().items[i].points[k], saved.items[i].points[k]), 1e-6);
  }
  EXPECT_NEAR(s.state().items[1].values.height, saved.items[1].values.height, 1e-6);
  // Bad text names where it came from; nothing is added.
  try {
    add_measurements(main,
                     R"({"type":"FeatureCollection","features":[{"type":"Feature",)"
                     R"("geometry":{"type":"Point","coordinates":[1,2,3]},)"
                     R"("properties":{"tool":"height"}}]})",
                     "the link");
    FAIL() << "a one-point height was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the link"), std::string::npos) << e.what();
  }
  EXPECT_EQ(s.state().items.size(), saved.items.size());
}

TEST(ToolsApi, AProfileIsDrawnFromThePointsInItsCorridor) {
  ToolsScene s;
  build(s);
  Registry& main = s.main();
  set_tool(main, Tool::Profile);
  ASSERT_TRUE(click(main, s.at(100, 130)));
  ASSERT_TRUE(click(main, s.at(230, 120)));
  finish(main);
  const int item = current_profile(s.state());
  ASSERT_EQ(item, 0);
  const ProfileView view = profile_view(main, item, {200, 100});
  EXPECT_EQ(view.item, 0);
  EXPECT_GT(view.points, 100u);
  ASSERT_EQ(view.image.width, 200u);
  ASSERT_EQ(view.image.height, 100u);
  // Points drawn: pixels that are neither the background nor the grid's grey.
  size_t coloured = 0;
  for (size_t i = 0; i < view.image.rgba.size(); i += 4) {
    const uint8_t r = view.image.rgba[i], g = view.image.rgba[i + 1], b = view.image.rgba[i + 2];
    coloured += std::max({r, g, b}) - std::min({r, g, b}) > 30;
  }
  EXPECT_GT(coloured, 100u);
  EXPECT_NEAR(view.frame.length, s.state().items[0].values.length_horizontal, 1e-6);
  // No profile export without files to read again.
  EXPECT_FALSE(can_export(main));
  start_profile_export(main, item, {"", "p.csv", ""});
  EXPECT_EQ(s.state().message, "export needs LAS/LAZ/COPC inputs");
}
