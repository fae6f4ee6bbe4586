#pragma once
// ViewerPlugin: what makes `stipple view` a viewer beyond the generic plugins: its keys (P
// screenshot, V vsync, F1 UI, Escape quit), the stats/controls panel, and the scripted exit
// (--frames N --screenshot FILE) that tests use.
#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace stipple {
class Engine;
}

namespace stipple::viewer {

struct ViewerPlugin {
  static constexpr std::string_view name = "ViewerPlugin";
  static constexpr std::string_view description =
      "viewer keys (P screenshot, V vsync, F1 UI, Esc quit), stats and controls panel, "
      "--frames/--screenshot";
  // The scene comes from PointCloudPlugin, VirtualPointCloudPlugin or TilesetPlugin (each
  // provides SceneInfo and PointDrawSettings); require() checks that one is there.
  static constexpr std::array<std::string_view, 2> dependencies{"InputPlugin", "RenderGraphPlugin"};
  static constexpr std::array<std::string_view, 6> optional_dependencies{
      "PointCloudPlugin", "VirtualPointCloudPlugin", "TilesetPlugin", "SurfaceTargetPlugin",
      "UiPlugin",         "CameraControllerPlugin"};
  uint64_t exit_after_frames = 0;  // 0: run until the window closes
  std::string screenshot;          // written from the last frame when exiting after N frames
  void build(Engine& engine);
  void require(Engine& engine);
};

// "stipple-screenshot-N.png" with the first N not taken in the working directory.
std::string next_screenshot_name();

}  // namespace stipple::viewer
