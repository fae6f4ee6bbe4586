#pragma once
// ToolsPlugin: what LiDAR users do in a viewer beyond looking. Inspect a point (its record read
// again from the file), measure (distances, heights, areas, angles, circles, volumes), profile
// (a cross-section window), annotate, filter (classes, returns, intensity, GPS time, point
// source) and clip (boxes, polygons, planes), and export the clip or profile through the same
// code as `stipple clip` / `stipple profile`. Measurements are drawn over the view (ImGui's
// background draw list, in the frame graph's "ui" pass), edited by dragging their vertices, and
// saved to / loaded from GeoJSON in the source CRS.
//
// Keys (when the panel does not have the keyboard): 1 inspect, 2 distance, 3 height, 4 area,
// 5 angle, 6 circle, 7 volume, 8 profile, 9 annotation, B clip box, G clip polygon, 0 no tool;
// Enter or a right click finishes a polyline or polygon, Backspace removes its last point,
// Escape cancels it, Delete removes the selected measurement.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "stipple/viewer/measure.hpp"
#include "stipple/viewer/records.hpp"

namespace stipple {
class Engine;
class Registry;
}  // namespace stipple

namespace stipple::viewer {

// Main-world resource: the tools' state (tests and other plugins may read it).
struct ToolsState {
  Tool tool = Tool::None;
  std::vector<Measurement> items;
  int active = -1;           // the item being clicked in, if any
  int selected = -1;         // the item the panel shows (and Delete removes)
  double profile_width = 0;  // default corridor width (0: 1% of the scene's size)
  std::optional<PointRecord> inspected;
  std::string message;  // the last error or notice, shown in the panel
  SourceFrame frame;
  uint64_t version = 0;  // bumped on every change (the profile window and clip follow it)
};

// Writes every measurement (and the last inspected point) as GeoJSON in the source CRS.
void save_measurements(const ToolsState& state, const std::string& path);
// Adds the measurements of a GeoJSON file (stipple::Error naming the file and feature).
void load_measurements(ToolsState& state, const std::string& path);

struct ToolsPlugin {
  static constexpr std::string_view name = "ToolsPlugin";
  static constexpr std::string_view description =
      "inspect, measure, profile, annotate, filter, clip and export, with GeoJSON "
      "measurements";
  static constexpr std::array<std::string_view, 3> dependencies{"InputPlugin", "WindowPlugin",
                                                                "CameraPlugin"};
  static constexpr std::array<std::string_view, 3> optional_dependencies{
      "UiPlugin", "PointCloudPlugin", "TilesetPlugin"};
  std::string measurements_in;   // loaded at start
  std::string measurements_out;  // written when the viewer exits
  void build(Engine& engine);
  void finish(Engine& engine);
};

}  // namespace stipple::viewer
