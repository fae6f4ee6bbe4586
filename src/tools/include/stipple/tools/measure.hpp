#pragma once
// What the viewer's measuring tools measure, without any UI: the tools, a measurement (its
// clicked points and what follows from them), the geometry (lengths horizontal and along the
// slope, height differences, areas horizontal and 3D, angles, circles through three points,
// volumes above a plane), and the GeoJSON features that save and load them in the source CRS.
//
// Points are kept in the viewer's local source frame: the source CRS's coordinates, Z up (for
// lon/lat sources, the local east-north-up metres the renderer draws in), so lengths and areas
// are in the CRS's linear unit. SourceFrame converts to the CRS for saving.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "stipple/io/geojson.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple::tools {

enum class Tool : uint8_t {
  None,
  Inspect,      // one click: the record under the cursor
  Distance,     // a polyline: segments and total, horizontal and along the slope
  Height,       // two clicks: height difference (and distances)
  Area,         // a polygon: area horizontal and 3D, perimeter
  Angle,        // three clicks: the angle at the second
  Circle,       // three clicks: the circle through them
  Volume,       // the reference height, then three clicks of a box footprint
  Profile,      // a polyline with a width: the cross-section window
  Annotation,   // one click: a label at that point
  ClipBox,      // three clicks of a box footprint (full height): a clip box
  ClipPolygon,  // a polygon: an extruded clip polygon
};
inline constexpr int kToolCount = 12;
const char* tool_name(Tool tool);
std::optional<Tool> parse_tool(const std::string& name);
// Points a tool takes; 0: a polyline or polygon of any length, finished by the user.
int tool_points(Tool tool);
// The least points an open tool needs before it can be finished.
int tool_min_points(Tool tool);

struct MeasureValues {
  std::vector<double> segments_horizontal, segments_3d;
  double length_horizontal = 0, length_3d = 0;
  double height = 0;  // last point's z minus the first's
  double area_horizontal = 0, area_3d = 0, perimeter = 0;
  double angle_degrees = 0;
  glm::dvec3 center{0.0};
  double radius = 0;
  double volume_above = 0;      // above plane_z within the box
  double covered_fraction = 0;  // of the box's cells that held points
  double plane_z = 0;
};

struct Measurement {
  Tool tool = Tool::None;
  std::vector<glm::dvec3> points;  // local source frame (Z up)
  std::string label;
  double width = 1.0;  // Profile: corridor width
  bool complete = false;
  MeasureValues values;  // compute_values / measure_volume fill it
};

// Geometry from the points (everything but the volume, which needs the cloud).
void compute_values(Measurement& m);

// The box footprint of three clicks: a and b along one edge, c's distance from that edge's line
// the width (on c's side); the heights span [min_z, max_z].
pc::ClipBox box_from_clicks(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c,
                            double min_z, double max_z);
// Volume: points[0] sets the plane, points[1..3] the footprint.
pc::ClipBox volume_box(const Measurement& m);

// The circle through three points in 3D; nullopt when they are (nearly) collinear.
struct Circle {
  glm::dvec3 center;
  double radius;
};
std::optional<Circle> circle_through(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c);

// Volume above `plane_z` inside the box's footprint, as a 2.5D surface: a grid of `cell`-sized
// cells over the footprint, each cell's height the highest shown point in it (empty cells take
// the mean of their non-empty neighbours, once; still empty ones count as the plane), summed as
// cell area * max(0, height - plane_z). Points are the cloud's (world space, Y up), those the
// filter shows.
double volume_above(const pc::PointCloud& cloud, const pc::ClipBox& box, double plane_z,
                    double cell, const pc::PointFilter& filter, const pc::ClipRegion& clip,
                    double* covered_fraction = nullptr);
// compute_values and, for a volume, volume_above with a cell of twice the cloud's spacing.
void measure_with_cloud(Measurement& m, const pc::PointCloud* cloud, const pc::PointFilter& filter,
                        const pc::ClipRegion& clip);

// The local source frame and the source CRS: identity for projected sources; local ENU metres
// and lon/lat/height for geographic ones.
struct SourceFrame {
  std::optional<glm::dvec3> enu_origin;  // lon, lat, h of the local frame (geographic sources)
  int epsg = 0;                          // the CRS's EPSG code, when known
  std::string unit;                      // "metre", "foot", ...; for labels
  glm::dvec3 to_crs(const glm::dvec3& local) const;
  glm::dvec3 from_crs(const glm::dvec3& crs) const;
};

// GeoJSON: Point (inspect, annotation), LineString (distance, height, angle, circle, profile),
// Polygon (area, volume footprint, clip box, clip polygon); properties "tool", "label" and the
// values (in the CRS's units; "unit" names it). Volume's first point is "plane_point".
io::GeoFeature to_feature(const Measurement& m, const SourceFrame& frame);
// Throws stipple::Error naming the feature for what a tool cannot use.
Measurement from_feature(const io::GeoFeature& f, const SourceFrame& frame, size_t index,
                         const std::string& name);

// A label's text for a measurement ("12.34 m", "area 120.5 m²", ...), unit abbreviated.
std::string value_text(const Measurement& m, const std::string& unit);
std::string unit_symbol(const std::string& unit);

}  // namespace stipple::tools
