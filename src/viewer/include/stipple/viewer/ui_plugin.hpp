#pragma once
// UiPlugin: Dear ImGui in the engine. The main world runs the ImGui frame (NewFrame in Input,
// after the window's events; widgets from any plugin's Update systems; Render in PostUpdate)
// and Extract hands a copy of the draw data to the render world, which adds pass "ui" over the
// target in PreDraw. ImGui itself is only ever touched on the main thread.
#include <array>
#include <string_view>

namespace stipple {
class Engine;
}

namespace stipple::viewer {

// Main-world resource: F1 (or the viewer's UI) toggles it.
struct UiSettings {
  bool visible = true;
};

struct UiPlugin {
  static constexpr std::string_view name = "UiPlugin";
  static constexpr std::string_view description =
      "Dear ImGui: frames in the main world, drawn as pass \"ui\" by a WebGPU renderer";
  static constexpr std::array<std::string_view, 3> dependencies{"WindowPlugin", "GpuPlugin",
                                                                "RenderGraphPlugin"};
  bool visible = true;
  void build(Engine& engine);
};

}  // namespace stipple::viewer
