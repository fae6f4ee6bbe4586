#pragma once
// The contract between scene plugins (pc::PointCloudPlugin, tiles3d::TilesetPlugin, or one of
// your own) and what works over any scene (the viewer's UI and camera controller, `stipple
// render`): every scene plugin inserts these two main-world resources in build().
#include <cstdint>
#include <string>

#include "stipple/math/aabb.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"

namespace stipple::pc {

// Main- and render-world resource (copied in Extract): how points are drawn. Colour modes are
// chosen in the shader, so changing one costs nothing.
struct PointDrawSettings {
  pc::PointRenderSettings render;  // the point pipeline (same flags as `stipple render`)
  uint64_t budget = 0;             // at most this many points (whole chunks, nearest first); 0: all
  bool compute = false;  // the compute rasterizer (seed 001) instead of the point pipeline
  bool hqs = false;      // compute rasterizer: high-quality shading
  // Compute rasterizer, seed 002 III-D: hole filling radius (0: off) and the occlusion check's
  // threshold in radians (0: off).
  uint32_t fill_radius = 0;
  float occlusion_beta = 0.0f;
};

// Main-world resource: what was loaded.
struct SceneInfo {
  Aabb world_bounds;
  uint64_t points = 0;
  pc::CloudAttributes attributes;
  std::string name;  // first file's name, or "procedural scene"
};

}  // namespace stipple::pc
