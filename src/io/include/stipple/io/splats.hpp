#pragma once
// 3D Gaussian splats as every reader returns them and every consumer (renderer, tiler, info,
// Python) takes them: one structure of arrays in linear units, whatever the file's encoding
// (log scales, logit opacities, quantised or compressed), so consumers never see formats.
//
// Conventions (those of the INRIA reference implementation after activation):
// - scales are linear standard deviations along the splat's local axes;
// - rotations are unit quaternions stored (x, y, z, w);
// - opacities are linear in [0, 1];
// - colour is spherical harmonics: sh_dc is the degree-0 coefficient per channel (the colour
//   is 0.5 + 0.28209479177387814 * sh_dc before clamping); sh_rest holds degrees 1..sh_degree,
//   coefficient-major per splat: splat i, coefficient k (0-based over (deg+1)^2 - 1) is
//   sh_rest[i * rest_count() + k] as (R, G, B).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace stipple::io {

struct SplatSet {
  std::vector<glm::vec3> positions;  // in the set's own frame (see transform)
  std::vector<glm::vec3> scales;     // linear
  std::vector<glm::vec4> rotations;  // unit quaternion (x, y, z, w)
  std::vector<float> opacities;      // linear, [0, 1]
  std::vector<glm::vec3> sh_dc;      // degree-0 SH coefficient per channel
  std::vector<glm::vec3> sh_rest;    // size() * rest_count(), coefficient-major per splat
  int sh_degree = 0;                 // 0..3
  // From the set's frame to the source's, which is Y up (glTF's axes): a glTF node's matrix, a
  // tile's transform; for the PLY family (INRIA and PlayCanvas PLY, .splat, .ksplat, SOG), whose
  // trainers write y down and z forward, half a turn about x; identity for SPZ (y up, z back).
  glm::dmat4 transform{1.0};
  std::string format;  // what the reader read, e.g. "INRIA PLY", "SPZ v4"

  size_t size() const { return positions.size(); }
  size_t rest_count() const { return size_t((sh_degree + 1) * (sh_degree + 1) - 1); }
};

// Appends `part`'s splats to `all`, whose SH degree they must share (callers check or widen).
inline void append_splats(SplatSet& all, const SplatSet& part) {
  auto cat = [](auto& a, const auto& b) { a.insert(a.end(), b.begin(), b.end()); };
  cat(all.positions, part.positions);
  cat(all.scales, part.scales);
  cat(all.rotations, part.rotations);
  cat(all.opacities, part.opacities);
  cat(all.sh_dc, part.sh_dc);
  cat(all.sh_rest, part.sh_rest);
}

}  // namespace stipple::io
