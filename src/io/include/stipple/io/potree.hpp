#pragma once
// Potree octrees as streamed sources, the way COPC is one (copc.hpp): the octree becomes an
// io::Tileset that the 3D Tiles traversal and streamer serve unchanged. Every node is a tile (its
// cube, geometric error = spacing / 2^depth, additive refinement) whose content is its points;
// every hierarchy file or chunk is a tile's pending children, read when a traversal reaches it.
// Local files and http(s) alike. Child i of a node is the octant x = bit 2, y = bit 1, z = bit 0.
//
// Potree 2.0 (PotreeConverter 2: metadata.json, hierarchy.bin, octree.bin). hierarchy.bin: chunks
// of 22-byte records (type u8: 0 normal, 1 leaf, 2 proxy; child mask u8, bit i = child i; points
// u32; byte offset u64; byte size u64), breadth first from the chunk's root; a proxy's offset and
// size locate its chunk, which lists it again with its descendants. A node's content is its byte
// range of octree.bin. Encoding DEFAULT: the points' records one after the other, the attributes
// of metadata.json in order, position int32 x 3 with scale and offset. Encoding BROTLI: the node
// is one Brotli stream of the attributes one after the other (each for every point), position
// as a 128-bit Morton code of its three int32 (upper 64 bits first), rgb as a 64-bit Morton code
// of its three uint16; the other attributes as in DEFAULT.
//
// Potree 1.0-1.4 (PotreeConverter up to 1.0RC): cloud.js lists the whole octree in "hierarchy", an
// array of [node name, points] (the root "r" first; Potree's viewer reads it in that order); every
// node's file sits directly in octreeDir: <name>.bin for format 1.4 binary (positions as in 1.5),
// <name> without extension for 1.0-1.3 binary (positions float32 x 3 in the cloud's coordinates),
// <name>.las or .laz. The nodes decode as 1.5-1.8's.
//
// Potree 1.5-1.8 (PotreeConverter 1.x, formats 1.5 to 1.8: cloud.js, and beside it the octreeDir of
// nodes). A node's files are under octreeDir/r/, one folder deeper per whole group of
// hierarchyStepSize digits in its name (step 5: r0123 at r/r0123.bin, r012345 at
// r/01234/r012345.bin). A node whose level is a multiple of the step has a .hrc file beside its
// data: 5-byte records (child mask u8, points u32), breadth first over its subtree down to `step`
// levels below it; the deepest listed nodes' children are in their own .hrc. Data: binary (the
// pointAttributes' records one after the other; position uint32 x 3, scale applied, relative to
// the node's cube's corner), LAS or LAZ (a file per node, absolute coordinates).
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
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
  int major = 2;                           // 2: metadata.json; 1: cloud.js
  int minor = 0;                           // 1.x: the format's minor version
  std::string version;                     // as the file gives it
  std::string uri;                         // metadata.json or cloud.js
  std::string hierarchy_uri, octree_uri;   // 2.0: beside it
  std::string octree_dir;                  // 1.x: the folder holding r/ (resolved)
  std::string name, projection, encoding;  // 2.0: DEFAULT, BROTLI; 1.x: BINARY, LAS, LAZ
  uint64_t points = 0;
  glm::dvec3 scale{1.0}, offset{0.0};
  glm::dvec3 cube_min{0.0}, cube_max{0.0};  // boundingBox: the octree's root cube
  glm::dvec3 data_min{0.0}, data_max{0.0};  // the points' bounds (position min/max)
  double spacing = 0;
  uint64_t first_chunk_size = 0;
  int step_size = 0, depth = 0;  // 1.x: hierarchyStepSize (0 for 1.0-1.4)
  // 1.0-1.4: the octree as cloud.js lists it, [node name, points] in the file's order.
  std::vector<std::pair<std::string, uint64_t>> hierarchy;
  std::vector<PotreeAttribute> attributes;
  size_t record_size = 0;
};

// Deepest level accepted (2^30 cells an axis would already be absurd).
constexpr int kMaxPotreeDepth = 30;

// Whether `uri` is a Potree cloud: a path or URL whose file name is metadata.json (2.0) or
// cloud.js (1.x).
bool is_potree_input(const std::string& uri);

// Parses metadata.json. Throws stipple::Error naming the file and the problem.
std::shared_ptr<const PotreeCloud> parse_potree_metadata(std::span<const uint8_t> json,
                                                         const std::string& uri);
// Parses a Potree 1.x cloud.js (formats 1.0 to 1.8; 1.0-1.4 with their hierarchy). Throws
// stipple::Error naming the file.
std::shared_ptr<const PotreeCloud> parse_potree1_cloud(std::span<const uint8_t> json,
                                                       const std::string& uri);

Tileset load_potree_tileset(const std::string& uri, const Fetcher& fetcher,
                            const TilesetOptions& options = {});

// Reads the hierarchy chunk (2.0) or .hrc file (1.x) that `pending` names (read_children calls
// this for its kind).
Expansion read_potree_chunk(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                            const Fetcher& fetcher, const TilesetOptions& options);

// A node's bytes (2.0: its range of octree.bin; 1.x: its file; the URI carries its point count
// and, for 1.x, its name) decoded into points relative to the node's points' centre: colour,
// normals, and intensity, classification, return number and count, GPS time and every other
// attribute as PointAttribute under Potree's name.
PointContent decode_potree_node(const PotreeCloud& cloud, std::span<const uint8_t> bytes,
                                const std::string& uri, const DecodeLimits& limits = {});

}  // namespace stipple::io
