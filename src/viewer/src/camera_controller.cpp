#include "stipple/viewer/camera_controller.hpp"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "stipple/engine/engine.hpp"
#include "stipple/engine/time.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/viewer/window_plugins.hpp"

namespace stipple::viewer {
namespace {
constexpr double kMaxPitch = glm::radians(89.0);
using platform::Key;
using platform::MouseButton;
}  // namespace

glm::dvec3 forward_from(double yaw, double pitch) {
  return {std::cos(pitch) * std::sin(yaw), std::sin(pitch), -std::cos(pitch) * std::cos(yaw)};
}

glm::dquat orientation_from(double yaw, double pitch) {
  return glm::angleAxis(-yaw, glm::dvec3(0, 1, 0)) * glm::angleAxis(pitch, glm::dvec3(1, 0, 0));
}

CameraController controller_from_camera(const Camera& camera, const glm::dvec3& pivot,
                                        double scene_size) {
  CameraController c;
  glm::dvec3 f = glm::normalize(camera.forward());
  c.position = camera.position;
  c.pitch = std::asin(std::clamp(f.y, -1.0, 1.0));
  c.yaw = std::atan2(f.x, -f.z);
  c.pitch = std::clamp(c.pitch, -kMaxPitch, kMaxPitch);
  c.scene_size = std::max(scene_size, 1e-6);
  c.distance = std::max(glm::dot(pivot - camera.position, f), c.scene_size * 1e-3);
  c.pivot = c.position + forward_from(c.yaw, c.pitch) * c.distance;
  return c;
}

void apply_controller(const CameraController& c, Camera& camera) {
  camera.position = c.position;
  camera.orientation = orientation_from(c.yaw, c.pitch);
}

void update_orbit(CameraController& c, const platform::InputState& in, double fov_y,
                  const glm::dvec2& viewport) {
  const glm::dvec2 d = in.cursor_delta;
  if (in.down(MouseButton::Left) && !in.pressed(MouseButton::Left)) {
    // The scene follows the cursor: dragging right turns the camera left around the pivot.
    c.yaw -= d.x * c.rotate_speed;
    c.pitch = std::clamp(c.pitch + d.y * c.rotate_speed, -kMaxPitch, kMaxPitch);
  } else if ((in.down(MouseButton::Right) && !in.pressed(MouseButton::Right)) ||
             (in.down(MouseButton::Middle) && !in.pressed(MouseButton::Middle))) {
    // The point under the cursor at the pivot's depth stays under the cursor.
    double world_per_pixel = 2.0 * c.distance * std::tan(fov_y * 0.5) / std::max(viewport.y, 1.0);
    glm::dquat q = orientation_from(c.yaw, c.pitch);
    glm::dvec3 right = q * glm::dvec3(1, 0, 0), up = q * glm::dvec3(0, 1, 0);
    c.pivot += (-right * d.x + up * d.y) * world_per_pixel;
  }
  if (in.scroll.y != 0) {
    // Zoom about the point under the cursor at the pivot's depth: everything scales around it,
    // so that point stays under the cursor.
    double factor = std::pow(c.zoom_step, in.scroll.y);
    double new_distance = std::clamp(c.distance * factor, c.scene_size * 1e-5, c.scene_size * 20);
    factor = new_distance / c.distance;
    Camera camera;
    camera.fov_y = fov_y;
    camera.position = c.pivot - forward_from(c.yaw, c.pitch) * c.distance;
    camera.orientation = orientation_from(c.yaw, c.pitch);
    glm::dvec3 ray = cursor_ray(camera, in.cursor, viewport);
    glm::dvec3 anchor =
        camera.position + ray * (c.distance / std::max(glm::dot(ray, camera.forward()), 1e-6));
    c.pivot = anchor + (c.pivot - anchor) * factor;
    c.distance = new_distance;
  }
  c.position = c.pivot - forward_from(c.yaw, c.pitch) * c.distance;
}

void update_fly(CameraController& c, const platform::InputState& in, double dt) {
  const glm::dvec2 d = in.cursor_delta;
  bool look = (in.down(MouseButton::Left) && !in.pressed(MouseButton::Left)) ||
              (in.down(MouseButton::Right) && !in.pressed(MouseButton::Right));
  if (look) {
    // Mouse look: the view turns the way the cursor moves.
    c.yaw += d.x * c.rotate_speed;
    c.pitch = std::clamp(c.pitch - d.y * c.rotate_speed, -kMaxPitch, kMaxPitch);
  }
  glm::dquat q = orientation_from(c.yaw, c.pitch);
  glm::dvec3 forward = q * glm::dvec3(0, 0, -1), right = q * glm::dvec3(1, 0, 0);
  glm::dvec3 move{0.0};
  if (in.down(Key::W)) move += forward;
  if (in.down(Key::S)) move -= forward;
  if (in.down(Key::D)) move += right;
  if (in.down(Key::A)) move -= right;
  if (in.down(Key::E)) move.y += 1;
  if (in.down(Key::Q)) move.y -= 1;
  if (glm::dot(move, move) > 0) {
    double speed = c.scene_size * c.fly_speed_fraction * (in.shift() ? 5.0 : 1.0);
    c.position += glm::normalize(move) * speed * dt;
  }
  c.pivot = c.position + forward * c.distance;  // orbit resumes in front of the camera
}

void toggle_mode(CameraController& c) {
  if (c.mode == CameraMode::Orbit) {
    c.mode = CameraMode::Fly;
  } else {
    c.mode = CameraMode::Orbit;
    c.pivot = c.position + forward_from(c.yaw, c.pitch) * c.distance;
  }
}

void focus_on(CameraController& c, const glm::dvec3& point) {
  glm::dvec3 to = point - c.position;
  double length = glm::length(to);
  if (length <= 0) return;
  glm::dvec3 f = to / length;
  c.pitch = std::clamp(std::asin(std::clamp(f.y, -1.0, 1.0)), -kMaxPitch, kMaxPitch);
  c.yaw = std::atan2(f.x, -f.z);
  c.pivot = point;
  c.distance = length;
  if (c.mode == CameraMode::Orbit) c.position = c.pivot - forward_from(c.yaw, c.pitch) * length;
}

void update_controller(CameraController& c, const platform::InputState& in, double dt, double fov_y,
                       const glm::dvec2& viewport) {
  if (in.pressed(Key::F) || in.pressed(Key::Tab)) toggle_mode(c);
  if (c.mode == CameraMode::Orbit)
    update_orbit(c, in, fov_y, viewport);
  else
    update_fly(c, in, dt);
}

namespace {

void control_cameras(Registry& main) {
  platform::InputState input = main.resource<platform::InputState>();
  if (const auto* capture = main.try_resource<UiCapture>()) {
    // The UI has them: the camera sees no clicks, drags, wheel or keys.
    if (capture->mouse) {
      input.button_down.fill(false);
      input.button_pressed.fill(false);
      input.scroll = {0.0, 0.0};
      input.double_clicked = false;
    }
    if (capture->keyboard) {
      input.key_down.fill(false);
      input.key_pressed.fill(false);
    }
    if (capture->double_click) input.double_clicked = false;
  }
  const auto* time = main.try_resource<Time>();
  double dt = time ? std::min(time->delta_seconds, 0.1) : 1.0 / 60.0;
  glm::dvec2 viewport(main.resource<WindowState>().window_size);
  main.view<Camera, CameraController>().each([&](Camera& camera, CameraController& c) {
    if (input.double_clicked) {
      // Picking radius: 4 pixels around the cursor.
      double tan_radius = 4.0 * 2.0 * std::tan(camera.fov_y * 0.5) / std::max(viewport.y, 1.0);
      pc::PickRay ray{camera.position, cursor_ray(camera, input.double_click_position, viewport),
                      tan_radius};
      if (auto hit = pc::pick_scene(main, ray)) focus_on(c, hit->point);
    }
    update_controller(c, input, dt, camera.fov_y, viewport);
    apply_controller(c, camera);
    // Keep the near plane useful from close up to far away.
    camera.near_plane = std::max(c.scene_size * 1e-6, std::min(c.distance * 1e-3, 1.0));
  });
}

}  // namespace

void CameraControllerPlugin::build(Engine& engine) {
  engine.add_system(MainStage::Update, control_cameras, "control_cameras");
}

void CameraControllerPlugin::finish(Engine& engine) {
  Registry& main = engine.main();
  glm::dvec3 pivot{0.0};
  double size = 100;
  if (const auto* scene = main.try_resource<pc::SceneInfo>();
      scene && !scene->world_bounds.empty()) {
    pivot = scene->world_bounds.center();
    size = glm::length(scene->world_bounds.size());
  }
  std::vector<Entity> cameras;
  main.view<Camera>().each([&](Entity e, const Camera&) {
    if (!main.has<CameraController>(e)) cameras.push_back(e);
  });
  for (Entity e : cameras)
    main.emplace<CameraController>(e, controller_from_camera(main.get<Camera>(e), pivot, size));
}

}  // namespace stipple::viewer
