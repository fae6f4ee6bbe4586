#pragma once
// Orbit and fly cameras driven by an InputState: pure functions (unit-tested without a window)
// plus CameraControllerPlugin, which applies them to the main world's camera each Update.
//
// Orbit: left drag rotates around the pivot, right or middle drag pans, the wheel zooms towards
// the point under the cursor. Fly: WASD moves, Q/E down/up, shift is faster, dragging with a
// mouse button looks around. F or Tab switches; a double click centres the view on the point
// under the cursor (the nearest point along the ray, CPU side, from whichever scene plugins
// registered a picker in ScenePickers: app/picking.hpp).
#include <array>
#include <string_view>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "stipple/math/aabb.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/platform/input.hpp"

namespace stipple {
class Engine;
}

namespace stipple::viewer {

enum class CameraMode { Orbit, Fly };

// Main-world component on the camera entity. The pose is yaw/pitch of the view direction
// (yaw 0, pitch 0 looks along -Z; yaw turns towards +X, pitch up towards +Y) and the position;
// in orbit mode position = pivot - forward * distance.
struct CameraController {
  CameraMode mode = CameraMode::Orbit;
  glm::dvec3 position{0.0};
  double yaw = 0, pitch = 0;  // radians
  glm::dvec3 pivot{0.0};
  double distance = 1;
  double scene_size = 100;           // scales fly speed and the zoom limits
  double rotate_speed = 0.005;       // radians per pixel
  double fly_speed_fraction = 0.15;  // of scene_size per second
  double zoom_step = 0.85;           // distance factor per wheel notch
};

glm::dvec3 forward_from(double yaw, double pitch);
glm::dquat orientation_from(double yaw, double pitch);
// A controller matching a camera pose, orbiting `pivot` (projected onto the view ray).
CameraController controller_from_camera(const Camera& camera, const glm::dvec3& pivot,
                                        double scene_size);
// Writes position and orientation into the camera.
void apply_controller(const CameraController& c, Camera& camera);

// One frame of input. `viewport` is the window size in cursor units; dt in seconds.
void update_orbit(CameraController& c, const platform::InputState& input, double fov_y,
                  const glm::dvec2& viewport);
void update_fly(CameraController& c, const platform::InputState& input, double dt);
void toggle_mode(CameraController& c);
// Keeps the camera where it is and turns it to look at `point`, which becomes the pivot.
void focus_on(CameraController& c, const glm::dvec3& point);
// Everything of a frame: mode toggle keys, then the mode's update.
void update_controller(CameraController& c, const platform::InputState& input, double dt,
                       double fov_y, const glm::dvec2& viewport);

// Main-world resource: whether the UI wants the mouse or keyboard this frame (cameras ignore
// them then). Written by the UI plugin.
struct UiCapture {
  bool mouse = false;
  bool keyboard = false;
  // A measuring tool owns clicks this frame: no double-click focus (the tools plugin sets it).
  bool double_click = false;
};

struct CameraControllerPlugin {
  static constexpr std::string_view name = "CameraControllerPlugin";
  static constexpr std::string_view description =
      "orbit and fly camera from input; double click focuses the point under the cursor";
  static constexpr std::array<std::string_view, 3> dependencies{"InputPlugin", "WindowPlugin",
                                                                "CameraPlugin"};
  static constexpr std::array<std::string_view, 5> optional_dependencies{
      "TimePlugin", "PointCloudPlugin", "VirtualPointCloudPlugin", "TilesetPlugin", "UiPlugin"};
  // finish() attaches a controller to every Camera entity without one, orbiting the centre of
  // SceneInfo's bounds when a scene plugin (point clouds or a tileset) is there.
  void build(Engine& engine);
  void finish(Engine& engine);
};

}  // namespace stipple::viewer
