#pragma once
// Picking the point under the cursor, whatever draws the scene. Each scene plugin registers a
// function in the main-world resource ScenePickers (PointCloudPlugin over its loaded clouds,
// TilesetPlugin over the tiles drawn this frame); the camera controller asks them all and keeps
// the nearest hit, so it depends on neither plugin.
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/math/aabb.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

namespace stipple {
class Registry;
}

namespace stipple::pc {

// A cone around a ray: points within `tan_radius` (tangent of its half-angle, e.g. a few
// pixels' worth) of the axis count as hits.
struct PickRay {
  glm::dvec3 origin{0.0};
  glm::dvec3 direction{0, 0, -1};  // normalised
  double tan_radius = 0.0;
};

struct PickHit {
  glm::dvec3 point{0.0};  // world space
  double t = 0.0;         // distance along the ray's direction
  // What the chunk holds of the point: its packed attributes, extras where kept, and the index
  // of its record among the source's points (PointChunk::first_point + i; kNoSourcePoint for
  // streamed tiles, whose points are not numbered).
  PointChunk::Vertex vertex{};
  bool has_extra = false;
  PointChunk::Extra extra{};
  double gps_origin = 0.0;
  uint64_t source_point = kNoSourcePoint;
  static constexpr uint64_t kNoSourcePoint = ~uint64_t(0);
};

// Main-world resource (optional): only points these filters show can be picked. Scene plugins'
// pickers read it; the viewer keeps it equal to PointDrawSettings' filter and clip region.
struct PickFilter {
  PointFilter filter;
  ClipRegion clip;
};

// Whether any point inside `bounds` can lie within the cone at a distance in (0, max_t).
bool cone_may_hit(const Aabb& bounds, const PickRay& ray, double max_t);

// Replaces `best` with the point of `chunk` nearest to the ray's origin within the cone, if it
// is nearer than `best`. `bounds` (world space, e.g. PointChunk::bounds) lets a chunk out of
// the cone be skipped without reading its points; empty bounds skip the chunk. With `filter`,
// points it hides are passed over. `numbered`: the chunk's first_point is meaningful.
void pick_in_chunk(const pc::PointChunk& chunk, const Aabb& bounds, const PickRay& ray,
                   std::optional<PickHit>& best, const PickFilter* filter = nullptr,
                   bool numbered = true);

// A scene's picker: the nearest point of what it shows within the cone, if any.
using PickFunction = std::optional<PickHit> (*)(Registry& main, const PickRay& ray);

// Main-world resource: the registered pickers (add_scene_picker creates it).
struct ScenePickers {
  std::vector<PickFunction> pickers;
};

void add_scene_picker(Registry& main, PickFunction picker);
// The nearest hit over every registered picker; nullopt when none hits (or none is registered).
std::optional<PickHit> pick_scene(Registry& main, const PickRay& ray);

}  // namespace stipple::pc
