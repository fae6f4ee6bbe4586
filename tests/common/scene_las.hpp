#pragma once
// Test input: the built-in procedural scan written as a LAS 1.4 (format 7) or LAZ file, the way
// `stipple generate` writes it, for tests of modules that read LAS (io and above).
#include <algorithm>
#include <cstdint>
#include <filesystem>

#include "stipple/io/las.hpp"
#include "stipple/io/procedural.hpp"

namespace stipple::test {

inline std::filesystem::path write_scene_las(const std::filesystem::path& path, uint64_t points,
                                             bool compress = false) {
  io::SceneParams scene;
  scene.point_count = points;
  io::LasWriteOptions o;
  o.version_minor = 4;
  o.point_format = 7;
  o.compress = compress;
  o.scale = {0.001, 0.001, 0.001};
  o.offset = {scene.origin.x, scene.origin.y, 0.0};
  io::LasWriter w(path, o);
  for (uint64_t first = 0; first < points; first += 100000) {
    io::PointBatch b;
    io::generate_scene(scene, first, std::min<uint64_t>(100000, points - first), b);
    w.write(b);
  }
  w.close();
  return path;
}

}  // namespace stipple::test
