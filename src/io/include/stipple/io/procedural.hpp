#pragma once
// The built-in scene: rolling terrain with roads, a town of buildings and scattered trees,
// sampled like an airborne LiDAR scan (parallel flight lines, first/last returns under trees,
// a few wall hits). Deterministic: point i depends only on the seed and i, so any range can be
// generated independently (in parallel, or streamed into a file of billions of points).
#include <cstdint>
#include <vector>

#include <glm/vec2.hpp>

#include "stipple/io/point_batch.hpp"
#include "stipple/math/aabb.hpp"

namespace stipple::io {

struct SceneParams {
  uint64_t point_count = 1'000'000;
  uint32_t seed = 1;
  double density = 12.0;  // points per square metre, as a typical airborne survey
  // Where the scene sits in its projected CRS (UTM zone 33N, EPSG:32633).
  glm::dvec3 origin{500000.0, 5100000.0, 200.0};
  int epsg = 32633;
};

// Side length in metres of the square scene for these parameters.
double scene_size(const SceneParams& params);
// Bounds of all points the scene can produce (Z-up, CRS units).
Aabb scene_bounds(const SceneParams& params);
// The scene's geometry as built, in its CRS (for tests that measure it): every building's
// footprint, ground level (at its centre) and eave height; flat roofs are at base + height.
struct SceneBuilding {
  glm::dvec2 min, max;
  double base = 0, height = 0;
  bool gabled = false;
};
std::vector<SceneBuilding> scene_buildings(const SceneParams& params);
// The terrain's height at (x, y) without ranging noise.
double scene_ground_height(const SceneParams& params, double x, double y);

// Appends points [first, first + count) to batch: positions, RGB (8-bit values), intensity,
// classification, returns, scan angle, GPS time, point source id.
void generate_scene(const SceneParams& params, uint64_t first, uint64_t count,
                    io::PointBatch& batch);

}  // namespace stipple::io
