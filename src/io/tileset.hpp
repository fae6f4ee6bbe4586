#pragma once
// 3D Tiles 1.0/1.1 tileset.json: the tile tree flattened into one array, with external tilesets
// and implicit tiling (subtree files) expanded when loaded, transforms accumulated and every
// bounding volume turned into an oriented box in the tileset's frame (ECEF or local, Z-up).
#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "io/fetch.hpp"

namespace stipple::io {

enum class Refine : uint8_t { Add, Replace };

struct BoundingVolume {
  enum class Kind : uint8_t { Box, Sphere, Region } kind = Kind::Box;
  std::array<double, 12> box{};    // centre, then x, y, z half-axis vectors
  std::array<double, 4> sphere{};  // centre, radius
  std::array<double, 6> region{};  // west, south, east, north (radians), min, max height (m)
};

// An oriented box (centre and half-axis vectors as columns); spheres keep their radius too.
struct Obb {
  glm::dvec3 center{0.0};
  glm::dmat3 half_axes{0.0};
  double sphere_radius = -1.0;  // >= 0 when the volume is a sphere
  double radius() const;        // of the bounding sphere
  // Distance from a point to the volume (0 inside).
  double distance(const glm::dvec3& p) const;
};

Obb obb_of(const BoundingVolume& volume, const glm::dmat4& transform);

struct Tile {
  BoundingVolume volume;      // as declared, in the tile's frame
  Obb box;                    // in the tileset frame (transforms applied)
  glm::dmat4 transform{1.0};  // tile frame -> tileset frame (the chain of transforms)
  double geometric_error = 0.0;
  Refine refine = Refine::Replace;
  std::vector<std::string> contents;  // resolved URIs of renderable content (pnts, glb, ...)
  int32_t parent = -1;
  std::vector<uint32_t> children;
  uint32_t depth = 0;
  std::string error;  // what failed to load below this tile (external tileset, subtree)
};

struct TilesetOptions {
  FetchOptions fetch;
  size_t max_tiles = 4'000'000;  // expansion of implicit/external trees stops here
  int max_external_depth = 32;
  uint64_t max_json_bytes = 256ull << 20;
};

struct Tileset {
  std::string uri;
  std::string version;           // asset.version
  double geometric_error = 0.0;  // the tileset's own
  std::vector<Tile> tiles;       // tiles[0] is the root; parents come before children
  std::vector<std::string> warnings;
  std::vector<std::string> errors;  // per-tile failures, also in Tile::error
  uint32_t external_tilesets = 0;
  uint32_t subtrees = 0;
  bool implicit = false;
};

using Fetcher = std::function<std::vector<uint8_t>(const std::string& uri)>;

// Loads a tileset from a path or URL, with external tilesets and subtrees through io::fetch.
// A broken root is an Error; a broken external tileset or subtree is recorded on its tile.
Tileset load_tileset(const std::string& uri, const TilesetOptions& options = {});
// The same from bytes already read, fetching what they reference through `fetcher`.
Tileset parse_tileset(std::span<const uint8_t> json_bytes, const std::string& uri,
                      const Fetcher& fetcher, const TilesetOptions& options = {});

// Whether a content URI names a tileset (an external tileset) rather than renderable content.
bool is_tileset_uri(const std::string& uri);

}  // namespace stipple::io
