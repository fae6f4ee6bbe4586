// The measuring tools' geometry and their GeoJSON round trip.
#include <gtest/gtest.h>

#include <cmath>

#include "stipple/core/error.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/tools/measure.hpp"

using namespace stipple;
using namespace stipple::tools;

namespace {
Measurement make(Tool tool, std::vector<glm::dvec3> points) {
  Measurement m;
  m.tool = tool;
  m.points = std::move(points);
  m.complete = true;
  compute_values(m);
  return m;
}
}  // namespace

TEST(Measure, PolylineLengthsHorizontalAndAlongTheSlope) {
  const Measurement m = make(Tool::Distance, {{0, 0, 0}, {3, 4, 12}, {3, 4, 0}});
  ASSERT_EQ(m.values.segments_3d.size(), 2u);
  EXPECT_DOUBLE_EQ(m.values.segments_horizontal[0], 5.0);
  EXPECT_DOUBLE_EQ(m.values.segments_3d[0], 13.0);
  EXPECT_DOUBLE_EQ(m.values.segments_horizontal[1], 0.0);
  EXPECT_DOUBLE_EQ(m.values.segments_3d[1], 12.0);
  EXPECT_DOUBLE_EQ(m.values.length_3d, 25.0);
  EXPECT_DOUBLE_EQ(m.values.length_horizontal, 5.0);
  EXPECT_DOUBLE_EQ(m.values.height, 0.0);
  EXPECT_DOUBLE_EQ(make(Tool::Height, {{1, 1, 2}, {5, 4, 9.5}}).values.height, 7.5);
}

TEST(Measure, AreaHorizontalAnd3D) {
  // A 4 x 3 rectangle tilted up 2 along X: horizontal 12, 3D 3 * sqrt(4^2 + 2^2).
  const Measurement m = make(Tool::Area, {{0, 0, 0}, {4, 0, 2}, {4, 3, 2}, {0, 3, 0}});
  EXPECT_NEAR(m.values.area_horizontal, 12.0, 1e-12);
  EXPECT_NEAR(m.values.area_3d, 3 * std::sqrt(20.0), 1e-12);
  EXPECT_NEAR(m.values.perimeter, 6 + 2 * std::sqrt(20.0), 1e-12);
  // Far from the origin (UTM magnitudes) the same, to 1e-6.
  const glm::dvec3 o(500000, 5100000, 200);
  const Measurement far = make(
      Tool::Area, {o, o + glm::dvec3(4, 0, 2), o + glm::dvec3(4, 3, 2), o + glm::dvec3(0, 3, 0)});
  EXPECT_NEAR(far.values.area_horizontal, 12.0, 1e-6);
}

TEST(Measure, AngleCircleAndBox) {
  EXPECT_NEAR(make(Tool::Angle, {{1, 0, 0}, {0, 0, 0}, {0, 0, 1}}).values.angle_degrees, 90.0,
              1e-12);
  EXPECT_NEAR(make(Tool::Angle, {{1, 0, 0}, {0, 0, 0}, {1, 1, 0}}).values.angle_degrees, 45.0,
              1e-12);
  // Three points of a circle of radius 5 around (10, 20, 30), in a tilted plane.
  const glm::dvec3 c(10, 20, 30), u = glm::normalize(glm::dvec3(1, 0, 1)), v(0, 1, 0);
  auto on = [&](double a) { return c + 5.0 * (std::cos(a) * u + std::sin(a) * v); };
  const Measurement circle = make(Tool::Circle, {on(0.1), on(1.7), on(4.0)});
  EXPECT_NEAR(circle.values.radius, 5.0, 1e-9);
  EXPECT_NEAR(glm::distance(circle.values.center, c), 0.0, 1e-9);
  EXPECT_FALSE(circle_through({0, 0, 0}, {1, 1, 1}, {2, 2, 2}));
  // Box from clicks: an edge from (0,0) to (10,0) and a point 4 to its left.
  const pc::ClipBox box = box_from_clicks({0, 0, 0}, {10, 0, 0}, {3, 4, 0}, 0, 10);
  EXPECT_NEAR(box.center.x, 5, 1e-12);
  EXPECT_NEAR(box.center.y, 2, 1e-12);
  EXPECT_NEAR(box.half_size.x, 5, 1e-12);
  EXPECT_NEAR(box.half_size.y, 2, 1e-12);
  EXPECT_TRUE(box.contains({9, 3.9, 5}));
  EXPECT_FALSE(box.contains({9, -0.1, 5}));
}

TEST(Measure, VolumeAboveAPlaneOfABlock) {
  // A 10 x 6 m block 4 m high on flat ground at z 100, sampled every 0.25 m (world Y up).
  pc::PointCloud cloud;
  io::PointBatch batch;
  for (double x = -5; x < 15; x += 0.25)
    for (double y = -5; y < 11; y += 0.25) {
      const bool block = x >= 0 && x < 10 && y >= 0 && y < 6;
      batch.positions.emplace_back(x + 0.125, y + 0.125, block ? 104.0 : 100.0);
    }
  pc::append_batch(cloud, batch, 8, 1 << 20);
  pc::finish_cloud(cloud);
  // Volume tool: the plane at the ground, a box around the block with a margin.
  Measurement m = make(Tool::Volume, {{-2, 5, 100}, {-2, -2, 0}, {12, -2, 0}, {0, 8, 0}});
  measure_with_cloud(m, &cloud, {}, {});
  EXPECT_NEAR(m.values.plane_z, 100.0, 1e-12);
  EXPECT_NEAR(m.values.area_horizontal, 14.0 * 10.0, 1e-9);
  // 240 m3, within the cells the block's edges cross (2 * spacing cells over its perimeter).
  EXPECT_NEAR(m.values.volume_above, 240.0, 0.06 * 240.0);
  EXPECT_GT(m.values.covered_fraction, 0.95);
  // A filter that hides everything leaves nothing.
  pc::PointFilter none;
  none.classes.fill(0);
  measure_with_cloud(m, &cloud, none, {});
  EXPECT_EQ(m.values.volume_above, 0.0);
}

TEST(Measure, GeoJsonRoundTripInTheSourceCrs) {
  SourceFrame projected;
  projected.epsg = 2992;
  projected.unit = "foot";
  for (Tool tool :
       {Tool::Distance, Tool::Height, Tool::Area, Tool::Angle, Tool::Circle, Tool::Volume,
        Tool::Profile, Tool::Annotation, Tool::ClipBox, Tool::ClipPolygon}) {
    std::vector<glm::dvec3> pts = {{636000.25, 849000.5, 410.125},
                                   {636010, 849000.5, 412},
                                   {636010, 849010, 415},
                                   {636000, 849012, 420}};
    pts.resize(tool_points(tool) ? size_t(tool_points(tool)) : pts.size());
    Measurement m = make(tool, pts);
    m.label = "a label";
    const io::GeoFeature f = to_feature(m, projected);
    const io::GeoDocument doc =
        io::parse_geojson(io::geojson_text({f}, projected.epsg), "round trip");
    EXPECT_EQ(doc.crs_name, "urn:ogc:def:crs:EPSG::2992");
    const Measurement back = from_feature(doc.features.at(0), projected, 0, "round trip");
    EXPECT_EQ(back.tool, tool) << tool_name(tool);
    EXPECT_EQ(back.label, "a label");
    ASSERT_EQ(back.points.size(), pts.size()) << tool_name(tool);
    for (size_t i = 0; i < pts.size(); ++i) EXPECT_EQ(back.points[i], pts[i]) << tool_name(tool);
  }
  // Lon/lat sources: saved in degrees, loaded back into the same local metres.
  SourceFrame geographic;
  geographic.enu_origin = glm::dvec3(-123.07, 44.05, 0);
  const Measurement m = make(Tool::Distance, {{10, 20, 3}, {-40, 55, 7}});
  const io::GeoFeature f = to_feature(m, geographic);
  EXPECT_NEAR(f.parts[0][0].x, -123.07, 0.001);
  EXPECT_NEAR(f.parts[0][0].y, 44.05, 0.001);
  const Measurement back = from_feature(f, geographic, 0, "geo");
  EXPECT_NEAR(glm::distance(back.points[1], m.points[1]), 0.0, 1e-6);
  EXPECT_NEAR(back.values.length_3d, m.values.length_3d, 1e-6);
}

TEST(Measure, BadFeaturesAreNamed) {
  SourceFrame frame;
  io::GeoFeature f;
  f.type = "LineString";
  f.parts = {{{0, 0, 0}}};
  f.properties["tool"] = std::string("height");
  try {
    (void)from_feature(f, frame, 3, "m.geojson");
    FAIL() << "a one-point height was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("m.geojson: feature 3: a height takes 2 points"),
              std::string::npos)
        << e.what();
  }
  f.properties["tool"] = std::string("teleport");
  EXPECT_THROW((void)from_feature(f, frame, 0, "m.geojson"), Error);
}
