#pragma once
// LAS/LAZ -> 3D Tiles, out of core (issue 7). See tiler.cpp for the pipeline.
#include <cstdint>
#include <string>
#include <vector>

namespace stipple::tiler {

enum class Format { Glb, Pnts };

struct TileOptions {
  std::vector<std::string> inputs;
  std::string output;
  Format format = Format::Glb;
  std::string crs;     // e.g. "EPSG:2992": overrides every input's own CRS
  double spacing = 0;  // root spacing in metres; 0: cube edge / 128 (as Potree)
  uint64_t max_memory = 2ull << 30;
  unsigned threads = 0;            // 0: every core
  bool force = false;              // replace an existing output directory
  size_t max_node_points = 60000;  // tile cap: larger nodes are split / subsampled further
  // none, meshopt (glb: EXT_meshopt_compression) or draco (pnts: 3DTILES_draco_point_compression)
  std::string compression = "none";
  // 3D Tiles 1.1 implicit tiling: an octree whose availability is in subtree files of
  // `subtree_levels` levels, instead of every tile listed in tileset.json.
  bool implicit = false;
  int subtree_levels = 6;
};

struct TileStats {
  uint64_t points = 0;  // points read = points written
  uint64_t tiles = 0;
  int depth = 0;      // deepest level
  size_t chunks = 0;  // out-of-core chunks indexed independently
  double root_spacing = 0;
  double seconds = 0;
};

TileStats build_tileset(const TileOptions& options);

// "2G", "512M", "64k", "1000000" -> bytes. Throws stipple::Error on anything else.
uint64_t parse_size(const std::string& text);

}  // namespace stipple::tiler
