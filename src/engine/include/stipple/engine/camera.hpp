#pragma once
// CameraPlugin: the main world's cameras (stipple::Camera components, double precision) are
// extracted to their render-world twins with the position and the rotation kept apart (seed 000,
// section 5): Prepare subtracts the position from model matrices in double, and the view matrix
// the GPU gets is rotation only.
#include <array>
#include <string_view>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "stipple/engine/registry.hpp"
#include "stipple/math/camera.hpp"

namespace stipple {

class Engine;

// Render-world component on a camera's twin.
struct ExtractedCamera {
  glm::dvec3 position{0.0};                 // world space, double
  glm::dquat rotation{1.0, 0.0, 0.0, 0.0};  // camera-to-world
  glm::dmat4 view_rotation{1.0};            // world-to-view, rotation only
  double fov_y = 0;
  double near_plane = 0;
};

// The render world's camera (the first extracted one), or null before any was extracted.
const ExtractedCamera* first_extracted_camera(Registry& render);
// An extracted camera as a math::Camera (position and rotation apart, as extracted).
Camera to_camera(const ExtractedCamera& c);

// The camera-relative model matrix for the GPU: translation minus camera position in double,
// then cast to float.
glm::mat4 camera_relative_model(const glm::dmat4& model, const glm::dvec3& camera_position);

// With TransformPlugin, a camera entity that has a GlobalTransform takes its pose from it
// (translation and rotation; scale ignored); otherwise from Camera::position/orientation.
void extract_cameras(Registry& main);

struct CameraPlugin {
  static constexpr std::string_view name = "CameraPlugin";
  static constexpr std::string_view description =
      "Camera in the main world, ExtractedCamera (position and rotation apart) in the render world";
  static constexpr std::array<std::string_view, 1> optional_dependencies{"TransformPlugin"};
  void build(Engine& engine);
};

}  // namespace stipple
