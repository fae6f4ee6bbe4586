#pragma once
// Which points are shown or exported: attribute filters (classification, returns, intensity, GPS
// time, point source ID) and clip regions (rotated boxes, extruded polygons, planes). One
// definition serves `stipple clip` and `stipple profile` (tested on the CPU per record), the
// billboard shaders (the same tests in point_common.wgsl, on uniforms made by filter_uniforms)
// and the viewer's panel, so what is exported is what was shown.
//
// Coordinates of clip regions are the source's: its CRS units, Z up (for lon/lat sources, the
// local east-north-up metres the renderer uses).
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "stipple/io/point_batch.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple::pc {

// Return kinds; a filter keeps a point that is of any kind it names.
enum ReturnKind : uint8_t {
  kReturnFirst = 1,         // return number 1
  kReturnLast = 2,          // return number == number of returns
  kReturnSingle = 4,        // number of returns 1
  kReturnIntermediate = 8,  // neither first nor last
};

struct PointFilter {
  // Bit c of word c / 32: class c is kept. All set: no class filter.
  std::array<uint32_t, 8> classes{~0u, ~0u, ~0u, ~0u, ~0u, ~0u, ~0u, ~0u};
  uint8_t returns = 0;                     // ReturnKind bits; 0: every return
  std::optional<glm::dvec2> intensity;     // inclusive
  std::optional<glm::dvec2> gps_time;      // inclusive
  std::optional<glm::dvec2> point_source;  // inclusive
  bool operator==(const PointFilter&) const = default;

  bool class_kept(uint32_t c) const { return c < 256 && (classes[c / 32] >> (c % 32) & 1u); }
  void set_class(uint32_t c, bool kept);
  bool filters_classes() const;
  // Anything to test at all.
  bool active() const;
  // GPS time or point source: attributes beyond the points' packed word (the GPU path then
  // binds a second per-point buffer).
  bool needs_extras() const { return gps_time.has_value() || point_source.has_value(); }
  bool accepts(uint32_t classification, uint32_t return_number, uint32_t number_of_returns,
               uint32_t intensity, double gps_time, uint32_t point_source) const;
  // Point i of a batch (missing attributes read as the renderer's defaults: class 1, single
  // return, intensity 0, GPS time 0, source 0).
  bool accepts(const io::PointBatch& batch, size_t i) const;
};

bool return_kind_matches(uint8_t kinds, uint32_t return_number, uint32_t number_of_returns);

// A box rotated about the vertical axis: centre, half extents, and the angle (radians,
// counter-clockwise from +X) of its local X axis.
struct ClipBox {
  glm::dvec3 center{0.0};
  glm::dvec3 half_size{0.5};
  double yaw = 0.0;
  bool operator==(const ClipBox&) const = default;
  bool contains(const glm::dvec3& p) const;
  // The corners in the source frame (bottom four counter-clockwise, then the top four).
  std::array<glm::dvec3, 8> corners() const;
};

// A polygon in X/Y extruded between min_z and max_z; holes by the even-odd rule over its rings.
struct ClipPolygon {
  std::vector<std::vector<glm::dvec2>> rings;
  double min_z = -1e300, max_z = 1e300;
  bool operator==(const ClipPolygon&) const = default;
  bool contains(const glm::dvec3& p) const;
};

// The half-space normal . p + offset >= 0.
struct ClipPlane {
  glm::dvec3 normal{0, 0, 1};
  double offset = 0.0;
  bool operator==(const ClipPlane&) const = default;
  bool contains(const glm::dvec3& p) const {
    return normal.x * p.x + normal.y * p.y + normal.z * p.z + offset >= 0.0;
  }
};

enum class ClipMode : uint8_t { Inside, Outside, Highlight };
ClipMode parse_clip_mode(const std::string& name);
const char* clip_mode_name(ClipMode mode);

// A point is in the region when it is on the kept side of every plane and, if there are boxes
// or polygons, inside at least one of them. Inside shows those points, Outside the others,
// Highlight all of them with the region's points tinted.
struct ClipRegion {
  std::vector<ClipBox> boxes;
  std::vector<ClipPolygon> polygons;
  std::vector<ClipPlane> planes;
  ClipMode mode = ClipMode::Inside;
  bool operator==(const ClipRegion&) const = default;
  bool empty() const { return boxes.empty() && polygons.empty() && planes.empty(); }
  bool contains(const glm::dvec3& p) const;
  // Whether a point at `p` is kept (Highlight keeps everything).
  bool keeps(const glm::dvec3& p) const {
    if (empty() || mode == ClipMode::Highlight) return true;
    return contains(p) == (mode == ClipMode::Inside);
  }
};

// Whether point i of a loaded chunk is drawn under `filter` and `clip` (as the shaders decide;
// Highlight draws every point): the CPU side of the GPU filters, for picking and the viewer's
// profile. GPS time and point source count only where the chunk kept its extras.
bool chunk_point_shown(const PointChunk& chunk, size_t i, const PointFilter& filter,
                       const ClipRegion& clip);

// Most clip shapes the GPU path takes at once (each kind); more is an error naming the limit.
inline constexpr size_t kMaxGpuClipShapes = 8;
// Most polygon vertices the GPU path takes over all polygons.
inline constexpr size_t kMaxGpuPolygonVertices = 4096;

// ---- parsing of the command-line syntax (errors name the flag and what is wrong) ----
// "2,6" or "2-5,9": classes 0-255.
std::array<uint32_t, 8> parse_classes(const std::string& text, const char* flag);
// "first", "last,single", ... (first, last, single, intermediate).
uint8_t parse_returns(const std::string& text, const char* flag);
// "a,b" with a <= b.
glm::dvec2 parse_range(const std::string& text, const char* flag);
// "minx,miny,minz,maxx,maxy,maxz[,yaw_degrees]": an axis-aligned box, optionally turned about
// its centre.
ClipBox parse_box(const std::string& text, const char* flag);
// "a,b,c,d": the half-space a*x + b*y + c*z + d >= 0.
ClipPlane parse_plane(const std::string& text, const char* flag);

// ASPRS LAS 1.4 R15 class names (0-22; "reserved" and "user defined" above).
std::string classification_name(uint32_t c);

}  // namespace stipple::pc
