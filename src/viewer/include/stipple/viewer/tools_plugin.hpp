#pragma once
// ToolsPlugin: the tools of `stipple view` (tools::ToolsCorePlugin's state and actions: inspect,
// measure, profile, annotate, filter, clip, export) with Dear ImGui and the window's input: a
// panel, the measurements drawn over the view (ImGui's background draw list, in the frame graph's
// "ui" pass) and edited by dragging their vertices, the profile window, the inspected record.
// The logic is the tools module's; this is only the window's layer over it (the browser page is
// another).
//
// Keys (when the panel does not have the keyboard): 1 inspect, 2 distance, 3 height, 4 area,
// 5 angle, 6 circle, 7 volume, 8 profile, 9 annotation, B clip box, G clip polygon, 0 no tool;
// Enter or a right click finishes a polyline or polygon, Backspace removes its last point,
// Escape cancels it, Delete removes the selected measurement.
#include <array>
#include <string>
#include <string_view>

#include "stipple/tools/tools.hpp"

namespace stipple {
class Engine;
}  // namespace stipple

namespace stipple::viewer {

struct ToolsPlugin {
  static constexpr std::string_view name = "ToolsPlugin";
  static constexpr std::string_view description =
      "the tools in the window: panel, overlay, keys and mouse over ToolsCorePlugin (inspect, "
      "measure, profile, annotate, filter, clip, export; GeoJSON measurements)";
  static constexpr std::array<std::string_view, 3> dependencies{"InputPlugin", "WindowPlugin",
                                                                "CameraPlugin"};
  static constexpr std::array<std::string_view, 3> optional_dependencies{
      "UiPlugin", "PointCloudPlugin", "TilesetPlugin"};
  std::string measurements_in;   // loaded at start
  std::string measurements_out;  // written when the viewer exits
  // Adds tools::ToolsCorePlugin with the measurements' files.
  void build(Engine& engine);
};

}  // namespace stipple::viewer
