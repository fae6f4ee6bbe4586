#include "stipple/app/camera_path.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "stipple/core/error.hpp"

namespace stipple::app {

Camera path_camera(const CameraPath& a, const Aabb& world, double t, double aspect) {
  const double fov =
      a.fov_min + (a.fov_max - a.fov_min) * 0.5 * (1.0 + std::cos(2.0 * M_PI * a.zoom_cycles * t));
  Camera wide = frame_box(world, aspect, 0.0, a.elevation, a.fov_max);
  const double distance = glm::length(wide.position - world.center());
  const double az = 2.0 * M_PI * a.turns * t, el = glm::radians(a.elevation);
  const glm::dvec3 c = world.center();
  const glm::dvec3 eye = c + distance * glm::dvec3(std::cos(el) * std::sin(az), std::sin(el),
                                                   std::cos(el) * std::cos(az));
  Camera camera = wide;
  camera.fov_y = glm::radians(fov);
  camera.look_at(eye, c);
  return camera;
}

void add_camera_path_options(CLI::App* cmd, CameraPath& a) {
  cmd->add_option("--turns", a.turns, "Orbits along the path")->capture_default_str();
  cmd->add_option("--fov-min", a.fov_min, "Narrowest vertical field of view (degrees)")
      ->check(CLI::Range(1.0, 170.0))
      ->capture_default_str();
  cmd->add_option("--fov-max", a.fov_max, "Widest vertical field of view (degrees)")
      ->check(CLI::Range(1.0, 170.0))
      ->capture_default_str();
  cmd->add_option("--zoom-cycles", a.zoom_cycles, "Zoom in and out this often along the path")
      ->capture_default_str();
  cmd->add_option("--elevation", a.elevation, "Camera elevation (degrees)")->capture_default_str();
}

void add_frame_mode_options(CLI::App* cmd, FrameMode& mode) {
  cmd->add_flag("--pipelined", mode.pipelined,
                "Render world on its own thread (drawing frame N while the main world builds "
                "N+1); frames do not wait for the GPU");
  cmd->add_flag("--no-gpu-wait", mode.no_gpu_wait,
                "Frames do not wait for the GPU (timestamps read back later), on one thread");
}

void add_flight_duration_option(CLI::App* cmd, double& seconds) {
  cmd->add_option("--duration", seconds,
                  "Fly the camera path by the clock over this many seconds (the camera at the same "
                  "speed whatever the frame rate) and stop then, even if frames of --frames "
                  "remain (0: the path runs by frame)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
}

std::optional<double> flight_along(double duration_s, double flown_s, uint32_t f, uint32_t frames) {
  if (duration_s <= 0) return double(f) / frames;
  if (f > 0 && flown_s >= duration_s) return std::nullopt;
  return std::min(1.0, flown_s / duration_s);
}

scene::EngineCore bench_engine_core(const std::string& backend, const FrameMode& mode) {
  scene::EngineCore core;
  core.backend = backend;
  core.pipelined = mode.pipelined;
  core.keep_history = true;  // per-frame GPU times
  core.wait_for_gpu = mode.waits_for_gpu();
  core.max_frames_in_flight = 2;
  return core;
}

void check_camera_path(const CameraPath& a) {
  if (a.fov_min > a.fov_max) fail("--fov-min {} exceeds --fov-max {}", a.fov_min, a.fov_max);
}

double low_fps(std::vector<double> ms, double fraction) {
  if (ms.empty()) return 0;
  std::sort(ms.begin(), ms.end(), std::greater<>());
  const size_t n = std::max<size_t>(1, size_t(std::floor(double(ms.size()) * fraction)));
  const double mean = std::accumulate(ms.begin(), ms.begin() + std::ptrdiff_t(n), 0.0) / double(n);
  return mean > 0 ? 1000.0 / mean : 0;
}

}  // namespace stipple::app
