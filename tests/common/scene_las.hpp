#pragma once
// Test input: the built-in procedural scan written as a LAS 1.4 (format 7) or LAZ file, the way
// `stipple generate` writes it, for tests of modules that read LAS (io and above).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <vector>

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

// A survey delivered as tiles: the points of `source` cut by position into nx x ny tiles,
// written into `folder` as tile-NN.las (name order is tile order), and `merged` written as the
// tiles one after another: the same points in the order a reader of the tiles sees them. Tiles
// without points are not written. Returns the tiles' paths in name order.
inline std::vector<std::filesystem::path> split_las_into_tiles(
    const std::filesystem::path& source, const std::filesystem::path& folder, int nx, int ny,
    const std::filesystem::path& merged) {
  io::LasReader reader(source);
  const io::LasHeader h = reader.header();
  io::PointBatch all;
  while (reader.read(all, 1 << 20) > 0) {
  }
  io::LasWriteOptions o;
  o.version_minor = h.version_minor < 2 ? 2 : h.version_minor;
  o.point_format = h.point_format;
  o.scale = h.scale;
  o.offset = h.offset;
  std::filesystem::create_directories(folder);
  io::LasWriter whole(merged, o);
  std::vector<std::filesystem::path> tiles;
  const glm::dvec3 size = h.max - h.min;
  for (int t = 0; t < nx * ny; ++t) {
    std::vector<uint8_t> keep(all.size());
    for (size_t i = 0; i < all.size(); ++i) {
      const glm::dvec3 f = (all.positions[i] - h.min) / size;
      const int x = std::clamp(int(f.x * nx), 0, nx - 1), y = std::clamp(int(f.y * ny), 0, ny - 1);
      keep[i] = y * nx + x == t;
    }
    io::PointBatch tile = all;
    tile.compact(keep);
    if (tile.size() == 0) continue;
    char name[32];
    std::snprintf(name, sizeof name, "tile-%02d.las", t);
    io::LasWriter w(folder / name, o);
    w.write(tile);
    w.close();
    whole.write(tile);
    tiles.push_back(folder / name);
  }
  whole.close();
  return tiles;
}

}  // namespace stipple::test
