#pragma once
// Potree 2.0 (PotreeConverter 2: metadata.json, hierarchy.bin, octree.bin) as a streamed source,
// the way COPC is one (copc.hpp): the octree becomes an io::Tileset that the 3D Tiles traversal
// and streamer serve unchanged. Every node is a tile (its cube, geometric error = spacing /
// 2^depth, additive refinement) whose content is its byte range of octree.bin; every hierarchy
// chunk is a tile's pending children, read when a traversal reaches it (a proxy node names the
// chunk that lists it again with its descendants). Local files and http(s) alike (byte ranges).
//
// hierarchy.bin: chunks of 22-byte records (type u8: 0 normal, 1 leaf, 2 proxy; child mask u8,
// bit i = child i; points u32; byte offset u64; byte size u64), breadth first from the chunk's
// root; a proxy's offset and size locate its chunk in hierarchy.bin. Child i of a node is the
// octant x = bit 2, y = bit 1, z = bit 0 of i. octree.bin, encoding DEFAULT: a node is its points'
// records one after the other, the attributes of metadata.json in order; position is int32 x 3,
// scale and offset applied. BROTLI encoding is refused by name.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/pnts.hpp"
#include "stipple/io/tileset.hpp"

namespace stipple::io {

struct PotreeAttribute {
  std::string name;  // as Potree names them: position, rgb, intensity, gps-time, ...
  std::string type;  // int8 ... uint64, float, double
  int elements = 1, element_size = 1, size = 1;
  size_t offset = 0;  // in the point record
  glm::dvec3 min{0.0}, max{0.0};
};

struct PotreeCloud {
  std::string uri;                         // metadata.json
  std::string hierarchy_uri, octree_uri;   // beside it
  std::string name, projection, encoding;  // encoding: DEFAULT
  uint64_t points = 0;
  glm::dvec3 scale{1.0}, offset{0.0};
  glm::dvec3 cube_min{0.0}, cube_max{0.0};  // boundingBox: the octree's root cube
  glm::dvec3 data_min{0.0}, data_max{0.0};  // the points' bounds (position min/max)
  double spacing = 0;
  uint64_t first_chunk_size = 0;
  int step_size = 0, depth = 0;
  std::vector<PotreeAttribute> attributes;
  size_t record_size = 0;
};

// Deepest level accepted (2^30 cells an axis would already be absurd).
constexpr int kMaxPotreeDepth = 30;

// Whether `uri` is a Potree 2.0 cloud: a path or URL whose file name is metadata.json.
bool is_potree_input(const std::string& uri);

// Parses metadata.json. Throws stipple::Error naming the file and the problem.
std::shared_ptr<const PotreeCloud> parse_potree_metadata(std::span<const uint8_t> json,
                                                         const std::string& uri);

Tileset load_potree_tileset(const std::string& uri, const Fetcher& fetcher,
                            const TilesetOptions& options = {});

// Reads the hierarchy chunk that `pending` names (read_children calls this for its kind).
Expansion read_potree_chunk(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                            const Fetcher& fetcher, const TilesetOptions& options);

// A node's bytes of octree.bin (its range URI carries its point count) decoded into points
// relative to the node's points' centre: colour, and intensity, classification, return number
// and count, GPS time and every other attribute as PointAttribute under Potree's name.
PointContent decode_potree_node(const PotreeCloud& cloud, std::span<const uint8_t> bytes,
                                const std::string& uri, const DecodeLimits& limits = {});

}  // namespace stipple::io
