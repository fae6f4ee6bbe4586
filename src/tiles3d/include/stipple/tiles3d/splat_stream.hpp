#pragma once
// SplatTilesetPlugin: streams a splat tileset (3D Tiles whose content is KHR_gaussian_splatting
// glb, as `stipple tile` writes from splat files) with the camera, through the same TileStreamer
// as point tilesets: the traversal's screen-space error (geometricError, REPLACE refinement), the
// memory budget and the point budget (here counting splats), LRU eviction, loads on workers.
//
// Workers decode each tile's splats (decode_content) and move them into the root tile's frame
// (the hook StreamerOptions::prepare). Each frame whose drawn tiles changed, the main thread
// publishes the list of the drawn tiles' splat sets in the main-world resource StreamedSplats with
// a new generation: the splat renderer draws them as ONE set (projected, sorted and drawn
// together, not tile by tile), composed on the GPU from each tile's own upload, so the main
// thread copies no splat.
//
// tiles3d does not draw splats itself: in DESIGN.md's module table the splats module sits beside
// pointcloud, not below tiles3d. StreamedSplats is the seam: a consumer above both (scene) hands
// its set to splats::SplatPlugin.
#include <array>
#include <cstdint>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <glm/mat4x4.hpp>

#include "stipple/io/splats.hpp"
#include "stipple/io/tileset.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/tiles3d/streamer.hpp"

namespace stipple {
class Engine;
}

namespace stipple::tiles3d {

// Main-world resource: the splat stream and what it drew this frame.
struct StreamedSplats {
  // The drawn tiles' splats, each in the root tile's frame (glTF Y-up, relative to the root's
  // transform, which is `transform`: float positions stay small for geo-referenced tilesets), in
  // traversal order; empty until a tile is in. Replaced when the drawn tiles change.
  std::vector<std::shared_ptr<const io::SplatSet>> parts;
  glm::dmat4 transform{1.0};
  uint64_t generation = 0;  // bumped with each new list
  std::shared_ptr<const io::Tileset> tileset;
  std::shared_ptr<TileStreamer> streamer;
  // Tileset frame (Z-up) -> engine world (Y-up): the plain axis swap, as for a splat file or
  // read_splats' static cut of the same tileset (no east-north-up re-expression), so a streamed
  // tileset draws where its source file does.
  glm::dmat4 world_from_tileset{1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 1};
  Aabb world_bounds;                    // the root volume, world space
  uint32_t width = 1280, height = 720;  // viewport for the screen-space error (a window overrides)
  std::vector<uint32_t> drawn;          // tiles whose splats are in `parts`, traversal order
  std::set<std::string> problems;       // tile problem kinds printed (each once)
  // This frame's figures (tests, `stipple render`'s summary).
  uint64_t frames = 0;
  uint64_t drawn_splats = 0;
  uint32_t drawn_tiles = 0;
  uint32_t resident_tiles = 0;
  uint64_t resident_bytes = 0;
  uint64_t errors = 0;
  bool budget_limited = false;
  double sse_threshold = 0;
  bool idle = false;  // nothing queued or in flight, and `parts` hold this frame's selection
};

// A tile's splats, decoded in its glb's frame, moved into the root tile's glTF Y-up frame
// (`tile_transform`, `root_transform`: tile and root frames -> tileset frame, Z-up). Throws
// stipple::Error when the tile turns or scales its splats relative to the root (the tiler
// writes a transform on the root only).
io::SplatSet splats_in_root_frame(const io::SplatSet& splats, const glm::dmat4& tile_transform,
                                  const glm::dmat4& root_transform, std::string_view name);

struct SplatTilesetPlugin {
  static constexpr std::string_view name = "SplatTilesetPlugin";
  static constexpr std::string_view description =
      "streams a splat tileset with the camera (traversal, budgets, LRU) and lists the drawn "
      "tiles' splats, to be drawn as one set (StreamedSplats)";
  static constexpr std::array<std::string_view, 2> dependencies{"CameraPlugin", "TransformPlugin"};
  std::string uri;  // tileset.json path or URL
  StreamerOptions streamer;
  uint32_t width = 1280, height = 720;
  void build(Engine& engine);
};

}  // namespace stipple::tiles3d
