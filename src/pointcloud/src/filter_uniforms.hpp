#pragma once
// The filter and clip region as the shaders test them (point_filter.wgsl's `Filter`), shared by
// the billboard passes and the compute rasterizer. Private to the pointcloud module.
#include <algorithm>
#include <cstdint>
#include <vector>

#include <glm/vec4.hpp>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/filters.hpp"

namespace stipple::pc::detail {

// Mirrors `Filter` in point_filter.wgsl.
struct FilterUniforms {
  uint32_t classes[8];
  uint32_t returns;
  uint32_t flags;
  uint32_t clip_mode;
  uint32_t counts;
  float intensity[2];
  float point_source[2];
  float highlight[4];
  float boxes[kMaxGpuClipShapes][16];
  float planes[kMaxGpuClipShapes][4];
  uint32_t rings[32][4];
  float polygons[kMaxGpuClipShapes][4];
};
static_assert(sizeof(FilterUniforms) == 1360);
constexpr size_t kMaxGpuRings = 32;
// Stand-in for an unbounded range in a float uniform (shaders may assume no infinities).
constexpr double kFloatHuge = 3e38;

inline float clamp_float(double v) {
  return float(std::clamp(v, -kFloatHuge, kFloatHuge));
}

// Fills `u` for this camera and returns the polygons' ring vertices (x, y pairs, camera-relative
// source coordinates) for the polygon buffer. Throws stipple::Error past the GPU's limits.
std::vector<float> make_filter_uniforms(const PointFilter& filter, const ClipRegion& clip,
                                        const glm::vec4& highlight, const Camera& camera,
                                        FilterUniforms& u);

}  // namespace stipple::pc::detail
