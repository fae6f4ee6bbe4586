// The sky's uniforms (sky.hpp): the view ray that sky.wgsl reconstructs for a pixel from the
// inverse view-projection is the camera's ray through that pixel, and the sun is where its
// azimuth and elevation say, in the world frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/sky.hpp"

using namespace stipple;

namespace {

// What sky_color does: framebuffer pixel -> NDC on the near plane -> world direction.
glm::dvec3 ray(const pc::SkyUniforms& u, double px, double py) {
  glm::mat4 inv;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) inv[c][r] = u.inv_view_proj[c * 4 + r];
  const glm::vec4 ndc(float(px / u.view[0] * 2.0 - 1.0), float(1.0 - py / u.view[1] * 2.0), 1.0f,
                      1.0f);
  const glm::vec4 p = inv * ndc;
  return glm::normalize(glm::dvec3(p) / double(p.w));
}

}  // namespace

TEST(Sky, UniformsGiveTheCameraRays) {
  Camera camera;
  camera.fov_y = glm::radians(50.0);
  camera.look_at({100.0, 20.0, -30.0}, {150.0, 45.0, -80.0});
  const uint32_t w = 160, h = 100;
  const glm::dmat4 view_proj = camera.projection(double(w) / h) * camera.view_rotation();
  pc::SkySettings settings;
  settings.enabled = true;
  settings.sun_azimuth_deg = 90.0;
  settings.sun_elevation_deg = 30.0;
  const pc::SkyUniforms u = pc::sky_uniforms(settings, view_proj, w, h);

  // The image centre looks along the camera's forward; the top edge's middle is fov/2 above it.
  const glm::dvec3 centre = ray(u, w * 0.5, h * 0.5);
  EXPECT_NEAR(glm::dot(centre, camera.forward()), 1.0, 1e-5);
  const glm::dvec3 top = ray(u, w * 0.5, 0.0);
  EXPECT_NEAR(std::acos(std::min(1.0, glm::dot(top, camera.forward()))), camera.fov_y * 0.5, 1e-4);
  EXPECT_GT(glm::dot(top, camera.up()), 0.0);  // framebuffer y grows downwards
  const glm::dvec3 right = ray(u, double(w), h * 0.5);
  EXPECT_GT(glm::dot(right, camera.right()), 0.0);

  // East, 30 degrees up: world +X and +Y; up is world +Y.
  EXPECT_NEAR(u.sun[0], std::cos(glm::radians(30.0)), 1e-6);
  EXPECT_NEAR(u.sun[1], 0.5, 1e-6);
  EXPECT_NEAR(u.sun[2], 0.0, 1e-6);
  EXPECT_EQ(u.sun[3], 1.0f);
  EXPECT_EQ(u.up[1], 1.0f);
  EXPECT_EQ(u.view[0], float(w));
  EXPECT_EQ(u.view[2], settings.exposure);

  settings.enabled = false;
  EXPECT_EQ(pc::sky_uniforms(settings, view_proj, w, h).sun[3], 0.0f);  // the plain background
}
