#pragma once
// The tools of a point-cloud viewer, with no UI: inspect a point (its record read again from the
// source), measure (distances, heights, areas, angles, circles, volumes), profile (a corridor
// along a polyline), annotate, clip (boxes and polygons, inside/outside/highlight) and filter
// (classes, returns, intensity, GPS time, point source), and export what is shown through
// `stipple clip` / `stipple profile`'s code. Measurements are saved and loaded as GeoJSON in the
// source CRS.
//
// The state is a main-world resource (ToolsState, with the filters and clip region in
// pc::PointDrawSettings, which both renderers read). A front end turns its own input into the
// actions below and draws `overlay()` and `profile_view()` its own way: `stipple view` with
// Dear ImGui (viewer::ToolsPlugin), the browser page with HTML. Neither is known here. Positions
// on the view are pixels from its top-left corner, in a view `view_size` pixels large (the
// window's for `stipple view`, the canvas's drawing buffer in the page).
#include <array>
#include <atomic>
#include <cstdint>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "stipple/pointcloud/clip.hpp"
#include "stipple/pointcloud/profile.hpp"
#include "stipple/renderer/gpu.hpp"
#include "stipple/tools/measure.hpp"
#include "stipple/tools/records.hpp"

namespace stipple {
class Engine;
class Registry;
}  // namespace stipple

namespace stipple::tools {

// A position on the view: the cursor (or touch) in pixels, and the view's size in those pixels.
struct ViewPoint {
  glm::dvec2 cursor{0.0};
  glm::dvec2 view_size{0.0};
};

// Main-world resource: the tools' state (front ends and tests read it; change it through the
// actions, which keep `version` and the derived values right).
struct ToolsState {
  Tool tool = Tool::None;
  std::vector<Measurement> items;
  int active = -1;           // the item being clicked in, if any
  int selected = -1;         // the item the front end shows (and remove_selected removes)
  double profile_width = 0;  // default corridor width (0: 1% of the scene's size)
  std::optional<PointRecord> inspected;
  std::string message;  // the last error or notice
  SourceFrame frame;
  glm::dvec2 gps_extent{0.0, 0.0};  // the loaded cloud's GPS times (a filter's first range)
  uint64_t version = 0;             // bumped on every change (the clip region follows it)
};

// ---- actions ------------------------------------------------------------------------------

// Chooses a tool; a measurement being drawn with another tool is cancelled.
void set_tool(Registry& main, Tool tool);
// A click of the current tool: inspect the point under the cursor, or add it to the measurement
// being drawn (a new one when none is). Returns false (and says why in `message`) where no point
// is under the cursor or no tool is chosen.
bool click(Registry& main, const ViewPoint& at);
// Finishes the measurement being drawn where it has enough points (Enter, a right click).
void finish(Registry& main);
// Removes the last point of the measurement being drawn (the measurement, once it has none).
void undo_point(Registry& main);
// Drops the measurement being drawn.
void cancel(Registry& main);
// Removes a measurement (the selected one with item -1).
void remove(Registry& main, int item = -1);
// Removes every measurement and the inspected point.
void clear(Registry& main);
void select(Registry& main, int item);
void set_label(Registry& main, int item, std::string label);
// A profile's corridor width (> 0), a volume's reference height.
void set_width(Registry& main, int item, double width);
void set_plane_z(Registry& main, int item, double z);

// Dragging a vertex of a finished measurement: the vertex within grab distance of the cursor
// ({item, vertex}; {-1, -1} where none is), moved to the point under the cursor while dragged,
// then put down (a volume is summed again then).
std::pair<int, int> vertex_near(Registry& main, const ViewPoint& at);
void move_vertex(Registry& main, int item, int vertex, const ViewPoint& at);
void put_vertex(Registry& main, int item);

// ---- pointer input -----------------------------------------------------------------------

// Front ends pass their pointer on (positions in view pixels). A left press near a vertex of a
// finished measurement grabs it, and once the pointer moves past a click's tolerance (4 pixels)
// it drags the vertex, which is put down on release; a press and release within the tolerance is
// a click: of the current tool with the left button, finishing the measurement being drawn with
// the right. While the tools hold the pointer (pointer_holds) the camera must not follow it.
enum class Button : uint8_t { Left, Right };
void pointer_down(Registry& main, const ViewPoint& at, Button button);
void pointer_move(Registry& main, const ViewPoint& at);
void pointer_up(Registry& main, const ViewPoint& at, Button button);
// The pointer went to something else (a panel over the view): nothing is grabbed or clicked.
void pointer_cancel(Registry& main);
bool pointer_holds(Registry& main);

// ---- measurements as GeoJSON --------------------------------------------------------------

// Every finished measurement (and the last inspected point, with every attribute) as a GeoJSON
// FeatureCollection in the source CRS.
std::string measurements_geojson(const ToolsState& state);
void save_measurements(const ToolsState& state, const std::string& path);
// Adds the measurements of GeoJSON text (`name` in errors: stipple::Error naming it and the
// feature; nothing is added then) or of a file, measured against the loaded cloud.
void add_measurements(Registry& main, std::string_view geojson, const std::string& name);
void load_measurements(Registry& main, const std::string& path);

// ---- drawing over the view ----------------------------------------------------------------

// What the front end draws over the view this frame, in view pixels: segments, vertices and
// labels in their tool's colour (tool_color), the selected item's lines wider, helper lines
// faint; a ring around the inspected point.
struct OverlayLine {
  glm::dvec2 a{0.0}, b{0.0};
  Tool tool = Tool::None;
  float width = 2.0f;
  bool faint = false;
};
struct OverlayDot {
  glm::dvec2 at{0.0};
  Tool tool = Tool::None;
  int item = -1, vertex = -1;
};
struct OverlayLabel {
  glm::dvec2 at{0.0};  // the point labelled (draw the text up and right of it)
  std::string text;
  Tool tool = Tool::None;
};
struct Overlay {
  std::vector<OverlayLine> lines;
  std::vector<OverlayDot> dots;
  std::vector<OverlayLabel> labels;
  std::optional<glm::dvec2> inspected;
};
Overlay overlay(Registry& main, const glm::dvec2& view_size);
// RGB in 0..1.
glm::vec3 tool_color(Tool tool);

// ---- the profile window -------------------------------------------------------------------

// The profile of the selected (else the last) finished profile measurement, or -1.
int current_profile(const ToolsState& state);
// A profile's cross-section drawn `size` pixels large from the points in memory (filtered and
// clipped as shown), with the frame that maps its pixels to distance along and height.
struct ProfileView {
  int item = -1;
  pc::ProfileFrame frame;
  gpu::Image image;
  double width = 0;      // the corridor's
  uint64_t points = 0;   // in the corridor
  uint64_t version = 0;  // ToolsState::version it was drawn at
};
ProfileView profile_view(Registry& main, int item, const glm::uvec2& size);

// ---- exports ------------------------------------------------------------------------------

// What is shown (filters and clip region) written to a LAS/LAZ file, and a profile's corridor to
// PNG, CSV and LAS (any may be empty), through `stipple clip` and `stipple profile`'s code, in
// the background, one after the other. They need LAS/LAZ/COPC inputs; `message` says so
// otherwise. Each one's result ("wrote ...", "export failed: ...") comes back through
// take_export_results and into `message`.
struct ProfileFiles {
  std::string png, csv, las;
};
void start_clip_export(Registry& main, const std::string& path);
void start_profile_export(Registry& main, int item, const ProfileFiles& files);
struct ExportProgress {
  bool running = false;
  uint64_t done = 0, total = 0;  // input points
};
ExportProgress export_progress(Registry& main);
// The results of the exports finished since the last call (`wait`: waits for those running).
std::vector<std::string> take_export_results(Registry& main, bool wait = false);
// Whether the scene's points can be exported (its inputs are LAS/LAZ/COPC files).
bool can_export(Registry& main);

// ---- the plugin ---------------------------------------------------------------------------

// The state and the systems that keep the scene following it: the tools' clip shapes added to
// the command line's, the pick filter, finished exports. Front ends add it and drive it; the
// source frame and the record source are read from the scene once it is built.
struct ToolsCorePlugin {
  static constexpr std::string_view name = "ToolsCorePlugin";
  static constexpr std::string_view description =
      "the tools' state: inspect, measure, profile, annotate, filter, clip and export";
  std::string measurements_in;   // loaded at start
  std::string measurements_out;  // written when the app exits
  // Exports on their own threads (off: on the caller's, finished when start_* returns; the
  // browser page, whose workers are the engine's pool's).
  bool background_exports = true;
  void build(Engine& engine);
  void finish(Engine& engine);
};

}  // namespace stipple::tools
