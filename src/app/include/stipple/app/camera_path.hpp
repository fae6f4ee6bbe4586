#pragma once
// The camera path of seed 002's measurements (section IV-B): an orbit around the data's centre
// while the vertical field of view zooms in and out, shared by the benches that fly it
// (`bench virtual`, `bench stream`), and the path's command-line options; the frame modes those
// benches run in.
#include <cstdint>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "stipple/math/aabb.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/scene/scene.hpp"

namespace stipple::app {

struct CameraPath {
  double turns = 1.0;                     // orbits over the path
  double fov_min = 20.0, fov_max = 90.0;  // degrees: the zoom
  double zoom_cycles = 2.0;               // zoom in and out this often along the path
  double elevation = 35.0;                // degrees above the horizon
};

// The camera at t in [0, 1): orbiting the centre at the distance that frames `world` at the
// widest field of view, the field of view following a cosine between the limits.
Camera path_camera(const CameraPath& path, const Aabb& world, double t, double aspect);

// --turns, --fov-min, --fov-max, --zoom-cycles, --elevation.
void add_camera_path_options(CLI::App* cmd, CameraPath& path);
// Throws stipple::Error for a path the options cannot mean (a zoom range upside down).
void check_camera_path(const CameraPath& path);

// How a bench's frames run: one after the other, each waiting for the GPU (the default); not
// waiting for it, on one thread (--no-gpu-wait); or with the render world on its own thread
// (--pipelined: seed 000's pipelined mode, frames not waiting for the GPU either).
struct FrameMode {
  bool pipelined = false, no_gpu_wait = false;
  bool waits_for_gpu() const { return !pipelined && !no_gpu_wait; }
  // "sequential", "sequential, no GPU wait" or "pipelined".
  const char* name() const {
    return pipelined ? "pipelined" : (no_gpu_wait ? "sequential, no GPU wait" : "sequential");
  }
};
// --pipelined, --no-gpu-wait.
void add_frame_mode_options(CLI::App* cmd, FrameMode& mode);
// --duration: the path flown by the clock over this many seconds (0: by frame).
void add_flight_duration_option(CLI::App* cmd, double& seconds);
// Where frame f of a flight of `frames` is along the path, `flown_s` seconds after it began: by
// frame, or with a --duration (duration_s > 0) by the clock, the camera at the same speed however
// fast the frames come; nullopt once the duration has passed (never at the first frame).
std::optional<double> flight_along(double duration_s, double flown_s, uint32_t f, uint32_t frames);
// The engine core of a bench in `mode` on `backend`: every frame's GPU times kept, at most two
// frames in flight where frames do not wait for the GPU.
scene::EngineCore bench_engine_core(const std::string& backend, const FrameMode& mode);

// FPS of the slowest `fraction` of frames (the "1% low") from frame times in ms.
double low_fps(std::vector<double> ms, double fraction);

}  // namespace stipple::app
