#pragma once
// The engine's built-in plugins. Each can be left out or replaced by a plugin of the same name.
#include <string_view>

#include "stipple/engine/camera.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/time.hpp"
#include "stipple/engine/transform.hpp"

namespace stipple {

// Runs the render world on its own thread (seed 000, section 3.3). Without it, both worlds run
// their stages in order on the calling thread, as in web builds.
struct PipelinedRenderingPlugin {
  static constexpr std::string_view name = "PipelinedRenderingPlugin";
  static constexpr std::string_view description =
      "render world on a dedicated thread, one frame behind the main world";
  void build(Engine& engine) { engine.set_pipelined(true); }
};

inline auto default_plugins() {
  return PluginGroup{TimePlugin{}, TransformPlugin{}, CameraPlugin{}, PipelinedRenderingPlugin{}};
}

}  // namespace stipple
