#pragma once
// A perspective camera in double precision. Rendering is camera-relative (seed 000, section 5):
// the GPU gets the rotation-only view matrix and positions with the camera subtracted in double.
#include <cstdint>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
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

// Fits a camera looking from a fixed direction (azimuth and elevation as for frame_box) to a set
// of world-space points: the position from which every point projects inside the view less a
// margin, as close as that allows, with the points' projected extent centred (exactly along the
// axis that sets the distance; across it, the two points that bound it are placed symmetric,
// which centres the extent when they are its extremes, as they are in most data). The sides of
// the view pyramid are planes whose normals depend only on the direction, so each point only
// moves four running maxima (exact and order-independent, in one pass); a box whose corners
// cannot move them holds no point that can, which lets a caller skip whole chunks.
class ViewFit {
 public:
  // The margin keeps every point centre at least 5% of the image, and 8 pixels (more than the
  // radius of the largest automatic point size, 12 px), from the edges, so points are not
  // clipped by the image border.
  ViewFit(uint32_t width, uint32_t height, double azimuth_deg = 30.0, double elevation_deg = 40.0,
          double fov_y_deg = 50.0);
  void add(const glm::dvec3& world);
  void add_corners(const Aabb& box);  // the box's eight corners
  // Whether some point inside the box could widen the fit (false: its points need no look).
  bool could_widen(const Aabb& box) const;
  bool empty() const { return extent_.empty(); }
  // The fitted camera. Data of no extent (framed_extent) is fitted as a few metres around it.
  Camera camera() const;

 private:
  struct Sides {
    double right, left, top, bottom;
  };
  Sides sides(const glm::dvec3& p) const;
  double fov_y_ = 0, tan_x_ = 0, tan_y_ = 0;
  glm::dquat orientation_{1.0, 0.0, 0.0, 0.0};
  glm::dvec3 right_{1, 0, 0}, up_{0, 1, 0}, forward_{0, 0, -1};
  Sides max_{-1e300, -1e300, -1e300, -1e300};
  glm::dvec3 touching_[4]{};  // a point that set each of them
  double nearest_ = 1e300;    // the least depth along forward_ (from the origin)
  Aabb extent_;
};

// World-space direction through a cursor position: `cursor` in pixels from the top-left corner
// of a view `viewport` pixels large (any pixels: a window's or a canvas's, as long as both agree).
glm::dvec3 cursor_ray(const Camera& camera, const glm::dvec2& cursor, const glm::dvec2& viewport);

}  // namespace stipple
