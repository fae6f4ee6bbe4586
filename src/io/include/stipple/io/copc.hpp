#pragma once
// Cloud Optimized Point Cloud (COPC 1.0) as a streamed source: the info VLR, the octree
// hierarchy read page by page as a traversal reaches it, and node chunks decoded on their own.
//
// A COPC file becomes an io::Tileset, so the 3D Tiles traversal and streamer serve it unchanged:
// every octree node is a tile (a cube, geometric error = root spacing / 2^depth, additive
// refinement) whose content is its LAZ chunk, named by a byte-range URI (fetch.hpp); every
// hierarchy page is a tile's pending children, read like an implicit-tiling subtree (the page
// holds the node's own entry too). Local files are read with positional reads, http(s) with
// Range requests.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/las.hpp"
#include "stipple/io/pnts.hpp"
#include "stipple/io/tileset.hpp"

namespace stipple::io {

// The "copc" info VLR (user id "copc", record 1, 160 bytes).
struct CopcInfo {
  glm::dvec3 center{0.0};  // of the root cube, in the file's coordinates
  double halfsize = 0;
  double spacing = 0;  // between points at the root
  uint64_t root_hier_offset = 0, root_hier_size = 0;
  double gpstime_min = 0, gpstime_max = 0;
};

struct CopcKey {
  int32_t d = 0, x = 0, y = 0, z = 0;
  bool operator==(const CopcKey&) const = default;
  std::string str() const;  // "d-x-y-z", as COPC tools print keys
};

// One hierarchy entry: a node's chunk (point_count >= 0) or a child page (point_count -1).
struct CopcEntry {
  CopcKey key;
  uint64_t offset = 0;
  int32_t byte_size = 0;
  int32_t point_count = 0;
};

// Deepest octree level accepted (keys past it are corrupt: 2^31 cells per axis cannot exist).
constexpr int32_t kMaxCopcDepth = 30;

CopcInfo parse_copc_info(std::span<const uint8_t> payload, const std::string& name);
// Parses one hierarchy page: a whole number of 32-byte entries, each a valid key (0 <= x, y, z
// < 2^d, d <= kMaxCopcDepth) with its chunk or page inside a file of `file_size` bytes (0:
// unknown). Throws stipple::Error naming the entry and the problem; with `errors`, only a page
// that is not whole entries throws, and a bad entry is left out with its message there.
std::vector<CopcEntry> parse_copc_page(std::span<const uint8_t> bytes, const std::string& name,
                                       uint64_t file_size,
                                       std::vector<std::string>* errors = nullptr);

// What every node decode needs: the header and VLRs as read once at open.
struct CopcFile {
  std::string uri;
  uint64_t file_size = 0;
  LasHeader header;
  CopcInfo info;
  std::vector<uint8_t> prefix;  // the file's first offset_to_points bytes (header and VLRs)
  int rgb_bits = 16;            // 8 when the root node's RGB is all <= 255 (see LasHeader)
};

// Whether `uri` is a COPC file: a name ending in .copc.laz (local or URL), or a local LAZ whose
// first VLR is the COPC info.
bool is_copc_input(const std::string& uri);

// Opens a COPC file through `fetcher` (range URIs): header, VLRs, info. Throws stipple::Error.
std::shared_ptr<const CopcFile> open_copc(const std::string& uri, const Fetcher& fetcher,
                                          const DecodeLimits& limits = {});

// The tile tree of a COPC file: its root node, with the root hierarchy page pending.
Tileset load_copc_tileset(const std::string& uri, const TilesetOptions& options = {});
Tileset load_copc_tileset(const std::string& uri, const Fetcher& fetcher,
                          const TilesetOptions& options = {});

// Reads the hierarchy page that `pending` names (read_children calls this for its kind).
Expansion read_copc_page(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                         const Fetcher& fetcher, const TilesetOptions& options);

// A node's content: its LAZ chunk (the bytes of its range URI, which also carries the point
// count) decoded into points relative to the node's centre, in the file's coordinates; colour
// and the LAS attributes (intensity, classification, return number and count) as the 3D Tiles
// decoders give them. Throws stipple::Error.
PointContent decode_copc_node(const CopcFile& file, std::span<const uint8_t> chunk,
                              const std::string& uri, const DecodeLimits& limits = {});

// Centre and half size of a node's cube.
glm::dvec3 copc_node_center(const CopcInfo& info, const CopcKey& key, double* halfsize);

}  // namespace stipple::io
