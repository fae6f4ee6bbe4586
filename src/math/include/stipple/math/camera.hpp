#pragma once
// A perspective camera in double precision. Rendering is camera-relative (seed 000, section 5):
// the GPU gets the rotation-only view matrix and positions with the camera subtracted in double.
#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "stipple/math/aabb.hpp"

namespace stipple {

// World space is right-handed and Y-up. Scanned data (LAS, projected CRSs, ENU) is Z-up.
inline glm::dvec3 z_up_to_y_up(const glm::dvec3& p) {
  return {p.x, p.z, -p.y};
}
inline glm::dvec3 y_up_to_z_up(const glm::dvec3& p) {
  return {p.x, -p.z, p.y};
}

struct Camera {
  glm::dvec3 position{0.0};
  glm::dquat orientation{1.0, 0.0, 0.0, 0.0};  // camera-to-world rotation; looks along -Z
  double fov_y = glm::radians(60.0);           // vertical field of view, radians
  double near_plane = 0.1;                     // far plane is at infinity (reverse Z)

  glm::dvec3 forward() const { return orientation * glm::dvec3(0, 0, -1); }
  glm::dvec3 up() const { return orientation * glm::dvec3(0, 1, 0); }
  glm::dvec3 right() const { return orientation * glm::dvec3(1, 0, 0); }
  void look_at(const glm::dvec3& eye, const glm::dvec3& target, const glm::dvec3& up = {0, 1, 0});
  // World-to-view rotation only: R^T of eq. 5; the camera sits at the origin.
  glm::dmat4 view_rotation() const;
  // Reverse-Z, infinite far plane, WebGPU clip space (depth 1 at the near plane, 0 at infinity).
  glm::dmat4 projection(double aspect) const;
  // Full view-projection in double (for CPU-side tests and culling), camera at `position`.
  glm::dmat4 view_projection(double aspect) const;
};

// A box whose every side is under kDegenerateExtent (a single point, or every point at one
// location) has nothing to fit a view to: it is framed as a cube of kDegenerateFrame (metres,
// in the usual data units) around its centre instead, so the points show up mid-image.
inline constexpr double kDegenerateExtent = 1e-3;
inline constexpr double kDegenerateFrame = 5.0;
Aabb framed_extent(const Aabb& box);

// A camera that shows the whole world-space (Y-up) box from an oblique angle: azimuth and
// elevation in degrees, measured in the data's Z-up frame (azimuth 0 = looking north from the
// south), with the box's bounding sphere inside the view.
Camera frame_box(const Aabb& world_box, double aspect, double azimuth_deg = 30.0,
                 double elevation_deg = 40.0, double fov_y_deg = 50.0);

}  // namespace stipple
