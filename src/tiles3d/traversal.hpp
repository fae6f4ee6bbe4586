#pragma once
// Tile selection as a pure function of (tileset, view, per-tile load state): what to render,
// what to load (ordered by screen-space error, then distance), which tiles' pending children to
// read (external tilesets, subtrees), what to cancel and what to evict.
// Seed 000 section 4, eq. 1: SSE = eps * f / d, f = h / (2 tan(theta / 2)).
#include <cstdint>
#include <vector>

#include <glm/mat4x4.hpp>

#include "io/tileset.hpp"
#include "math/camera.hpp"

namespace stipple::tiles3d {

enum class LoadState : uint8_t { Unloaded, Loading, Loaded, Failed };

struct TileState {
  LoadState state = LoadState::Unloaded;
  uint64_t bytes = 0;      // resident size when Loaded
  uint64_t last_used = 0;  // frame it was last rendered or kept
};

struct View {
  Camera camera;                      // engine world space (Y-up)
  double width = 1280, height = 720;  // viewport, pixels
  // Tileset frame (ECEF or local, Z-up) -> engine world (Y-up).
  glm::dmat4 world_from_tileset{1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1};
};

struct TraversalOptions {
  double max_sse = 16.0;                  // refine while a tile's SSE exceeds this (pixels)
  uint64_t memory_budget = 512ull << 20;  // resident bytes; unused tiles are evicted beyond it
  bool frustum_cull = true;
};

struct LoadRequest {
  uint32_t tile;
  double sse;
  double distance;
};

struct Selection {
  std::vector<uint32_t> render;      // tiles whose content is drawn this frame
  std::vector<LoadRequest> loads;    // most important first
  std::vector<LoadRequest> expands;  // tiles whose pending children to read, most important first
  std::vector<uint32_t> cancel;      // Loading tiles nobody wants any more
  std::vector<uint32_t> evict;       // Loaded tiles to drop, least recently used first
  std::vector<uint32_t> used;        // tiles rendered or kept this frame (update last_used)
  uint32_t visited = 0, culled = 0;
};

double screen_space_error(double geometric_error, double distance, const View& view);

// `states` has one entry per tile. Pure: no I/O, no mutation.
Selection select_tiles(const io::Tileset& tileset, const View& view,
                       const std::vector<TileState>& states, const TraversalOptions& options,
                       uint64_t frame);

// Loaded tiles to evict so that `incoming` more bytes fit the budget, least recently used first,
// never one used in `frame`. Empty when they cannot be made to fit.
std::vector<uint32_t> make_room(const std::vector<TileState>& states, uint64_t incoming,
                                uint64_t budget, uint64_t frame, bool* fits);

}  // namespace stipple::tiles3d
