#pragma once
// One-shot loading of a tileset for headless rendering (`stipple render tileset.json`): frame
// the root volume, stream until the selection for that camera is resident (reading external
// tilesets and subtrees as the traversal reaches them), convert to chunks.
#include <set>
#include <string>
#include <vector>

#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/tiles3d/streamer.hpp"

namespace stipple::tiles3d {

// Tileset frame -> engine world: geocentric tilesets are re-expressed in the east-north-up
// frame at the root's centre (so "up" is up), then Z-up becomes Y-up.
glm::dmat4 world_from_tileset(const io::Tileset& tileset);
// The root bounding volume as a world-space (Y-up) box.
Aabb world_bounds(const io::Tileset& tileset, const glm::dmat4& world_from_tileset);

// The box to frame: the root volume, unless some of the contents known at load (the tree read
// so far, breadth first, up to `max_contents` headers: io::summarize_content) are not points:
// then the union of the tiles whose content is points (a tileset whose points are a small part
// of its volume is not framed as a dot), and `warning` says what is not drawn. The root volume
// when no point content is found. `not_drawn_kinds` receives what the warning named
// (io::describe_content_type), for StreamerOptions::not_drawn_warned.
Aabb drawable_world_bounds(const io::Tileset& tileset, const glm::dmat4& world_from_tileset,
                           const io::Fetcher& fetcher, std::string* warning,
                           std::set<std::string>* not_drawn_kinds = nullptr,
                           size_t max_contents = 16);

struct RenderLoadOptions {
  StreamerOptions streamer;
  uint32_t width = 1280, height = 720;
  double azimuth = 30.0, elevation = 40.0, fov = 50.0;
  const Camera* camera = nullptr;  // null: frame the root volume
  size_t max_updates = 100'000;
};

struct RenderLoadResult {
  pc::PointCloud cloud;
  Camera camera;
  std::vector<TileError> errors;
  std::vector<TileError> warnings;  // the loaded contents' (TileStreamer::take_warnings)
  // drawable_world_bounds' warning on content that is not drawn, not printed: the caller says
  // it (the tiles do not repeat it).
  std::string not_drawn_warning;
  uint32_t tiles_rendered = 0;
  // The memory budget limited detail: tiles were drawn at this screen-space error instead of
  // max_sse (infinite: not even the root fitted).
  bool budget_limited = false;
  double sse_threshold = 0;
  StreamerStats stats;
};

// Appends a tile's decoded points to the cloud as one chunk: double origin (tile centre in the
// world), float offsets. `tile_transform` maps the tile frame to the tileset frame. The file's
// alpha is kept (PointContent::alpha; CloudAttributes::has_translucent says whether any point is
// under full opacity), except that fully transparent points are left out: returns how many.
uint64_t append_content(pc::PointCloud& cloud, const io::PointContent& content,
                        const glm::dmat4& tile_transform, const glm::dmat4& world_from_tileset);

RenderLoadResult load_tileset_for_render(const std::string& uri, const RenderLoadOptions& options);

}  // namespace stipple::tiles3d
