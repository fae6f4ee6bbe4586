#pragma once
// TilesetPlugin: out-of-core streaming of a 3D Tiles tileset (file or URL) in the engine.
//
// Main world, Update: the TileStreamer runs with the current Camera (converted to the tileset's
// View), so requests follow the view. Its workers decode each tile and convert it into
// render-ready chunks (StreamerOptions::prepare: shared, immutable, counted in the memory
// budget), so the main thread never touches points; tiles it evicted are dropped. Extract hands
// the render world the tiles to draw this frame (ids + shared chunk data) and the ids still
// resident.
// With `compute`, Prepare puts newly drawn tiles' LOD batches into a pc::LodBatchStore and
// Queue hands the drawn tiles' batches to the compute rasterizer instead (seed 001, 3.5).
// Render world, Prepare: uploads newly drawn tiles into ranges of shared suballocator pages
// (pc::PagedPoints: writeBuffer, no buffer per tile), and frees the ranges of tiles no longer
// resident once the frames that may still read them have completed (a FrameFence marked after
// each Draw). Queue: a GpuPointCloud view of the selected tiles' chunks (with its own CLOD
// argument buffer) goes to add_point_cloud_passes. Parents stay drawn until their children are
// ready (the traversal).
//
// It provides the same main-world resources as PointCloudPlugin (SceneInfo, PointDrawSettings),
// so the viewer's plugins work over either.
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/io/source.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/pointcloud/compute_raster.hpp"
#include "stipple/pointcloud/paged_points.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/tiles3d/streamer.hpp"
#include "stipple/tiles3d/tile_chunks.hpp"

namespace stipple {
class Engine;
}

namespace stipple::tiles3d {

// Main-world resource: the streaming state.
struct TilesetStream {
  // Grows inside streamer->update() as external tilesets and subtrees are read: main thread only.
  std::shared_ptr<const io::Tileset> tileset;
  std::shared_ptr<tiles3d::TileStreamer> streamer;
  glm::dmat4 world_from_tileset{1.0};
  Aabb world_bounds;  // the root volume (of its point tiles where it holds others), world space
  uint32_t width = 1280, height = 720;  // viewport for screen-space error (a window overrides)
  // Tiles converted for rendering, by tile id (dropped when the streamer evicts the tile).
  std::vector<std::shared_ptr<const TileChunks>> chunks;
  std::vector<uint32_t> draw;  // this frame's tiles to draw (ids with chunks), traversal order
  uint64_t intensity_signature = 0;  // of the drawn tiles the intensity ramp was computed from
  // Tile errors and content warnings by their text without the tile's URI, with how many tiles
  // had each: each is printed for its first tile only (a tileset of b3dm tiles would otherwise
  // print one line per tile).
  std::map<std::string, uint32_t> problems;
  // The first printed, as printed; or the content not drawn that the load warned about.
  std::string first_problem;
};

// Prints a tile's error or content warning unless another tile had the same one (see
// TilesetStream::problems); returns whether it was printed.
bool report_tile_problem(TilesetStream& stream, const TileError& problem);
// Tiles whose problem was not printed because an earlier tile had the same.
uint64_t unreported_tile_problems(const TilesetStream& stream);

// Adds the points of this frame's drawn tiles to a view fit (framing from the data, once it has
// streamed in, rather than from the root volume, which may be far larger).
void fit_drawn_tiles(ViewFit& fit, const TilesetStream& stream);

// The nearest point of this frame's drawn tiles within the ray's cone (TilesetPlugin registers it
// in ScenePickers for double-click focus). Chunks whose bounds miss the cone are not read.
std::optional<pc::PickHit> pick_tileset_point(const TilesetStream& stream, const pc::PickRay& ray,
                                              const pc::PickFilter* filter = nullptr);

// Main-world resource: what the stream did this frame (tests, the UI, `stipple render`).
struct TilesetStats {
  uint64_t frames = 0;
  uint32_t resident_tiles = 0;   // Loaded in the streamer
  uint64_t resident_points = 0;  // of those tiles
  uint64_t resident_bytes = 0, peak_resident_bytes = 0, memory_budget = 0;
  uint64_t loads_completed = 0, evictions = 0;
  uint64_t discarded_over_budget = 0;  // loads dropped: even evicting every unused tile was short
  bool budget_limited = false;         // the budget raised the screen-space error threshold ...
  double sse_threshold = 0;            // ... to this (pixels)
  uint32_t drawn_tiles = 0;
  uint64_t drawn_points = 0;
  bool idle = false;  // nothing queued or in flight after this frame's update
  uint64_t errors = 0;
};

// Render-world resource: the tiles' GPU memory (tests, the UI).
struct TilesetGpuStats {
  uint64_t uploads = 0, frees = 0;  // tiles
  uint32_t gpu_tiles = 0;
  uint64_t gpu_points = 0;
  bool paged = false;
  pc::PagedPointStats pages;  // when paged
  gpu::SuballocatorStats allocator;
  uint64_t pending_frees = 0;  // ranges waiting for their frame to complete
  // Device memory of the tiles' points as the allocators account it: `gpu_bytes` is held by
  // uploaded tiles (and ranges waiting to be freed), `gpu_reserved_bytes` the buffers made for
  // them (compute path: the LOD batch store's slot arrays and batch table; billboards: the
  // suballocator's pages, or each chunk's own buffers).
  uint64_t gpu_bytes = 0, gpu_reserved_bytes = 0;
  uint64_t refused_uploads = 0;  // compute path: tiles that found no free slot range
};

struct TilesetPlugin {
  static constexpr std::string_view name = "TilesetPlugin";
  static constexpr std::string_view description =
      "streams a 3D Tiles tileset with the camera (worker pool, memory budget, LRU); uploads "
      "new tiles, frees evicted ones, draws the selection";
  static constexpr std::array<std::string_view, 4> dependencies{"GpuPlugin", "RenderGraphPlugin",
                                                                "CameraPlugin", "TransformPlugin"};
  std::string uri;  // tileset.json path or URL
  // What `uri` is, where the caller has classified it (scene::classify_scene); else found from
  // the uri here (io::source_format).
  std::optional<io::SourceFormat> format;
  tiles3d::StreamerOptions streamer;
  uint32_t width = 1280, height = 720;  // viewport for the screen-space error
  pc::PointRenderSettings render;       // copied into PointDrawSettings
  uint64_t budget = 0;                  // PointDrawSettings::budget (unused: the traversal is)
  // Size of the suballocator pages that hold the tiles on the GPU; 0: two dedicated buffers per
  // chunk instead (the path before pages, kept for comparison).
  uint64_t gpu_page_bytes = uint64_t(32) << 20;
  // Draw with the compute rasterizer: each tile is also made LOD batches on its worker, kept in
  // a pc::LodBatchStore, and the drawn tiles' batches are rasterized (1-pixel points; EDL,
  // background and edl settings from `render`, the rest from `raster`).
  bool compute = false;
  pc::ComputeRasterOptions raster;
  void build(Engine& engine);
};

}  // namespace stipple::tiles3d
