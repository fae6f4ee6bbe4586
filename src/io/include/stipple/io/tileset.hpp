#pragma once
// 3D Tiles 1.0/1.1 tileset.json: the tile tree flattened into one array, transforms accumulated
// and every bounding volume turned into an oriented box in the tileset's frame (ECEF or local,
// Z-up). The tree is read lazily: external tilesets and child subtrees of implicit tiling are
// left as pending children on their tile and read when a traversal wants them (a global implicit
// octree has billions of potential tiles): read_children (any thread) then attach_children.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "stipple/io/fetch.hpp"
#include "stipple/io/source.hpp"

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

// The implicit tiling of one implicit root tile, shared by every tile below it.
struct ImplicitTiling {
  bool octree = false;
  int branching = 4;
  int subtree_levels = 0;
  int available_levels = 0;
  std::string subtrees;               // resolved URI template
  std::vector<std::string> contents;  // resolved URI templates
  BoundingVolume root_volume;
  glm::dmat4 transform{1.0};
  double root_error = 0;
  Refine refine = Refine::Replace;
};

struct CopcFile;
struct PotreeCloud;
struct EptCloud;

// Children of a tile that have not been read: external tilesets (its content is tileset JSON),
// the subtree rooted at it (implicit tiling: its own content is unknown until then too), or the
// COPC hierarchy page of its node (which lists the node itself too, like a subtree).
// Immutable once made, so a worker can read it while the tileset grows.
struct PendingChildren {
  enum class Kind : uint8_t {
    External,
    Subtree,
    CopcPage,
    PotreeChunk,
    EptHierarchy
  } kind = Kind::External;
  // External: the tilesets; Subtree: the subtree file; CopcPage: the page's range URI.
  std::vector<std::string> uris;
  std::vector<std::string> chain;  // External: tilesets from the root down (cycle detection)
  glm::dmat4 transform{1.0};       // External: the tile's, which the external roots inherit
  Refine refine = Refine::Replace;
  std::shared_ptr<const ImplicitTiling> implicit;  // Subtree
  uint32_t level = 0, x = 0, y = 0, z = 0;         // Subtree, CopcPage: its root tile's key
  std::shared_ptr<const CopcFile> copc;            // CopcPage
  std::shared_ptr<const PotreeCloud> potree;       // PotreeChunk
  std::shared_ptr<const EptCloud> ept;             // EptHierarchy
  // Whether the tile's own content comes with the read (a subtree's or a page's root).
  bool brings_content() const { return kind != Kind::External; }
};

struct Tile {
  BoundingVolume volume;      // as declared, in the tile's frame
  Obb box;                    // in the tileset frame (transforms applied)
  glm::dmat4 transform{1.0};  // tile frame -> tileset frame (the chain of transforms)
  double geometric_error = 0.0;
  Refine refine = Refine::Replace;
  std::vector<std::string> contents;  // resolved URIs of renderable content (pnts, glb, ...)
  uint64_t content_points = 0;        // points its contents declare (COPC); 0: unknown
  int32_t parent = -1;
  std::vector<uint32_t> children;
  uint32_t depth = 0;
  std::string error;  // what failed to load below this tile (external tileset, subtree)
  std::shared_ptr<const PendingChildren> pending;  // children not read yet; null: none
};

struct TilesetOptions {
  FetchOptions fetch;
  // Safety limit on materialised tiles (the array grows as the tree is read): an expansion that
  // would pass it is refused with an error on its tile.
  size_t max_tiles = 2'000'000;
  int max_external_depth = 32;
  uint64_t max_json_bytes = 256ull << 20;
};

struct Tileset {
  std::string uri;
  std::string version;           // asset.version
  double geometric_error = 0.0;  // the tileset's own
  // tiles[0] is the root; parents come before children. Grows by attach_children: indices stay.
  std::vector<Tile> tiles;
  std::vector<std::string> warnings;
  std::vector<std::string> errors;  // per-tile failures, also in Tile::error
  uint32_t external_tilesets = 0;   // read so far
  uint32_t subtrees = 0;            // read so far
  uint32_t pending = 0;             // tiles with pending children
  bool implicit = false;
  // A COPC file's octree (copc.hpp): tiles are nodes, contents their chunks' range URIs, in the
  // file's coordinates (a local frame, Z-up).
  std::shared_ptr<const CopcFile> copc;
  // A Potree 2.0 cloud's octree (potree.hpp), the same way.
  std::shared_ptr<const PotreeCloud> potree;
  // An Entwine Point Tile dataset's octree (ept.hpp), the same way.
  std::shared_ptr<const EptCloud> ept;
};

using Fetcher = std::function<std::vector<uint8_t>(const std::string& uri)>;

// Loads a tileset from a path or URL through io::fetch: the root document, and the root subtree
// of implicit tiling found in it; external tilesets and child subtrees are left pending. A COPC
// file (is_copc_input) gives its octree (load_copc_tileset), a Potree 2.0 metadata.json
// (is_potree_input) its octree (load_potree_tileset).
// A broken root is an Error; a broken subtree is recorded on its tile.
Tileset load_tileset(const std::string& uri, const TilesetOptions& options = {});
// The same through `fetcher` (tests count or fault requests with it).
Tileset load_tileset(const std::string& uri, const Fetcher& fetcher,
                     const TilesetOptions& options = {});
// The same for an input already classified (source_format): the format picks the loader.
Tileset load_tileset(const std::string& uri, SourceFormat format, const Fetcher& fetcher,
                     const TilesetOptions& options = {});
// The same from bytes already read, fetching what they reference through `fetcher`.
Tileset parse_tileset(std::span<const uint8_t> json_bytes, const std::string& uri,
                      const Fetcher& fetcher, const TilesetOptions& options = {});

// What reading one tile's pending children produced: new tiles in their own index space
// (parents before children; parent -1 is the expanded tile), and content found for the tile.
struct Expansion {
  uint32_t tile = 0;
  std::vector<std::string> contents;  // for `tile` (the root of a subtree)
  uint64_t content_points = 0;        // what they declare (COPC)
  std::vector<Tile> tiles;
  std::vector<std::pair<int32_t, std::string>> errors;  // (new tile, or -1: `tile`; message)
  std::vector<std::string> warnings;
  uint32_t external_tilesets = 0, subtrees = 0;
  bool implicit = false;
  bool over_limit = false;  // max_tiles stopped it
};

// Reads (fetches and parses) the pending children of `tile`. Touches no tileset, so it may run on
// a worker while the tileset is used elsewhere; `tiles_now` is the tileset's size, for the
// max_tiles limit. Never throws: failures are errors of the expansion.
Expansion read_children(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                        const Fetcher& fetcher, const TilesetOptions& options);
// Appends an expansion's tiles after every existing tile (so parents still come before
// children), adds its contents to the tile and clears the tile's pending children. Returns the
// errors it brought, by tile index; an expansion past max_tiles is refused with an error.
std::vector<std::pair<uint32_t, std::string>> attach_children(Tileset& tileset,
                                                              Expansion&& expansion,
                                                              const TilesetOptions& options);
// Reads every pending child, breadth first, until none is left or `max_tiles` tiles exist (the
// one place the whole tree is wanted: `stipple info`). Returns whether the tree is complete.
bool expand_all(Tileset& tileset, const Fetcher& fetcher, const TilesetOptions& options,
                size_t max_tiles);

// Whether a content URI names a tileset (an external tileset) rather than renderable content.
bool is_tileset_uri(const std::string& uri);

}  // namespace stipple::io
