#pragma once
// Tile selection as a pure function of (tileset, view, per-tile load state): what to render,
// what to load (ordered by screen-space error, then distance), which tiles' pending children to
// read (external tilesets, subtrees), what to cancel and what to evict.
// Seed 000 section 4, eq. 1: SSE = eps * f / d, f = h / (2 tan(theta / 2)).
//
// The memory budget (and the point budget, where set) bounds the selection itself: when what a view wants (resident tiles it uses
// plus the tiles it would load, at their known or estimated sizes) exceeds the budget, the
// screen-space error threshold is raised, uniformly over the view, to the lowest value whose
// selection fits. Coarser resident ancestors are drawn instead of requesting tiles that could
// not be kept, so a budget-starved view settles instead of loading and evicting forever.
#include <cstdint>
#include <vector>

#include <glm/mat4x4.hpp>

#include "stipple/io/tileset.hpp"
#include "stipple/math/camera.hpp"

namespace stipple::tiles3d {

enum class LoadState : uint8_t { Unloaded, Loading, Loaded, Failed };

struct TileState {
  LoadState state = LoadState::Unloaded;
  // Resident size when Loaded; otherwise the size the content had when it was last loaded (kept
  // after eviction so the budget knows what reloading costs), 0 when never loaded.
  uint64_t bytes = 0;
  uint64_t last_used = 0;  // frame it was last rendered or kept
  uint64_t points = 0;     // points of its content once loaded (kept after eviction, like bytes)
};

struct View {
  Camera camera;                      // engine world space (Y-up)
  double width = 1280, height = 720;  // viewport, pixels
  // Tileset frame (ECEF or local, Z-up) -> engine world (Y-up).
  glm::dmat4 world_from_tileset{1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1};
};

struct TraversalOptions {
  double max_sse = 16.0;                  // refine while a tile's SSE exceeds this (pixels)
  uint64_t memory_budget = 512ull << 20;  // resident bytes: bounds the selection, and eviction
  // Points the selection may draw (Potree's point budget), bounded like the bytes: the error
  // threshold rises until the selection's points fit. Points of a tile not loaded yet: the
  // count its tile declares (COPC), else the nearest ancestor's. 0: no limit.
  uint64_t point_budget = 0;
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
  // Bytes the selection needs resident (used tiles, loads at their known or estimated size),
  // and the points of its used tiles (known, declared or estimated).
  uint64_t footprint = 0;
  uint64_t footprint_points = 0;
  // The screen-space error threshold applied: max_sse, or higher when the budget limited detail.
  double sse_threshold = 0;
  bool budget_limited = false;
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
