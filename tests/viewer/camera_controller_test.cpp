// Viewer logic without a window: input folding (double clicks), orbit and fly cameras, the
// point budget's chunk choice and CPU picking.
#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "stipple/platform/input.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/viewer/camera_controller.hpp"

using namespace stipple;
using namespace stipple::viewer;
using namespace stipple::pc;
using platform::InputEvent;
using platform::InputState;
using platform::Key;
using platform::MouseButton;

namespace {

InputEvent button(MouseButton b, bool down, double time) {
  InputEvent e;
  e.type = InputEvent::Type::MouseButton;
  e.code = int(b);
  e.down = down;
  e.time = time;
  return e;
}
InputEvent cursor(double x, double y) {
  InputEvent e;
  e.type = InputEvent::Type::CursorMove;
  e.value = {x, y};
  return e;
}
InputEvent key(Key k, bool down) {
  InputEvent e;
  e.type = InputEvent::Type::Key;
  e.code = int(k);
  e.down = down;
  return e;
}
InputEvent scroll(double y) {
  InputEvent e;
  e.type = InputEvent::Type::Scroll;
  e.value = {0, y};
  return e;
}

// A held left button dragged by (dx, dy) this frame.
InputState drag(MouseButton b, double dx, double dy) {
  InputState s;
  platform::apply_events(s, std::vector{cursor(400, 300), button(b, true, 0)});
  platform::apply_events(s, std::vector{cursor(400 + dx, 300 + dy)});
  return s;
}

CameraController orbit_controller() {
  Camera camera;
  camera.look_at({0, 50, 100}, {0, 0, 0});
  return controller_from_camera(camera, {0, 0, 0}, 100);
}

const glm::dvec2 kViewport{800, 600};
const double kFov = glm::radians(60.0);

}  // namespace

TEST(Input, FoldsEventsPerFrame) {
  InputState s;
  platform::apply_events(s, std::vector{key(Key::W, true), cursor(10, 20), scroll(2)});
  EXPECT_TRUE(s.down(Key::W));
  EXPECT_TRUE(s.pressed(Key::W));
  EXPECT_EQ(s.scroll.y, 2);
  platform::apply_events(s, std::vector{cursor(15, 20)});
  EXPECT_TRUE(s.down(Key::W));      // still held
  EXPECT_FALSE(s.pressed(Key::W));  // pressed only in its frame
  EXPECT_EQ(s.scroll.y, 0);
  EXPECT_EQ(s.cursor_delta, glm::dvec2(5, 0));
  platform::apply_events(s, std::vector{key(Key::W, false)});
  EXPECT_FALSE(s.down(Key::W));
  EXPECT_TRUE(s.key_released[size_t(Key::W)]);
}

TEST(Input, DoubleClickNeedsTwoQuickNearbyPresses) {
  InputState s;
  platform::apply_events(s, std::vector{cursor(100, 100), button(MouseButton::Left, true, 1.0),
                                        button(MouseButton::Left, false, 1.05)});
  EXPECT_FALSE(s.double_clicked);
  platform::apply_events(s, std::vector{button(MouseButton::Left, true, 1.2)});
  EXPECT_TRUE(s.double_clicked);
  EXPECT_EQ(s.double_click_position, glm::dvec2(100, 100));
  // Too slow.
  platform::apply_events(s, std::vector{button(MouseButton::Left, true, 3.0)});
  platform::apply_events(s, std::vector{button(MouseButton::Left, true, 3.5)});
  EXPECT_FALSE(s.double_clicked);
  // Too far apart.
  platform::apply_events(s, std::vector{button(MouseButton::Left, true, 5.0)});
  platform::apply_events(s, std::vector{cursor(120, 100), button(MouseButton::Left, true, 5.1)});
  EXPECT_FALSE(s.double_clicked);
}

TEST(Input, LosingFocusReleasesEverything) {
  InputState s;
  platform::apply_events(s, std::vector{key(Key::A, true), button(MouseButton::Right, true, 0)});
  InputEvent focus;
  focus.type = InputEvent::Type::Focus;
  focus.down = false;
  platform::apply_events(s, std::vector{focus});
  EXPECT_FALSE(s.down(Key::A));
  EXPECT_FALSE(s.down(MouseButton::Right));
}

TEST(OrbitCamera, MatchesTheCameraItStartsFrom) {
  Camera camera;
  camera.look_at({30, 40, 100}, {0, 0, 0});
  CameraController c = controller_from_camera(camera, {0, 0, 0}, 100);
  Camera applied = camera;
  apply_controller(c, applied);
  EXPECT_NEAR(glm::distance(applied.position, camera.position), 0, 1e-9);
  EXPECT_NEAR(glm::dot(applied.forward(), camera.forward()), 1, 1e-12);
  EXPECT_NEAR(glm::distance(c.pivot, glm::dvec3(0)), 0, 1e-9);
}

TEST(OrbitCamera, LeftDragRotatesAroundThePivot) {
  CameraController c = orbit_controller();
  double distance = c.distance;
  glm::dvec3 before = c.position;
  update_orbit(c, drag(MouseButton::Left, 50, 0), kFov, kViewport);
  EXPECT_NEAR(glm::distance(c.position, c.pivot), distance, 1e-9);
  EXPECT_NEAR(glm::distance(c.pivot, glm::dvec3(0)), 0, 1e-9);
  EXPECT_GT(glm::distance(c.position, before), 1.0);
  EXPECT_NEAR(c.position.y, before.y, 1e-9);  // horizontal drag: same height
  // Pitch stops short of the poles.
  for (int i = 0; i < 100; ++i) update_orbit(c, drag(MouseButton::Left, 0, 100), kFov, kViewport);
  EXPECT_LT(std::abs(c.pitch), glm::radians(89.0) + 1e-12);
  EXPECT_NEAR(glm::distance(c.position, c.pivot), distance, 1e-9);
}

TEST(OrbitCamera, RightOrMiddleDragPansInTheViewPlane) {
  for (MouseButton b : {MouseButton::Right, MouseButton::Middle}) {
    CameraController c = orbit_controller();
    glm::dvec3 forward = forward_from(c.yaw, c.pitch);
    double yaw = c.yaw, pitch = c.pitch;
    update_orbit(c, drag(b, -40, 25), kFov, kViewport);
    glm::dvec3 moved = c.pivot - glm::dvec3(0);
    EXPECT_GT(glm::length(moved), 1.0);
    EXPECT_NEAR(glm::dot(moved, forward), 0, 1e-9);  // perpendicular to the view
    EXPECT_EQ(c.yaw, yaw);
    EXPECT_EQ(c.pitch, pitch);
    // Dragging left moves the scene left: the camera goes right.
    Camera cam;
    apply_controller(c, cam);
    EXPECT_GT(glm::dot(moved, cam.right()), 0);
    // A pixel of drag moves the pivot by a pixel's worth at the pivot's depth.
    double world_per_pixel = 2 * c.distance * std::tan(kFov / 2) / kViewport.y;
    EXPECT_NEAR(glm::length(moved), std::hypot(40, 25) * world_per_pixel, 1e-9);
  }
}

TEST(OrbitCamera, WheelZoomsTowardsTheCursor) {
  // At the centre of the view: straight towards the pivot.
  CameraController c = orbit_controller();
  double distance = c.distance;
  InputState s;
  platform::apply_events(s, std::vector{cursor(kViewport.x / 2, kViewport.y / 2), scroll(1)});
  update_orbit(c, s, kFov, kViewport);
  EXPECT_NEAR(c.distance, distance * c.zoom_step, 1e-9);
  EXPECT_NEAR(glm::distance(c.pivot, glm::dvec3(0)), 0, 1e-9);

  // Off centre: the point under the cursor at the pivot's depth stays under the cursor.
  c = orbit_controller();
  Camera before;
  before.fov_y = kFov;
  apply_controller(c, before);
  glm::dvec2 at(650, 180);
  glm::dvec3 ray = cursor_ray(before, at, kViewport);
  glm::dvec3 anchor = before.position + ray * (c.distance / glm::dot(ray, before.forward()));
  s = {};
  platform::apply_events(s, std::vector{cursor(at.x, at.y), scroll(2)});
  update_orbit(c, s, kFov, kViewport);
  Camera after = before;
  apply_controller(c, after);
  glm::dvec3 ray_after = cursor_ray(after, at, kViewport);
  glm::dvec3 to_anchor = glm::normalize(anchor - after.position);
  EXPECT_NEAR(glm::dot(ray_after, to_anchor), 1.0, 1e-9);
  EXPECT_LT(glm::distance(after.position, anchor), glm::distance(before.position, anchor));
  // Zooming out scales the other way.
  s = {};
  platform::apply_events(s, std::vector{cursor(at.x, at.y), scroll(-2)});
  update_orbit(c, s, kFov, kViewport);
  EXPECT_NEAR(c.distance, distance, 1e-6);
}

TEST(FlyCamera, WasdQeMovesAndShiftIsFaster) {
  CameraController c = orbit_controller();
  toggle_mode(c);
  ASSERT_EQ(c.mode, CameraMode::Fly);
  Camera cam;
  apply_controller(c, cam);
  glm::dvec3 start = c.position;
  InputState s;
  platform::apply_events(s, std::vector{key(Key::W, true)});
  update_fly(c, s, 0.5);
  glm::dvec3 step = c.position - start;
  EXPECT_NEAR(glm::dot(glm::normalize(step), cam.forward()), 1.0, 1e-12);
  double slow = glm::length(step);
  EXPECT_NEAR(slow, c.scene_size * c.fly_speed_fraction * 0.5, 1e-9);
  platform::apply_events(s, std::vector{key(Key::LeftShift, true)});
  glm::dvec3 p = c.position;
  update_fly(c, s, 0.5);
  EXPECT_NEAR(glm::length(c.position - p), slow * 5, 1e-9);

  s = {};
  platform::apply_events(s, std::vector{key(Key::E, true)});
  p = c.position;
  update_fly(c, s, 1.0);
  EXPECT_GT(c.position.y, p.y);
  EXPECT_NEAR(c.position.x, p.x, 1e-12);
  s = {};
  platform::apply_events(s, std::vector{key(Key::A, true)});
  p = c.position;
  update_fly(c, s, 1.0);
  EXPECT_LT(glm::dot(c.position - p, cam.right()), 0);
}

TEST(FlyCamera, DragLooksAroundWithoutMoving) {
  CameraController c = orbit_controller();
  toggle_mode(c);
  glm::dvec3 p = c.position;
  double yaw = c.yaw;
  update_fly(c, drag(MouseButton::Left, 30, 0), 0.1);
  EXPECT_EQ(c.position, p);
  EXPECT_GT(c.yaw, yaw);  // turns right with the cursor
}

TEST(CameraModes, TogglingKeepsThePoseAndFKeySwitches) {
  CameraController c = orbit_controller();
  InputState s;
  platform::apply_events(s, std::vector{key(Key::F, true)});
  glm::dvec3 p = c.position;
  update_controller(c, s, 0.016, kFov, kViewport);
  EXPECT_EQ(c.mode, CameraMode::Fly);
  EXPECT_NEAR(glm::distance(c.position, p), 0, 1e-9);
  platform::apply_events(s, std::vector{key(Key::F, false), key(Key::Tab, true)});
  update_controller(c, s, 0.016, kFov, kViewport);
  EXPECT_EQ(c.mode, CameraMode::Orbit);
  EXPECT_NEAR(glm::distance(c.position, p), 0, 1e-9);
}

TEST(CameraModes, FocusLooksAtThePointFromWhereTheCameraIs) {
  CameraController c = orbit_controller();
  glm::dvec3 p = c.position;
  focus_on(c, {10, 0, -5});
  EXPECT_NEAR(glm::distance(c.position, p), 0, 1e-9);
  EXPECT_EQ(c.pivot, glm::dvec3(10, 0, -5));
  glm::dvec3 expected = glm::normalize(glm::dvec3(10, 0, -5) - p);
  EXPECT_NEAR(glm::dot(forward_from(c.yaw, c.pitch), expected), 1.0, 1e-12);
}

TEST(PointBudget, NearestChunksFirstWithinTheBudget) {
  std::vector<Aabb> bounds = {
      {{100, 0, 0}, {101, 1, 1}}, {{0, 0, 0}, {1, 1, 1}}, {{10, 0, 0}, {11, 1, 1}}};
  std::vector<uint32_t> counts = {100, 100, 100};
  EXPECT_EQ(select_chunks(bounds, counts, {0, 0, 0}, 0), (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(select_chunks(bounds, counts, {0, 0, 0}, 250), (std::vector<uint32_t>{1, 2}));
  EXPECT_EQ(select_chunks(bounds, counts, {200, 0, 0}, 100), (std::vector<uint32_t>{0}));
  EXPECT_TRUE(select_chunks(bounds, counts, {0, 0, 0}, 50).empty());
}

TEST(Picking, NearestPointAlongTheRay) {
  pc::PointCloud cloud;
  cloud.chunks.resize(2);
  cloud.chunks[0].origin = {0, 0, -10};
  cloud.chunks[0].vertices = {{0, 0, 0, 0}, {5, 0, 0, 0}};  // (0,0,-10), (5,0,-10)
  cloud.chunks[1].origin = {0, 0, -20};
  cloud.chunks[1].vertices = {{0.05f, 0, 0, 0}, {0, 0, -1, 0}};  // (0.05,0,-20), (0,0,-21)
  PointCloudData data;
  data.chunk_bounds = chunk_bounds(cloud);
  data.cloud = std::make_shared<const pc::PointCloud>(std::move(cloud));
  auto hit = pick_point(data, {0, 0, 0}, {0, 0, -1}, 0.01);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(glm::distance(*hit, glm::dvec3(0, 0, -10)), 0, 1e-6);
  // Behind the camera nothing is hit; off to the side only within the cone.
  EXPECT_FALSE(pick_point(data, {0, 0, 0}, {0, 0, 1}, 0.01));
  // From z = -15: (0.05, 0, -20) is 0.05 off the axis at distance 5, (0, 0, -21) on it.
  hit = pick_point(data, {0, 0, -15}, {0, 0, -1}, 0.02);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->x, 0.05, 1e-6);
  hit = pick_point(data, {0, 0, -15}, {0, 0, -1}, 0.005);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->z, -21, 1e-6);
}
