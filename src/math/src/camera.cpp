#include "stipple/math/camera.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
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

ViewFit::ViewFit(uint32_t width, uint32_t height, double azimuth_deg, double elevation_deg,
                 double fov_y_deg) {
  fov_y_ = glm::radians(fov_y_deg);
  const double w = std::max(1u, width), h = std::max(1u, height);
  const double margin_x = std::max(0.05, 8.0 / w), margin_y = std::max(0.05, 8.0 / h);
  tan_y_ = std::tan(fov_y_ * 0.5) * std::max(0.1, 1.0 - 2.0 * margin_y);
  tan_x_ = std::tan(fov_y_ * 0.5) * (w / h) * std::max(0.1, 1.0 - 2.0 * margin_x);
  const double az = glm::radians(azimuth_deg), el = glm::radians(elevation_deg);
  // From the data towards the eye, Z-up: south-west of it and above (as frame_box).
  const glm::dvec3 to_eye =
      z_up_to_y_up({-std::sin(az) * std::cos(el), -std::cos(az) * std::cos(el), std::sin(el)});
  Camera c;
  c.look_at(to_eye, glm::dvec3(0.0));
  orientation_ = c.orientation;
  right_ = c.right(), up_ = c.up(), forward_ = c.forward();
}

// A point is inside the pyramid of a camera at e when, with x = right.(p - e), y = up.(p - e)
// and depth z = forward.(p - e), |x| <= tan_x z and |y| <= tan_y z: four half-spaces for e,
// each bounded by the largest of one linear function over the points.
ViewFit::Sides ViewFit::sides(const glm::dvec3& p) const {
  const double x = glm::dot(right_, p), y = glm::dot(up_, p), z = glm::dot(forward_, p);
  return {x - tan_x_ * z, -x - tan_x_ * z, y - tan_y_ * z, -y - tan_y_ * z};
}

void ViewFit::add(const glm::dvec3& p) {
  const Sides s = sides(p);
  const double values[4] = {s.right, s.left, s.top, s.bottom};
  double* maxima[4] = {&max_.right, &max_.left, &max_.top, &max_.bottom};
  for (int i = 0; i < 4; ++i)
    if (values[i] > *maxima[i]) {
      *maxima[i] = values[i];
      touching_[i] = p;
    }
  nearest_ = std::min(nearest_, glm::dot(forward_, p));
  extent_.extend(p);
}

void ViewFit::add_corners(const Aabb& box) {
  if (box.empty()) return;
  for (int i = 0; i < 8; ++i)
    add({(i & 1) ? box.max.x : box.min.x, (i & 2) ? box.max.y : box.min.y,
         (i & 4) ? box.max.z : box.min.z});
}

bool ViewFit::could_widen(const Aabb& box) const {
  if (box.empty()) return false;
  // A linear function's largest value over a box is at a corner.
  for (int i = 0; i < 8; ++i) {
    const Sides s = sides({(i & 1) ? box.max.x : box.min.x, (i & 2) ? box.max.y : box.min.y,
                           (i & 4) ? box.max.z : box.min.z});
    if (s.right > max_.right || s.left > max_.left || s.top > max_.top || s.bottom > max_.bottom)
      return true;
  }
  return false;
}

Camera ViewFit::camera() const {
  const Aabb framed = framed_extent(extent_);
  if (framed.min != extent_.min || framed.max != extent_.max) {
    // No extent to fit: a few metres around the data (framed_extent).
    ViewFit wider = *this;
    wider.max_ = {-1e300, -1e300, -1e300, -1e300};  // (touching_ is rewritten with them)
    wider.nearest_ = 1e300;
    wider.extent_ = Aabb{};
    wider.add_corners(framed);
    return wider.camera();
  }
  Camera c;
  c.fov_y = fov_y_;
  c.orientation = orientation_;
  if (extent_.empty()) return c;
  // The eye's coordinates along right, up and forward: each pair of opposite sides touches the
  // data at one depth; the farther of the two pairs' depths shows all of it.
  // Data spread along the view direction only (a line of points seen end-on) would put the eye
  // on its nearest point: it is kept at least 1% of the data's size in front of it. Backing
  // away only loosens the four constraints, so the centring below still holds.
  const double span = glm::length(extent_.size());
  const double z = std::min({-(max_.right + max_.left) / (2.0 * tan_x_),
                             -(max_.top + max_.bottom) / (2.0 * tan_y_), nearest_ - 0.01 * span});
  // Across, the points touching opposite sides are put at opposite places of the image (the
  // pair that set the depth is so already): the data centred in pixels, not in metres.
  auto centred = [&](const glm::dvec3& axis, const glm::dvec3& a, const glm::dvec3& b) {
    const double da = glm::dot(forward_, a) - z, db = glm::dot(forward_, b) - z;
    const double xa = glm::dot(axis, a), xb = glm::dot(axis, b);
    return da + db > 0 ? (xa * db + xb * da) / (da + db) : 0.5 * (xa + xb);
  };
  const double x = centred(right_, touching_[0], touching_[1]);
  const double y = centred(up_, touching_[2], touching_[3]);
  c.position = right_ * x + up_ * y + forward_ * z;
  const double distance = glm::dot(forward_, extent_.center()) - z;
  c.near_plane = std::max(distance * 1e-4, std::min(1e-3, 0.5 * (nearest_ - z)));
  return c;
}

glm::dvec3 cursor_ray(const Camera& camera, const glm::dvec2& cursor, const glm::dvec2& viewport) {
  double aspect = viewport.x / std::max(viewport.y, 1.0);
  double t = std::tan(camera.fov_y * 0.5);
  double x = (2.0 * cursor.x / std::max(viewport.x, 1.0) - 1.0) * t * aspect;
  double y = (1.0 - 2.0 * cursor.y / std::max(viewport.y, 1.0)) * t;
  return glm::normalize(camera.orientation * glm::dvec3(x, y, -1.0));
}

}  // namespace stipple
