#pragma once
// UiPlugin: Dear ImGui in the engine. The main world runs the ImGui frame (NewFrame in Input,
// after the window's events; widgets from any plugin's Update systems; Render in PostUpdate)
// and Extract hands a copy of the draw data to the render world, which adds pass "ui" over the
// target in PreDraw. ImGui itself is only ever touched on the main thread.
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string_view>
#include <vector>

namespace stipple {
class Engine;
}

namespace stipple::viewer {

// Main-world resource: F1 (or the viewer's UI) toggles it.
struct UiSettings {
  bool visible = true;
};

// An RGBA8 image for ImGui::Image (the profile window's cross-section).
struct UiImage {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;
};
// Main-world resource: images by texture id (ids from 2 up; 1 is the font atlas). Replacing an
// image uploads it again; the id stays valid.
struct UiImages {
  std::map<uintptr_t, std::shared_ptr<const UiImage>> images;
  uintptr_t next_id = 2;
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
