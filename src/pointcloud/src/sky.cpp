#include "stipple/pointcloud/sky.hpp"

#include <glm/gtc/matrix_inverse.hpp>

#include "stipple/math/sun.hpp"

namespace stipple::pc {

SkyUniforms sky_uniforms(const SkySettings& sky, const glm::dmat4& view_proj, uint32_t width,
                         uint32_t height) {
  SkyUniforms u{};
  const glm::dmat4 inv = glm::inverse(view_proj);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) u.inv_view_proj[c * 4 + r] = float(inv[c][r]);
  const glm::dvec3 sun = solar::sun_direction(sky.sun_azimuth_deg, sky.sun_elevation_deg);
  u.sun[0] = float(sun.x);
  u.sun[1] = float(sun.y);
  u.sun[2] = float(sun.z);
  u.sun[3] = sky.enabled ? 1.0f : 0.0f;
  // World Y is the data's up: point files' Z, and geocentric tilesets are re-expressed in their
  // east-north-up frame (tiles3d/render_load.hpp).
  u.up[1] = 1.0f;
  u.up[3] = sky.observer_height_m;
  u.view[0] = float(width);
  u.view[1] = float(height);
  u.view[2] = sky.exposure;
  u.view[3] = sky.sun_intensity;
  return u;
}

}  // namespace stipple::pc
