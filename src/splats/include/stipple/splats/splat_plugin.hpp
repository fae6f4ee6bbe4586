#pragma once
// SplatPlugin: 3D Gaussian splat sets as entities, drawn in the same frame as the point clouds.
// Each set becomes a main-world entity with SplatData + Transform + SyncTo<Render>; Extract
// hands the (shared, immutable) set to its twin; Prepare uploads it; Queue adds the splat passes
// (splats.hpp) after the scene's passes, so add this plugin after the point or tileset plugin:
// its passes then depth-test against the points' depth ("depth"), or, with no point pass in the
// frame, clear the colour target to the background first and draw without a depth test.
#include <array>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "stipple/io/splats.hpp"
#include "stipple/math/aabb.hpp"
#include "stipple/splats/splats.hpp"

namespace stipple {
class Engine;
}

namespace stipple::splats {

// Main-world component: one splat set, shared with the render world (never modified; a reload
// makes a new one with a higher generation). Or, where `parts` is not empty, a set made of parts
// in one frame that `parts_transform` places (a streamed tileset's drawn tiles): each part is
// uploaded once, and a new generation's parts are composed on the GPU (compose_splats).
struct SplatData {
  std::shared_ptr<const io::SplatSet> set;
  std::vector<std::shared_ptr<const io::SplatSet>> parts;
  glm::dmat4 parts_transform{1.0};
  uint64_t generation = 0;
};

// Main- and render-world resource.
struct SplatDrawSettings {
  glm::vec3 background{0.07f, 0.08f, 0.1f};  // when no point pass draws the frame first
  bool depth_test = true;                    // against the points' depth, when there is one
  // Empty: the device's faster one (default_splat_rasterizer).
  std::optional<SplatRasterizer> rasterizer;
};

// The world-space bounds of the splats' centres (through the set's transform), for framing a
// camera.
Aabb splat_bounds(const io::SplatSet& set);

// Whether a frame drawn earlier with the tile rasterizer wanted more (tile, splat) pairs than
// its buffers held, which have grown since (settle_tile_pairs): one more frame draws every
// splat. Never waits for the GPU (only for a pipelined render world's frame); for a front end
// that draws only when something changed (the web page), asked while it is idle.
bool splat_frames_incomplete(Engine& engine);

struct SplatPlugin {
  static constexpr std::string_view name = "SplatPlugin";
  static constexpr std::string_view description =
      "3D Gaussian splat sets as entities: uploads, sorts and draws them beside the points";
  static constexpr std::array<std::string_view, 3> dependencies{"GpuPlugin", "RenderGraphPlugin",
                                                                "TransformPlugin"};
  std::vector<std::shared_ptr<const io::SplatSet>> sets;
  SplatDrawSettings settings;
  void build(Engine& engine);
};

}  // namespace stipple::splats
