#include "tools_bridge.hpp"

#include <emscripten.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <optional>
#include <string>
#include <variant>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/viewport.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/point_cloud.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/tools/tools.hpp"

namespace stipple::web {

namespace {

using nlohmann::json;
using tools::Tool;
using tools::ToolsState;

void report(const char* key, const std::string& value) {
  EM_ASM({ Module.stippleReport(UTF8ToString($0), UTF8ToString($1)); }, key, value.c_str());
}

// The page's queued commands as JSON text (the queue emptied), "" when there are none.
std::string take_queue() {
  // The text's UTF-8 size first (kept on the page), then the text into a buffer of that size.
  const int size = EM_ASM_INT({
    const t = Module.stippleTools;
    if (!t || !t.queue.length) return 0;
    t.taken = JSON.stringify(t.queue.splice(0));
    return lengthBytesUTF8(t.taken) + 1;
  });
  if (size <= 0) return {};
  std::string text(size_t(size), '\0');
  EM_ASM(
      {
        const t = Module.stippleTools;
        stringToUTF8(t.taken, $0, $1);
        t.taken = null;
      },
      text.data(), size);
  text.resize(size_t(size) - 1);
  return text;
}

tools::ViewPoint view_point(Registry& main, const json& c) {
  const auto& v = main.resource<Viewport>();
  return {{c.value("x", 0.0), c.value("y", 0.0)}, {double(v.width), double(v.height)}};
}

std::optional<glm::dvec2> range(const json& j) {
  if (!j.is_array() || j.size() != 2 || !j[0].is_number() || !j[1].is_number()) return std::nullopt;
  const double a = j[0].get<double>(), b = j[1].get<double>();
  return glm::dvec2(std::min(a, b), std::max(a, b));
}

// The filters the page sets: classes kept (absent or null: all), returns (names; empty: all),
// intensity, GPS time and point source ranges (null: off).
void set_filter(pc::PointFilter& f, const json& c) {
  f = {};
  if (c.contains("classes") && c["classes"].is_array()) {
    f.classes.fill(0u);
    for (const auto& k : c["classes"])
      if (k.is_number_integer() && k.get<int>() >= 0 && k.get<int>() < 256)
        f.set_class(uint32_t(k.get<int>()), true);
  }
  if (c.contains("returns") && c["returns"].is_array())
    for (const auto& r : c["returns"]) {
      const std::string name = r.is_string() ? r.get<std::string>() : "";
      if (name == "first") f.returns |= pc::kReturnFirst;
      if (name == "last") f.returns |= pc::kReturnLast;
      if (name == "single") f.returns |= pc::kReturnSingle;
      if (name == "intermediate") f.returns |= pc::kReturnIntermediate;
    }
  if (c.contains("intensity")) f.intensity = range(c["intensity"]);
  if (c.contains("gpsTime")) f.gps_time = range(c["gpsTime"]);
  if (c.contains("pointSource")) f.point_source = range(c["pointSource"]);
}

json filter_json(const pc::PointFilter& f) {
  json j;
  if (f.filters_classes()) {
    json kept = json::array();
    for (uint32_t c = 0; c < 256; ++c)
      if (f.class_kept(c)) kept.push_back(c);
    j["classes"] = kept;
  } else {
    j["classes"] = nullptr;
  }
  json returns = json::array();
  if (f.returns & pc::kReturnFirst) returns.push_back("first");
  if (f.returns & pc::kReturnLast) returns.push_back("last");
  if (f.returns & pc::kReturnSingle) returns.push_back("single");
  if (f.returns & pc::kReturnIntermediate) returns.push_back("intermediate");
  j["returns"] = returns;
  auto r = [](const std::optional<glm::dvec2>& v) {
    return v ? json::array({v->x, v->y}) : json(nullptr);
  };
  j["intensity"] = r(f.intensity);
  j["gpsTime"] = r(f.gps_time);
  j["pointSource"] = r(f.point_source);
  return j;
}

json record_json(const tools::PointRecord& r) {
  json fields = json::object();
  for (const auto& [key, value] : r.fields) {
    if (const double* d = std::get_if<double>(&value))
      fields[key] = *d;
    else if (const std::string* t = std::get_if<std::string>(&value))
      fields[key] = *t;
    else if (const auto* list = std::get_if<std::vector<double>>(&value))
      fields[key] = *list;
  }
  json j = {{"source", r.source},
            {"record", r.index},
            {"fromSource", r.from_source},
            {"position", {r.position.x, r.position.y, r.position.z}},
            {"fields", fields}};
  if (r.lon_lat) j["lonLat"] = {r.lon_lat->x, r.lon_lat->y, r.lon_lat->z};
  return j;
}

json item_json(const tools::Measurement& m, const std::string& unit) {
  const auto& v = m.values;
  json points = json::array();
  for (const auto& p : m.points) points.push_back({p.x, p.y, p.z});
  json values = {{"lengthHorizontal", v.length_horizontal},
                 {"length3d", v.length_3d},
                 {"height", v.height},
                 {"areaHorizontal", v.area_horizontal},
                 {"area3d", v.area_3d},
                 {"perimeter", v.perimeter},
                 {"angleDegrees", v.angle_degrees},
                 {"center", {v.center.x, v.center.y, v.center.z}},
                 {"radius", v.radius},
                 {"volumeAbove", v.volume_above},
                 {"coveredFraction", v.covered_fraction},
                 {"segments3d", v.segments_3d},
                 {"segmentsHorizontal", v.segments_horizontal}};
  return {{"tool", tools::tool_name(m.tool)},
          {"label", m.label},
          {"complete", m.complete},
          {"width", m.width},
          {"points", points},
          {"values", values},
          {"text", m.tool == Tool::Annotation ? m.label : tools::value_text(m, unit)}};
}

// Where the page downloads exports from.
constexpr const char* kExportDir = "/export";

void apply(Engine& engine, const json& c, bool& holds) {
  Registry& main = engine.main();
  auto& s = main.resource<ToolsState>();
  auto& settings = main.resource<pc::PointDrawSettings>();
  const std::string op = c.value("op", "");
  const int item = c.value("item", -1);
  if (op == "tool") {
    const auto tool = tools::parse_tool(c.value("name", "none"));
    if (!tool) {
      s.message = "unknown tool '" + c.value("name", "") + "'";
      return;
    }
    tools::set_tool(main, *tool);
  } else if (op == "down" || op == "up") {
    const auto button = c.value("button", 0) == 2 ? tools::Button::Right : tools::Button::Left;
    if (op == "down")
      tools::pointer_down(main, view_point(main, c), button);
    else
      tools::pointer_up(main, view_point(main, c), button);
  } else if (op == "move") {
    tools::pointer_move(main, view_point(main, c));
  } else if (op == "pointerCancel") {
    tools::pointer_cancel(main);
  } else if (op == "click") {
    tools::click(main, view_point(main, c));
  } else if (op == "finish") {
    tools::finish(main);
  } else if (op == "undo") {
    tools::undo_point(main);
  } else if (op == "cancel") {
    tools::cancel(main);
  } else if (op == "remove") {
    tools::remove(main, item);
  } else if (op == "clear") {
    tools::clear(main);
  } else if (op == "select") {
    tools::select(main, item);
  } else if (op == "label") {
    tools::set_label(main, item, c.value("text", ""));
  } else if (op == "width") {
    tools::set_width(main, item, c.value("value", 0.0));
  } else if (op == "plane") {
    tools::set_plane_z(main, item, c.value("value", 0.0));
  } else if (op == "profileWidth") {
    s.profile_width = std::max(0.0, c.value("value", 0.0));
  } else if (op == "load") {
    try {
      tools::add_measurements(main, c.value("text", ""), c.value("name", "measurements"));
    } catch (const std::exception& e) {
      s.message = e.what();
      report("toolError", e.what());
    }
  } else if (op == "filter") {
    set_filter(settings.render.filter, c);
    // GPS-time and point-source filters read the points' extras, which the compute rasterizer
    // does not bind: billboards then, as `stipple view`'s panel offers.
    if (settings.compute && settings.render.filter.needs_extras()) settings.compute = false;
    ++s.version;
  } else if (op == "clipMode") {
    try {
      settings.render.clip.mode = pc::parse_clip_mode(c.value("mode", "inside"));
      ++s.version;
    } catch (const std::exception& e) {
      s.message = e.what();
    }
  } else if (op == "exportClip" || op == "exportProfile") {
    std::filesystem::create_directories(kExportDir);
    const std::string base = std::string(kExportDir) + "/" + c.value("name", "");
    if (op == "exportClip") {
      tools::start_clip_export(main, base);
    } else {
      tools::ProfileFiles files;
      if (c.value("csv", false)) files.csv = base + ".csv";
      if (c.value("las", false)) files.las = base + ".las";
      if (c.value("png", false)) files.png = base + ".png";
      tools::start_profile_export(main, item < 0 ? tools::current_profile(s) : item, files);
    }
    // The page's exports run on its thread (ToolsCorePlugin::background_exports off): their
    // results are in now.
    for (const std::string& result : tools::take_export_results(main, true))
      report("export", json({{"result", result}, {"dir", kExportDir}}).dump());
  } else if (op == "profile") {
    const int p = item < 0 ? tools::current_profile(s) : item;
    const uint32_t w = std::clamp(c.value("width", 600), 16, 4096);
    const uint32_t h = std::clamp(c.value("height", 240), 16, 4096);
    const tools::ProfileView view = tools::profile_view(main, p, {w, h});
    json frame = {{"item", view.item},
                  {"length", view.frame.length},
                  {"zRange", {view.frame.z_range.x, view.frame.z_range.y}},
                  {"zOrigin", view.frame.z_origin},
                  {"gridStep", {view.frame.grid_step.x, view.frame.grid_step.y}},
                  {"pixelsPerUnit", {view.frame.pixels_per_unit_x, view.frame.pixels_per_unit_z}},
                  {"width", view.width},
                  {"points", view.points}};
    // The pixel of (0 along, the lowest height): the page maps its clicks back from it.
    const glm::dvec2 origin = view.frame.to_pixel(0, view.frame.z_range.x, {w, h});
    frame["origin"] = {origin.x, origin.y};
    const std::string text = frame.dump();
    EM_ASM(
        {
          const f = Module.stippleToolsProfile;
          if (!f) return;
          const pixels = new Uint8ClampedArray(HEAPU8.subarray($2 >>> 0, ($2 >>> 0) + $0 * $1 * 4));
          f(JSON.parse(UTF8ToString($3)), {width : $0, height : $1, data : pixels});
        },
        view.image.width, view.image.height, view.image.rgba.data(), text.c_str());
    return;  // nothing to draw again
  } else {
    s.message = "unknown tool command '" + op + "'";
    return;
  }
  holds = holds || tools::pointer_holds(main);
}

struct BridgeState {
  uint64_t version = ~uint64_t(0);
  std::string message;
  Tool tool = Tool::None;
  int active = -1, selected = -1;
  pc::PointFilter filter;
  pc::ClipMode clip_mode = pc::ClipMode::Inside;
  size_t complete = 0;
  bool inspected = false;
  bool overlay_empty = true;
};

BridgeState& bridge_state() {
  static BridgeState state;
  return state;
}

}  // namespace

bool take_tool_commands(Engine& engine, bool& holds_pointer) {
  holds_pointer = false;
  const std::string text = take_queue();
  if (text.empty()) return false;
  const uint64_t version = engine.main().resource<ToolsState>().version;
  const json commands = json::parse(text, nullptr, false);
  if (!commands.is_array()) return false;
  for (const json& c : commands) {
    if (!c.is_object()) continue;
    try {
      apply(engine, c, holds_pointer);
    } catch (const std::exception& e) {
      engine.main().resource<ToolsState>().message = e.what();
      STIPPLE_WARN("tool command: {}", e.what());
    }
  }
  holds_pointer = holds_pointer || tools::pointer_holds(engine.main());
  // Drawn again only where a measurement, filter or the clip changed (pointer moves alone do
  // not); the state is reported either way (report_tools).
  return engine.main().resource<ToolsState>().version != version;
}

void report_tools(Engine& engine, bool force) {
  Registry& main = engine.main();
  const auto* state = main.try_resource<ToolsState>();
  if (!state) return;
  const auto& s = *state;
  const auto& settings = main.resource<pc::PointDrawSettings>();
  auto& b = bridge_state();
  if (!force && b.version == s.version && b.message == s.message && b.tool == s.tool &&
      b.active == s.active && b.selected == s.selected && b.filter == settings.render.filter &&
      b.clip_mode == settings.render.clip.mode)
    return;
  b.version = s.version;
  b.message = s.message;
  b.tool = s.tool;
  b.active = s.active;
  b.selected = s.selected;
  b.filter = settings.render.filter;
  b.clip_mode = settings.render.clip.mode;
  json items = json::array();
  size_t complete = 0;
  for (const auto& m : s.items) {
    items.push_back(item_json(m, s.frame.unit));
    complete += m.complete;
  }
  json j = {{"tool", tools::tool_name(s.tool)},
            {"active", s.active},
            {"selected", s.selected},
            {"message", s.message},
            {"unit", s.frame.unit},
            {"unitSymbol", tools::unit_symbol(s.frame.unit)},
            {"epsg", s.frame.epsg},
            {"items", items},
            {"filter", filter_json(settings.render.filter)},
            {"clipMode", pc::clip_mode_name(settings.render.clip.mode)},
            {"canExport", tools::can_export(main)},
            {"gpsExtent", {s.gps_extent.x, s.gps_extent.y}},
            {"geojson", tools::measurements_geojson(s)}};
  if (force) {
    // The ASPRS classes with the names and colours the classification mode draws them in.
    json legend = json::array();
    const auto& palette = pc::classification_palette();
    for (uint32_t c = 0; c < palette.size(); ++c) {
      const glm::vec3 rgb = palette[c];
      legend.push_back({{"code", c},
                        {"name", pc::classification_name(c)},
                        {"color", fmt::format("rgb({},{},{})", int(rgb.r * 255), int(rgb.g * 255),
                                              int(rgb.b * 255))}});
    }
    j["legend"] = legend;
  }
  if (s.inspected) j["inspected"] = record_json(*s.inspected);
  report("tools", j.dump());
  // Events: a point inspected, a measurement finished.
  if (s.inspected && (!b.inspected || force)) report("pick", record_json(*s.inspected).dump());
  b.inspected = s.inspected.has_value();
  if (complete > b.complete && !s.items.empty()) {
    int last = s.selected >= 0 ? s.selected : int(s.items.size()) - 1;
    report("measure", item_json(s.items[size_t(last)], s.frame.unit).dump());
  }
  b.complete = complete;
}

void report_overlay(Engine& engine) {
  Registry& main = engine.main();
  if (!main.try_resource<ToolsState>()) return;
  const auto& v = main.resource<Viewport>();
  const tools::Overlay o = tools::overlay(main, {double(v.width), double(v.height)});
  auto& b = bridge_state();
  const bool empty = o.lines.empty() && o.dots.empty() && o.labels.empty() && !o.inspected;
  if (empty && b.overlay_empty) return;
  b.overlay_empty = empty;
  auto color = [](Tool t) {
    const glm::vec3 c = tools::tool_color(t);
    return fmt::format("rgb({},{},{})", int(c.r * 255), int(c.g * 255), int(c.b * 255));
  };
  json lines = json::array(), dots = json::array(), labels = json::array();
  for (const auto& l : o.lines)
    lines.push_back({l.a.x, l.a.y, l.b.x, l.b.y, color(l.tool), l.width, l.faint});
  for (const auto& d : o.dots) dots.push_back({d.at.x, d.at.y, color(d.tool), d.item, d.vertex});
  for (const auto& l : o.labels) labels.push_back({l.at.x, l.at.y, l.text, color(l.tool)});
  json j = {{"width", v.width},
            {"height", v.height},
            {"lines", lines},
            {"dots", dots},
            {"labels", labels}};
  j["inspected"] = o.inspected ? json::array({o.inspected->x, o.inspected->y}) : json(nullptr);
  report("overlay", j.dump());
}

}  // namespace stipple::web
