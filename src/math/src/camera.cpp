#include "stipple/math/camera.hpp"

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

namespace stipple {

void Camera::look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up_hint) {
  position = eye;
  glm::dvec3 f = glm::normalize(target - eye);
  glm::dvec3 up_dir =
      std::abs(glm::dot(f, glm::normalize(up_hint))) > 0.999 ? glm::dvec3(0, 0, -1) : up_hint;
  glm::dvec3 r = glm::normalize(glm::cross(f, up_dir));
  glm::dvec3 u = glm::cross(r, f);
  glm::dmat3 m(r, u, -f);  // columns: camera X, Y, Z in world space
  orientation = glm::quat_cast(m);
}

glm::dmat4 Camera::view_rotation() const {
  return glm::dmat4(glm::transpose(glm::mat3_cast(orientation)));
}

glm::dmat4 Camera::projection(double aspect) const {
  double f = 1.0 / std::tan(fov_y * 0.5);
  glm::dmat4 p(0.0);
  p[0][0] = f / aspect;
  p[1][1] = f;
  p[2][3] = -1.0;        // w = -z_view
  p[3][2] = near_plane;  // z = near, so depth = near / -z_view
  return p;
}

glm::dmat4 Camera::view_projection(double aspect) const {
  return projection(aspect) * view_rotation() * glm::translate(glm::dmat4(1.0), -position);
}

Aabb framed_extent(const Aabb& box) {
  if (box.empty()) return box;
  const glm::dvec3 size = box.size();
  if (std::max({size.x, size.y, size.z}) >= kDegenerateExtent) return box;
  const glm::dvec3 c = box.center(), half(kDegenerateFrame * 0.5);
  return {c - half, c + half};
}

Camera frame_box(const Aabb& data_box, double aspect, double azimuth_deg, double elevation_deg,
                 double fov_y_deg) {
  const Aabb box = framed_extent(data_box);
  Camera camera;
  camera.fov_y = glm::radians(fov_y_deg);
  glm::dvec3 center = box.center();
  double radius = std::max(glm::length(box.size()) * 0.5, 1e-3);
  double az = glm::radians(azimuth_deg), el = glm::radians(elevation_deg);
  // Direction from the centre to the eye in the Z-up frame: south-west of the data, above it.
  glm::dvec3 dir_z_up(-std::sin(az) * std::cos(el), -std::cos(az) * std::cos(el), std::sin(el));
  glm::dvec3 dir = z_up_to_y_up(dir_z_up);
  // The closest distance at which all eight corners project inside 95% of the view. Fitting the
  // corners rather than the bounding sphere frames flat scans (wide, low boxes) much tighter.
  const double tan_y = std::tan(camera.fov_y * 0.5) * 0.95, tan_x = tan_y * aspect;
  auto fits = [&](double distance) {
    Camera c;
    c.look_at(center + dir * distance, center);
    glm::dmat4 view = c.view_rotation();
    for (int i = 0; i < 8; ++i) {
      glm::dvec3 corner((i & 1) ? box.max.x : box.min.x, (i & 2) ? box.max.y : box.min.y,
                        (i & 4) ? box.max.z : box.min.z);
      glm::dvec4 v = view * glm::dvec4(corner - c.position, 1.0);
      double depth = -v.z;
      if (depth <= 0 || std::abs(v.x) > depth * tan_x || std::abs(v.y) > depth * tan_y)
        return false;
    }
    return true;
  };
  double lo = 0.0, hi = radius / std::sin(std::min(std::atan(tan_x), std::atan(tan_y))) * 1.01;
  for (int i = 0; i < 60; ++i) {
    double mid = 0.5 * (lo + hi);
    (fits(mid) ? hi : lo) = mid;
  }
  camera.look_at(center + dir * hi, center);
  camera.near_plane = std::max(hi * 1e-4, 1e-3);
  return camera;
}

}  // namespace stipple
