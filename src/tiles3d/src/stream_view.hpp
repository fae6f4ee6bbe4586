#pragma once
// The view a tile streamer selects for, as the point and splat tileset plugins both take it from
// the main world: its first camera, the window's viewport where there is one (else the stream's
// own size: render's image), and the stream's tileset-to-world transform.
#include <cstdint>
#include <optional>

#include <glm/mat4x4.hpp>

#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/tiles3d/traversal.hpp"

namespace stipple::tiles3d {

// Empty while the main world has no camera.
inline std::optional<View> stream_view(Registry& main, uint32_t width, uint32_t height,
                                       const glm::dmat4& world_from_tileset) {
  const Camera* camera = nullptr;
  main.view<Camera>().each([&](const Camera& c) {
    if (!camera) camera = &c;
  });
  if (!camera) return std::nullopt;
  View view;
  view.camera = *camera;
  view.width = width;
  view.height = height;
  if (const auto* viewport = main.try_resource<Viewport>(); viewport && viewport->valid()) {
    view.width = viewport->width;
    view.height = viewport->height;
  }
  view.world_from_tileset = world_from_tileset;
  return view;
}

}  // namespace stipple::tiles3d
