#pragma once
// Entwine Point Tile (EPT 1.x: ept.json, ept-hierarchy/D-X-Y-Z.json, ept-data/D-X-Y-Z.laz|.bin|
// .zst) as a streamed source, the way COPC and Potree are (copc.hpp, potree.hpp): the octree
// becomes an io::Tileset that the 3D Tiles traversal and streamer serve unchanged. Every node is
// a tile (its cube, geometric error = (bounds width / span) / 2^depth, additive refinement)
// whose content is its data file; every hierarchy file is a tile's pending children, read when
// a traversal reaches the node whose count is -1 in its parent file. Local files and http(s).
//
// Data types: laszip (a LAZ file per node), binary (the schema's dimensions in order, packed,
// little-endian; X, Y, Z integers with scale and offset where the schema gives them), zstandard
// (binary, zstd-compressed).
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/pnts.hpp"
#include "stipple/io/tileset.hpp"

namespace stipple::io {

struct EptDimension {
  std::string name;  // X, Y, Z, Intensity, Red, GpsTime, ...
  std::string type;  // signed, unsigned, float
  int size = 0;      // bytes: 1, 2, 4, 8 (float: 4, 8)
  double scale = 1, offset = 0;
  bool scaled = false;
  size_t at = 0;  // in the binary record
};

struct EptCloud {
  std::string uri;        // ept.json
  std::string version;    // as ept.json gives it: 1.x, or 0.x in the 1.0 layout (early Entwine)
  std::string data_type;  // laszip, binary, zstandard
  uint64_t points = 0;
  glm::dvec3 cube_min{0.0}, cube_max{0.0};  // bounds: the octree's root cube
  glm::dvec3 data_min{0.0}, data_max{0.0};  // boundsConforming
  int span = 0;
  double spacing = 0;  // at the root: width / span
  std::vector<EptDimension> schema;
  size_t record_size = 0;
  std::string wkt;
};

constexpr int kMaxEptDepth = 30;

// Whether `uri` is an EPT dataset: a path or URL whose file name is ept.json.
bool is_ept_input(const std::string& uri);

std::shared_ptr<const EptCloud> parse_ept_metadata(std::span<const uint8_t> json,
                                                   const std::string& uri);

Tileset load_ept_tileset(const std::string& uri, const Fetcher& fetcher,
                         const TilesetOptions& options = {});

// Reads the hierarchy file that `pending` names (read_children calls this for its kind).
Expansion read_ept_hierarchy(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                             const Fetcher& fetcher, const TilesetOptions& options);

// A node's data file (its URI carries its point count) decoded into points relative to their
// centre: colour, intensity, classification, returns, GPS time and every other dimension.
PointContent decode_ept_node(const EptCloud& cloud, std::span<const uint8_t> bytes,
                             const std::string& uri, const DecodeLimits& limits = {});

}  // namespace stipple::io
