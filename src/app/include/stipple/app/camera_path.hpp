#pragma once
// The camera path of seed 002's measurements (section IV-B): an orbit around the data's centre
// while the vertical field of view zooms in and out, shared by the benches that fly it
// (`bench virtual`, `bench stream`), and the path's command-line options.
#include <CLI/CLI.hpp>

#include "stipple/math/aabb.hpp"
#include "stipple/math/camera.hpp"

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

// FPS of the slowest `fraction` of frames (the "1% low") from frame times in ms.
double low_fps(std::vector<double> ms, double fraction);

}  // namespace stipple::app
