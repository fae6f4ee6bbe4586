#include "stipple/viewer/tools_plugin.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <future>
#include <memory>

#include <fmt/format.h>
#include <imgui.h>
#include <glm/geometric.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/world.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/platform/input.hpp"
#include "stipple/pointcloud/clip.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/profile.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/viewer/camera_controller.hpp"
#include "stipple/viewer/ui_plugin.hpp"
#include "stipple/viewer/window_plugins.hpp"

namespace stipple::viewer {

void save_measurements(const ToolsState& state, const std::string& path) {
  std::vector<io::GeoFeature> features;
  for (const Measurement& m : state.items)
    if (m.complete) features.push_back(to_feature(m, state.frame));
  if (state.inspected) {
    // The last inspected record: every attribute, coordinates in full double precision.
    const PointRecord& r = *state.inspected;
    io::GeoFeature f;
    f.type = "Point";
    f.parts = {{r.position}};
    f.properties["tool"] = std::string("inspect");
    f.properties["source"] = r.source;
    f.properties["record"] = double(r.index);
    f.properties["from_source"] = double(r.from_source);
    if (r.lon_lat) {
      f.properties["longitude"] = r.lon_lat->x;
      f.properties["latitude"] = r.lon_lat->y;
    }
    for (const auto& [key, value] : r.fields) f.properties[key] = value;
    features.push_back(std::move(f));
  }
  io::write_geojson(path, features, state.frame.epsg);
}

void load_measurements(ToolsState& state, const std::string& path) {
  const io::GeoDocument doc = io::read_geojson(path);
  std::vector<Measurement> loaded;
  for (size_t i = 0; i < doc.features.size(); ++i) {
    if (doc.features[i].text("tool") == "inspect") continue;  // a record, not a measurement
    loaded.push_back(from_feature(doc.features[i], state.frame, i, path));
  }
  for (Measurement& m : loaded) state.items.push_back(std::move(m));
  ++state.version;
}

namespace {

using platform::Key;
using platform::MouseButton;

constexpr double kPickPixels = 3.0;   // cone radius of a tool's click
constexpr double kGrabPixels = 8.0;   // how near a vertex must be to drag it
constexpr double kClickPixels = 4.0;  // a press and release this close are a click

// Main-world resource: what the systems keep between frames.
struct ToolsRuntime {
  std::string measurements_out;
  bool written = false;
  RecordSource records;
  pc::ClipRegion base_clip;  // the command line's shapes
  uint64_t clip_version = ~uint64_t(0);
  glm::dvec2 press{0.0}, right_press{0.0};
  bool left_down = false;
  int drag_item = -1, drag_vertex = -1;  // the vertex under the last left press
  bool dragging = false;                 // ... and the cursor has moved it
  Tool tool_shown = Tool::None;          // the tool the panel last showed
  // Filters panel.
  glm::dvec2 gps_extent{0.0, 0.0};
  // Profile window.
  int profile_item = -1;
  uint64_t profile_version = ~uint64_t(0);
  uintptr_t profile_texture = 0;
  pc::ProfileFrame profile_frame;
  glm::uvec2 profile_size{900, 320};
  std::vector<glm::dvec2> profile_clicks;  // along, height
  // Export.
  std::array<char, 512> clip_path{}, profile_png{}, profile_csv{}, profile_las{}, save_path{};
  std::shared_ptr<std::atomic<uint64_t>> progress = std::make_shared<std::atomic<uint64_t>>(0);
  uint64_t progress_total = 0;
  // Exports in order: each waits for the one before, so keys pressed in a row all run.
  std::vector<std::shared_future<std::string>> jobs;
};

void set_text(std::array<char, 512>& buffer, const std::string& text) {
  std::snprintf(buffer.data(), buffer.size(), "%s", text.c_str());
}

const Camera* first_camera(Registry& main) {
  const Camera* camera = nullptr;
  main.view<Camera>().each([&](const Camera& c) {
    if (!camera) camera = &c;
  });
  return camera;
}

glm::dvec2 viewport_of(Registry& main) {
  return glm::dvec2(main.resource<WindowState>().window_size);
}

// Window coordinates of a local-frame point; nullopt behind the camera.
std::optional<glm::dvec2> project(const Camera& camera, const glm::dvec2& viewport,
                                  const glm::dvec3& local) {
  const glm::dvec3 rel = z_up_to_y_up(local) - camera.position;
  const glm::dvec4 clip = camera.projection(viewport.x / std::max(viewport.y, 1.0)) *
                          camera.view_rotation() * glm::dvec4(rel, 1.0);
  if (clip.w <= 1e-9) return std::nullopt;
  return glm::dvec2((clip.x / clip.w + 1) * 0.5 * viewport.x,
                    (1 - clip.y / clip.w) * 0.5 * viewport.y);
}

std::optional<pc::PickHit> pick_at(Registry& main, const glm::dvec2& cursor) {
  const Camera* camera = first_camera(main);
  if (!camera) return std::nullopt;
  const glm::dvec2 viewport = viewport_of(main);
  const double tan_radius =
      kPickPixels * 2.0 * std::tan(camera->fov_y * 0.5) / std::max(viewport.y, 1.0);
  return pc::pick_scene(main,
                        {camera->position, cursor_ray(*camera, cursor, viewport), tan_radius});
}

const pc::PointCloud* loaded_cloud(Registry& main) {
  const pc::PointCloud* cloud = nullptr;
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& d) {
    if (!cloud) cloud = d.cloud.get();
  });
  return cloud;
}

// The point under the cursor in the local source frame: the record's own coordinates where the
// source can be read again (full precision), else the drawn position.
std::optional<glm::dvec3> point_under(Registry& main, const glm::dvec2& cursor,
                                      std::optional<PointRecord>* record = nullptr) {
  const auto hit = pick_at(main, cursor);
  if (!hit) return std::nullopt;
  auto& rt = main.resource<ToolsRuntime>();
  try {
    PointRecord r = read_point_record(rt.records, *hit);
    const glm::dvec3 local = r.local;
    if (record) *record = std::move(r);
    return local;
  } catch (const Error& e) {
    main.resource<ToolsState>().message = e.what();
    return y_up_to_z_up(hit->point);
  }
}

void remeasure(Registry& main, Measurement& m) {
  const auto& settings = main.resource<pc::PointDrawSettings>();
  measure_with_cloud(m, loaded_cloud(main), settings.render.filter, settings.render.clip);
}

void finish_active(Registry& main) {
  auto& s = main.resource<ToolsState>();
  if (s.active < 0) return;
  Measurement& m = s.items[size_t(s.active)];
  if (int(m.points.size()) < tool_min_points(m.tool)) return;
  m.complete = true;
  remeasure(main, m);
  s.selected = s.active;
  s.active = -1;
  ++s.version;
}

void cancel_active(ToolsState& s) {
  if (s.active < 0) return;
  s.items.erase(s.items.begin() + s.active);
  s.active = -1;
  s.selected = -1;
  ++s.version;
}

void start_clip_export(Registry& main);
void start_profile_export(Registry& main, int item);
int current_profile(const ToolsState& s);

// A click of the current tool at `cursor`.
void tool_click(Registry& main, const glm::dvec2& cursor) {
  auto& s = main.resource<ToolsState>();
  std::optional<PointRecord> record;
  const auto point = point_under(main, cursor, &record);
  if (!point) {
    s.message = "no point under the cursor";
    return;
  }
  if (s.tool == Tool::Inspect) {
    s.inspected = std::move(record);
    if (!s.inspected) {
      PointRecord r;
      r.local = r.position = *point;
      s.inspected = r;
    }
    s.message.clear();
    return;
  }
  if (s.active < 0) {
    Measurement m;
    m.tool = s.tool;
    if (s.tool == Tool::Profile) {
      double width = s.profile_width;
      if (!(width > 0)) {
        const auto* scene = main.try_resource<pc::SceneInfo>();
        width = scene && !scene->world_bounds.empty()
                    ? glm::length(scene->world_bounds.size()) * 0.01
                    : 1.0;
      }
      m.width = width;
    }
    if (s.tool == Tool::Annotation) {
      size_t n = 1;
      for (const Measurement& other : s.items) n += other.tool == Tool::Annotation;
      m.label = fmt::format("Annotation {}", n);
    }
    s.items.push_back(std::move(m));
    s.active = int(s.items.size()) - 1;
  }
  Measurement& m = s.items[size_t(s.active)];
  m.points.push_back(*point);
  compute_values(m);
  ++s.version;
  s.message.clear();
  if (tool_points(m.tool) > 0 && int(m.points.size()) >= tool_points(m.tool)) finish_active(main);
}

// The vertex nearest to the cursor within kGrabPixels: {item, vertex}.
std::pair<int, int> vertex_near(Registry& main, const glm::dvec2& cursor) {
  const Camera* camera = first_camera(main);
  const auto& s = main.resource<ToolsState>();
  std::pair<int, int> best{-1, -1};
  if (!camera) return best;
  const glm::dvec2 viewport = viewport_of(main);
  double best_d = kGrabPixels;
  for (size_t i = 0; i < s.items.size(); ++i) {
    if (!s.items[i].complete) continue;
    for (size_t v = 0; v < s.items[i].points.size(); ++v) {
      const auto px = project(*camera, viewport, s.items[i].points[v]);
      if (!px) continue;
      const double d = glm::distance(*px, cursor);
      if (d <= best_d) best_d = d, best = {int(i), int(v)};
    }
  }
  return best;
}

void tools_input(Registry& main) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  auto& input = main.resource<platform::InputState>();
  auto* capture = main.try_resource<UiCapture>();
  if (!capture) capture = &main.insert_resource(UiCapture{});
  // With the UI, UiPlugin writes UiCapture afresh every frame; without it, it is ours alone.
  const bool with_ui = main.try_resource<UiSettings>() != nullptr;
  const bool ui_mouse = with_ui && capture->mouse, ui_keys = with_ui && capture->keyboard;
  capture->mouse = ui_mouse;
  if (!ui_keys) {
    static constexpr std::pair<Key, Tool> kKeys[] = {
        {Key::Num1, Tool::Inspect}, {Key::Num2, Tool::Distance}, {Key::Num3, Tool::Height},
        {Key::Num4, Tool::Area},    {Key::Num5, Tool::Angle},    {Key::Num6, Tool::Circle},
        {Key::Num7, Tool::Volume},  {Key::Num8, Tool::Profile},  {Key::Num9, Tool::Annotation},
        {Key::B, Tool::ClipBox},    {Key::G, Tool::ClipPolygon}, {Key::Num0, Tool::None}};
    for (const auto& [key, tool] : kKeys)
      if (input.pressed(key) && s.tool != tool) {
        cancel_active(s);
        s.tool = tool;
      }
    if (input.pressed(Key::Enter)) finish_active(main);
    if (input.pressed(Key::X)) start_clip_export(main);
    if (input.pressed(Key::R)) start_profile_export(main, current_profile(s));
    if (input.pressed(Key::Backspace) && s.active >= 0) {
      auto& pts = s.items[size_t(s.active)].points;
      if (!pts.empty()) pts.pop_back();
      if (pts.empty()) cancel_active(s);
      ++s.version;
    }
    if (input.pressed(Key::Escape) && s.active >= 0) {
      cancel_active(s);
      input.key_pressed[size_t(Key::Escape)] = false;  // not a quit: it cancelled the tool
    }
    if (input.pressed(Key::Delete) && s.selected >= 0 && s.selected < int(s.items.size()) &&
        s.active < 0) {
      s.items.erase(s.items.begin() + s.selected);
      s.selected = -1;
      ++s.version;
    }
  }
  // Clicks belong to the tools while one is chosen; dragging a vertex holds the mouse.
  capture->double_click = s.tool != Tool::None;
  if (ui_mouse) {
    rt.left_down = false;
    return;
  }
  if (input.pressed(MouseButton::Left)) {
    rt.press = input.cursor;
    rt.left_down = true;
    if (s.active < 0) {
      const auto [item, vertex] = vertex_near(main, input.cursor);
      rt.drag_item = item;
      rt.drag_vertex = vertex;
    }
  }
  if (input.pressed(MouseButton::Right)) rt.right_press = input.cursor;
  // A press near a vertex holds the mouse (no orbit); it becomes a drag once the cursor moves
  // past a click's tolerance, and stays a click (for the current tool) otherwise.
  const bool grabbed = rt.drag_item >= 0 && rt.drag_item < int(s.items.size());
  if (grabbed && rt.left_down && glm::distance(input.cursor, rt.press) > kClickPixels)
    rt.dragging = true;
  const bool dragging = grabbed && rt.dragging;
  if (grabbed) capture->mouse = true;
  if (dragging) {
    if (glm::length(input.cursor_delta) > 0)
      if (const auto p = point_under(main, input.cursor)) {
        Measurement& m = s.items[size_t(rt.drag_item)];
        m.points[size_t(rt.drag_vertex)] = *p;
        compute_values(m);
        ++s.version;
      }
  }
  if (input.button_released[size_t(MouseButton::Left)]) {
    const bool click = rt.left_down && glm::distance(input.cursor, rt.press) <= kClickPixels;
    if (dragging) {
      Measurement& m = s.items[size_t(rt.drag_item)];
      remeasure(main, m);  // volumes are summed once the vertex is put down
      s.selected = rt.drag_item;
      ++s.version;
    } else if (click && s.tool != Tool::None) {
      tool_click(main, input.cursor);
    }
    rt.left_down = false;
    rt.dragging = false;
    rt.drag_item = rt.drag_vertex = -1;
  }
  if (input.button_released[size_t(MouseButton::Right)] &&
      glm::distance(input.cursor, rt.right_press) <= kClickPixels)
    finish_active(main);
}

// Everything the tools contribute to the clip region, after the command line's shapes.
pc::ClipRegion clip_region(Registry& main, const ToolsState& s, const pc::ClipRegion& base) {
  pc::ClipRegion region = base;
  double lo = -1e300, hi = 1e300;
  if (const auto* scene = main.try_resource<pc::SceneInfo>();
      scene && !scene->world_bounds.empty()) {
    lo = scene->world_bounds.min.y - 1;
    hi = scene->world_bounds.max.y + 1;
  }
  for (const Measurement& m : s.items) {
    if (!m.complete) continue;
    if (m.tool == Tool::ClipBox && m.points.size() == 3)
      region.boxes.push_back(box_from_clicks(m.points[0], m.points[1], m.points[2], lo, hi));
    if (m.tool == Tool::ClipPolygon && m.points.size() >= 3) {
      pc::ClipPolygon polygon;
      std::vector<glm::dvec2> ring;
      for (const glm::dvec3& p : m.points) ring.emplace_back(p.x, p.y);
      polygon.rings = {ring};
      region.polygons.push_back(std::move(polygon));
    }
  }
  region.boxes.resize(std::min(region.boxes.size(), pc::kMaxGpuClipShapes));
  region.polygons.resize(std::min(region.polygons.size(), pc::kMaxGpuClipShapes));
  return region;
}

void tools_sync(Registry& main) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  auto& settings = main.resource<pc::PointDrawSettings>();
  if (rt.clip_version != s.version) {
    const pc::ClipMode mode = settings.render.clip.mode;
    settings.render.clip = clip_region(main, s, rt.base_clip);
    settings.render.clip.mode = mode;
    rt.clip_version = s.version;
  }
  main.insert_resource(pc::PickFilter{settings.render.filter, settings.render.clip});
  // Finished exports report; those in flight finish before the viewer goes.
  while (!rt.jobs.empty() &&
         (main.resource<AppExit>().requested ||
          rt.jobs.front().wait_for(std::chrono::seconds(0)) == std::future_status::ready)) {
    s.message = rt.jobs.front().get();
    rt.jobs.erase(rt.jobs.begin());
    std::printf("%s\n", s.message.c_str());
    std::fflush(stdout);
  }
  if (!rt.measurements_out.empty() && !rt.written && main.resource<AppExit>().requested) {
    rt.written = true;
    try {
      save_measurements(s, rt.measurements_out);
    } catch (const Error& e) {
      STIPPLE_ERROR("{}", e.what());
    }
  }
}

// ---- drawing over the view ----------------------------------------------------------------

ImU32 tool_color(Tool tool, float alpha = 1.0f) {
  switch (tool) {
    case Tool::Distance:
      return ImColor(1.0f, 0.85f, 0.2f, alpha);
    case Tool::Height:
      return ImColor(0.3f, 0.9f, 1.0f, alpha);
    case Tool::Area:
      return ImColor(0.4f, 1.0f, 0.4f, alpha);
    case Tool::Angle:
    case Tool::Circle:
      return ImColor(1.0f, 0.5f, 0.9f, alpha);
    case Tool::Volume:
      return ImColor(1.0f, 0.55f, 0.2f, alpha);
    case Tool::Profile:
      return ImColor(0.6f, 0.7f, 1.0f, alpha);
    case Tool::ClipBox:
    case Tool::ClipPolygon:
      return ImColor(1.0f, 0.3f, 0.3f, alpha);
    default:
      return ImColor(1.0f, 1.0f, 1.0f, alpha);
  }
}

void label(ImDrawList* draw, const glm::dvec2& at, const std::string& text, ImU32 color) {
  const ImVec2 size = ImGui::CalcTextSize(text.c_str());
  const ImVec2 p(float(at.x) + 6, float(at.y) - size.y - 4);
  draw->AddRectFilled(ImVec2(p.x - 3, p.y - 2), ImVec2(p.x + size.x + 3, p.y + size.y + 2),
                      IM_COL32(0, 0, 0, 170), 3.0f);
  draw->AddText(p, color, text.c_str());
}

void tools_overlay(Registry& main) {
  const auto* ui = main.try_resource<UiSettings>();
  if (!ui) return;  // no ImGui frame
  const Camera* camera = first_camera(main);
  if (!camera) return;
  const auto& s = main.resource<ToolsState>();
  const glm::dvec2 viewport = viewport_of(main);
  ImDrawList* draw = ImGui::GetBackgroundDrawList();
  auto px = [&](const glm::dvec3& p) { return project(*camera, viewport, p); };
  auto line = [&](const glm::dvec3& a, const glm::dvec3& b, ImU32 color, float thickness) {
    const auto pa = px(a), pb = px(b);
    if (pa && pb)
      draw->AddLine(ImVec2(float(pa->x), float(pa->y)), ImVec2(float(pb->x), float(pb->y)), color,
                    thickness);
  };
  const std::string unit = s.frame.unit;
  for (size_t i = 0; i < s.items.size(); ++i) {
    const Measurement& m = s.items[i];
    const ImU32 color = tool_color(m.tool);
    const float thickness = int(i) == s.selected ? 3.0f : 2.0f;
    const auto& p = m.points;
    if (m.tool == Tool::ClipBox && p.size() == 3) {
      const pc::ClipBox box = box_from_clicks(p[0], p[1], p[2], std::min({p[0].z, p[1].z, p[2].z}),
                                              std::max({p[0].z, p[1].z, p[2].z}) + 1);
      const auto c = box.corners();
      for (int k = 0; k < 4; ++k) {
        line(c[size_t(k)], c[size_t((k + 1) % 4)], color, thickness);
        line(c[size_t(k + 4)], c[size_t((k + 1) % 4 + 4)], color, thickness);
        line(c[size_t(k)], c[size_t(k + 4)], color, thickness);
      }
    } else if (m.tool == Tool::Volume && p.size() == 4) {
      const pc::ClipBox box = box_from_clicks(p[1], p[2], p[3], p[0].z, p[0].z);
      const auto c = box.corners();
      for (int k = 0; k < 4; ++k) line(c[size_t(k)], c[size_t((k + 1) % 4)], color, thickness);
    } else {
      const bool closed = (m.tool == Tool::Area || m.tool == Tool::ClipPolygon) && p.size() >= 3;
      for (size_t k = 0; k + 1 < p.size(); ++k) line(p[k], p[k + 1], color, thickness);
      if (closed) line(p.back(), p.front(), color, thickness);
      if (m.tool == Tool::Circle && m.values.radius > 0) {
        // The circle in its plane, as 64 segments.
        const glm::dvec3 c = m.values.center;
        const glm::dvec3 n = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
        const glm::dvec3 u = glm::normalize(p[0] - c), w = glm::cross(n, u);
        for (int k = 0; k < 64; ++k) {
          const double a0 = k * 2 * M_PI / 64, a1 = (k + 1) * 2 * M_PI / 64;
          line(c + m.values.radius * (std::cos(a0) * u + std::sin(a0) * w),
               c + m.values.radius * (std::cos(a1) * u + std::sin(a1) * w), color, 1.5f);
        }
      }
      if (m.tool == Tool::Height && p.size() == 2) {
        // The vertical and horizontal legs.
        const glm::dvec3 corner(p[1].x, p[1].y, p[0].z);
        line(p[0], corner, tool_color(m.tool, 0.5f), 1.0f);
        line(corner, p[1], tool_color(m.tool, 0.5f), 1.0f);
      }
    }
    for (const glm::dvec3& v : p)
      if (const auto at = px(v))
        draw->AddCircleFilled(ImVec2(float(at->x), float(at->y)), 4.0f, color);
    if (p.empty()) continue;
    std::string text = m.tool == Tool::Annotation ? m.label : value_text(m, unit);
    if (!m.label.empty() && m.tool != Tool::Annotation) text = m.label + ": " + text;
    if (m.tool == Tool::Distance && m.complete && p.size() > 2)
      for (size_t k = 0; k + 1 < p.size(); ++k)
        if (const auto mid = px((p[k] + p[k + 1]) * 0.5))
          label(draw, *mid, fmt::format("{:.2f}", m.values.segments_3d[k]), color);
    glm::dvec3 anchor = p.back();
    if (m.tool == Tool::Circle && m.values.radius > 0) anchor = m.values.center;
    if (const auto at = px(anchor)) label(draw, *at, text, color);
  }
  if (s.inspected)
    if (const auto at = px(s.inspected->local)) {
      draw->AddCircle(ImVec2(float(at->x), float(at->y)), 7.0f, IM_COL32(255, 255, 255, 255), 0,
                      2.0f);
    }
}

// ---- the panel ---------------------------------------------------------------------------

void run_in_background(ToolsRuntime& rt, ToolsState& s, uint64_t total,
                       std::function<std::string()> work) {
  std::shared_future<std::string> before;
  if (!rt.jobs.empty()) before = rt.jobs.back();
  rt.progress_total = total;
  s.message = "exporting ...";
  auto progress = rt.progress;
  rt.jobs.push_back(std::async(std::launch::async, [work, before, progress] {
                      if (before.valid()) before.wait();
                      progress->store(0);
                      try {
                        return work();
                      } catch (const Error& e) {
                        return std::string("export failed: ") + e.what();
                      }
                    }).share());
}

uint64_t input_points(const pc::PointCloud& cloud) {
  uint64_t total = 0;
  for (const auto& f : cloud.files) total += io::read_las_header(f).point_count;
  return total;
}

// The clip export: what is shown (filters and clip region) through `stipple clip`'s code.
void start_clip_export(Registry& main) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  const pc::PointCloud* cloud = loaded_cloud(main);
  if (!cloud || cloud->files.empty()) {
    s.message = "export needs LAS/LAZ/COPC inputs";
    return;
  }
  const auto& settings = main.resource<pc::PointDrawSettings>();
  pc::ClipJob job;
  job.inputs = cloud->files;
  job.output = rt.clip_path.data();
  job.filter = settings.render.filter;
  job.region = settings.render.clip;
  job.enu_origin = cloud->enu_origin;
  job.progress = false;
  job.points_done = rt.progress.get();
  auto progress = rt.progress;  // keeps the counter alive for the job
  run_in_background(rt, s, input_points(*cloud), [job, progress] {
    const pc::ClipResult r = pc::clip_to_las(job);
    return fmt::format("wrote {} of {} points to {}", r.points_written, r.points_read,
                       job.output.string());
  });
}

// The profile export of measurement `item` through `stipple profile`'s code.
void start_profile_export(Registry& main, int item) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  const pc::PointCloud* cloud = loaded_cloud(main);
  if (!cloud || cloud->files.empty()) {
    s.message = "export needs LAS/LAZ/COPC inputs";
    return;
  }
  if (item < 0 || item >= int(s.items.size()) || s.items[size_t(item)].tool != Tool::Profile ||
      !s.items[size_t(item)].complete) {
    s.message = "no profile to export";
    return;
  }
  const Measurement& m = s.items[size_t(item)];
  const auto& settings = main.resource<pc::PointDrawSettings>();
  pc::ProfileJob job;
  job.inputs = cloud->files;
  for (const glm::dvec3& p : m.points) job.line.vertices.emplace_back(p.x, p.y);
  job.line.width = m.width;
  job.filter = settings.render.filter;
  job.region = settings.render.clip;
  job.enu_origin = cloud->enu_origin;
  job.png = rt.profile_png.data();
  job.csv = rt.profile_csv.data();
  job.las = rt.profile_las.data();
  job.image.color = settings.render.color;
  job.progress = false;
  job.points_done = rt.progress.get();
  auto progress = rt.progress;
  run_in_background(rt, s, input_points(*cloud), [job, progress] {
    const pc::ProfileResult r = pc::run_profile(job);
    return fmt::format("profile: {} points in the corridor", r.points_in_corridor);
  });
}

// The last complete profile, or the selected one.
int current_profile(const ToolsState& s) {
  if (s.selected >= 0 && s.selected < int(s.items.size()) &&
      s.items[size_t(s.selected)].tool == Tool::Profile && s.items[size_t(s.selected)].complete)
    return s.selected;
  int item = -1;
  for (size_t i = 0; i < s.items.size(); ++i)
    if (s.items[i].tool == Tool::Profile && s.items[i].complete) item = int(i);
  return item;
}

void export_panel(Registry& main, ToolsRuntime& rt) {
  const pc::PointCloud* cloud = loaded_cloud(main);
  if (!cloud || cloud->files.empty()) {
    ImGui::TextDisabled("export: needs LAS/LAZ/COPC inputs");
    return;
  }
  ImGui::InputText("clip file", rt.clip_path.data(), rt.clip_path.size());
  if (ImGui::Button("export clip (X): filters and clip region")) start_clip_export(main);
  if (!rt.jobs.empty())
    ImGui::ProgressBar(rt.progress_total ? float(rt.progress->load()) / float(rt.progress_total)
                                         : 0.0f);
}

void profile_window(Registry& main, ToolsState& s, ToolsRuntime& rt) {
  const int item = current_profile(s);
  if (item < 0) return;
  const Measurement& m = s.items[size_t(item)];
  const pc::PointCloud* cloud = loaded_cloud(main);
  const auto& settings = main.resource<pc::PointDrawSettings>();
  auto& images = main.resource<UiImages>();
  pc::ProfileLine line;
  for (const glm::dvec3& p : m.points) line.vertices.emplace_back(p.x, p.y);
  line.width = m.width;
  if (rt.profile_item != item || rt.profile_version != s.version) {
    rt.profile_item = item;
    rt.profile_version = s.version;
    rt.profile_clicks.clear();
    const double z0 = m.points[0].z;
    std::vector<pc::ProfileSample> samples;
    if (cloud)
      samples = pc::profile_samples(*cloud, line, settings.render.filter, settings.render.clip, z0);
    glm::dvec2 z(std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity());
    for (const auto& p : samples) z = {std::min(z.x, z0 + p.height), std::max(z.y, z0 + p.height)};
    if (samples.empty()) z = {z0 - 1, z0 + 1};
    rt.profile_frame = pc::make_profile_frame(line.length(), z, z0, rt.profile_size);
    pc::ProfileImageOptions options;
    options.width = rt.profile_size.x;
    options.height = rt.profile_size.y;
    options.color = pc::resolve_color_mode(cloud ? cloud->attributes : pc::CloudAttributes{},
                                           settings.render.color);
    options.background = settings.render.background;
    gpu::Image image = pc::draw_profile(samples, rt.profile_frame, options,
                                        cloud ? cloud->attributes : pc::CloudAttributes{});
    auto ui_image = std::make_shared<UiImage>();
    ui_image->width = image.width;
    ui_image->height = image.height;
    ui_image->rgba = std::move(image.rgba);
    if (!rt.profile_texture) rt.profile_texture = images.next_id++;
    images.images[rt.profile_texture] = std::move(ui_image);
  }
  ImGui::SetNextWindowSize(ImVec2(float(rt.profile_size.x) + 20, float(rt.profile_size.y) + 150),
                           ImGuiCond_FirstUseEver);
  ImGui::Begin("profile");
  ImGui::Text("length %.3f, width %.3f; heights %.3f to %.3f; grid %g along, %g up",
              rt.profile_frame.length, m.width, rt.profile_frame.z_range.x,
              rt.profile_frame.z_range.y, rt.profile_frame.grid_step.x,
              rt.profile_frame.grid_step.y);
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  ImGui::Image(reinterpret_cast<ImTextureID>(rt.profile_texture),
               ImVec2(float(rt.profile_size.x), float(rt.profile_size.y)));
  if (ImGui::IsItemHovered()) {
    const ImVec2 mouse = ImGui::GetMousePos();
    const glm::dvec2 at =
        rt.profile_frame.from_pixel({mouse.x - origin.x, mouse.y - origin.y}, rt.profile_size);
    ImGui::SetTooltip("distance %.3f, height %.3f", at.x, at.y);
    // Two clicks in the profile measure between them (distance along, height, slope).
    if (ImGui::IsMouseClicked(0)) {
      if (rt.profile_clicks.size() == 2) rt.profile_clicks.clear();
      rt.profile_clicks.push_back(at);
    }
  }
  ImDrawList* draw = ImGui::GetWindowDrawList();
  for (const glm::dvec2& c : rt.profile_clicks) {
    const glm::dvec2 p = rt.profile_frame.to_pixel(c.x, c.y, rt.profile_size);
    draw->AddCircleFilled(ImVec2(origin.x + float(p.x), origin.y + float(p.y)), 4,
                          IM_COL32(255, 220, 50, 255));
  }
  if (rt.profile_clicks.size() == 2) {
    const glm::dvec2 a = rt.profile_clicks[0], b = rt.profile_clicks[1];
    const glm::dvec2 pa = rt.profile_frame.to_pixel(a.x, a.y, rt.profile_size);
    const glm::dvec2 pb = rt.profile_frame.to_pixel(b.x, b.y, rt.profile_size);
    draw->AddLine(ImVec2(origin.x + float(pa.x), origin.y + float(pa.y)),
                  ImVec2(origin.x + float(pb.x), origin.y + float(pb.y)),
                  IM_COL32(255, 220, 50, 255), 2);
    ImGui::Text("in the profile: along %.3f, height %+.3f, slope distance %.3f", b.x - a.x,
                b.y - a.y, glm::length(b - a));
  }
  if (cloud && !cloud->files.empty()) {
    ImGui::InputText("image", rt.profile_png.data(), rt.profile_png.size());
    ImGui::InputText("csv", rt.profile_csv.data(), rt.profile_csv.size());
    ImGui::InputText("las", rt.profile_las.data(), rt.profile_las.size());
    if (ImGui::Button("export profile (R)")) start_profile_export(main, item);
  }
  ImGui::End();
}

void filter_panel(Registry& main, ToolsRuntime& rt) {
  auto& settings = main.resource<pc::PointDrawSettings>();
  pc::PointFilter& f = settings.render.filter;
  if (!ImGui::TreeNode("filters and clipping")) return;
  if (settings.compute && f.needs_extras()) {
    ImGui::TextColored(ImVec4(1, 0.6f, 0.3f, 1),
                       "GPS-time and point-source filters: billboards only");
    if (ImGui::Button("draw with billboards")) settings.compute = false;
  }
  if (ImGui::TreeNode("classes")) {
    if (ImGui::SmallButton("all")) f.classes.fill(~0u);
    ImGui::SameLine();
    if (ImGui::SmallButton("none")) f.classes.fill(0u);
    for (uint32_t c = 0; c <= 22; ++c) {
      bool kept = f.class_kept(c);
      if (ImGui::Checkbox(fmt::format("{:2} {}", c, pc::classification_name(c)).c_str(), &kept))
        f.set_class(c, kept);
    }
    ImGui::TreePop();
  }
  static constexpr std::pair<uint8_t, const char*> kReturns[] = {
      {pc::kReturnFirst, "first"},
      {pc::kReturnLast, "last"},
      {pc::kReturnSingle, "single"},
      {pc::kReturnIntermediate, "intermediate"}};
  ImGui::Text("returns (none ticked: all):");
  for (const auto& [bit, name] : kReturns) {
    bool on = f.returns & bit;
    ImGui::SameLine();
    if (ImGui::Checkbox(name, &on)) f.returns = uint8_t(on ? f.returns | bit : f.returns & ~bit);
  }
  bool intensity = f.intensity.has_value();
  if (ImGui::Checkbox("intensity", &intensity))
    f.intensity = intensity ? std::optional<glm::dvec2>(glm::dvec2(0, 65535)) : std::nullopt;
  if (f.intensity) {
    ImGui::SameLine();
    float r[2] = {float(f.intensity->x), float(f.intensity->y)};
    if (ImGui::DragFloat2("##intensity", r, 16.0f, 0.0f, 65535.0f, "%.0f"))
      f.intensity = glm::dvec2(std::min(r[0], r[1]), std::max(r[0], r[1]));
  }
  bool gps = f.gps_time.has_value();
  if (ImGui::Checkbox("GPS time", &gps))
    f.gps_time = gps ? std::optional<glm::dvec2>(rt.gps_extent) : std::nullopt;
  if (f.gps_time) {
    double r[2] = {f.gps_time->x, f.gps_time->y};
    ImGui::InputDouble("from", &r[0], 1.0, 60.0, "%.6f");
    ImGui::InputDouble("to", &r[1], 1.0, 60.0, "%.6f");
    f.gps_time = glm::dvec2(std::min(r[0], r[1]), std::max(r[0], r[1]));
  }
  bool source = f.point_source.has_value();
  if (ImGui::Checkbox("point source", &source))
    f.point_source = source ? std::optional<glm::dvec2>(glm::dvec2(0, 65535)) : std::nullopt;
  if (f.point_source) {
    ImGui::SameLine();
    int r[2] = {int(f.point_source->x), int(f.point_source->y)};
    if (ImGui::DragInt2("##source", r, 1.0f, 0, 65535))
      f.point_source = glm::dvec2(std::min(r[0], r[1]), std::max(r[0], r[1]));
  }
  int mode = int(settings.render.clip.mode);
  const char* modes[] = {"inside", "outside", "highlight"};
  if (ImGui::Combo("clip mode", &mode, modes, 3)) settings.render.clip.mode = pc::ClipMode(mode);
  ImGui::Text("clip: %zu boxes, %zu polygons, %zu planes (B: box tool, G: polygon tool)",
              settings.render.clip.boxes.size(), settings.render.clip.polygons.size(),
              settings.render.clip.planes.size());
  ImGui::TreePop();
}

void inspect_window(Registry& main, const ToolsState& s) {
  if (!s.inspected) return;
  const glm::dvec2 viewport = viewport_of(main);
  ImGui::SetNextWindowPos(ImVec2(float(viewport.x) - 370, float(viewport.y) - 330),
                          ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowSize(ImVec2(360, 320), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.85f);
  ImGui::Begin("inspected point");
  const PointRecord& r = *s.inspected;
  ImGui::Text("%s, record %llu%s", r.source.c_str(), static_cast<unsigned long long>(r.index),
              r.from_source ? "" : " (as drawn)");
  ImGui::Text("x %.17g", r.position.x);
  ImGui::Text("y %.17g", r.position.y);
  ImGui::Text("z %.17g", r.position.z);
  if (r.lon_lat) ImGui::Text("lon %.9f, lat %.9f", r.lon_lat->x, r.lon_lat->y);
  for (const auto& [key, value] : r.fields) {
    if (const double* d = std::get_if<double>(&value))
      ImGui::Text("%s: %.17g", key.c_str(), *d);
    else if (const std::string* t = std::get_if<std::string>(&value))
      ImGui::Text("%s: %s", key.c_str(), t->c_str());
    else if (const auto* v = std::get_if<std::vector<double>>(&value)) {
      std::string text;
      for (double x : *v) text += fmt::format("{} ", x);
      ImGui::Text("%s: %s", key.c_str(), text.c_str());
    }
  }
  ImGui::End();
}

// Appended to the viewer's panel ("stipple"): a status line while a tool is on, and one
// collapsing section with the tools, the measurements, filters, clipping and export.
void tools_panel(Registry& main) {
  const auto* ui = main.try_resource<UiSettings>();
  if (!ui || !ui->visible) return;
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  ImGui::Begin("stipple");
  if (s.tool != Tool::None) {
    ImGui::Text("tool: %s", tool_name(s.tool));
    if (s.active >= 0) {
      ImGui::SameLine();
      ImGui::TextDisabled("(Enter/right click: finish, Backspace: undo, Esc: cancel)");
    }
  }
  if (!s.message.empty()) ImGui::TextColored(ImVec4(1, 0.7f, 0.3f, 1), "%s", s.message.c_str());
  if (rt.tool_shown != s.tool) {
    // A tool chosen by its key opens the section once.
    if (s.tool != Tool::None) ImGui::SetNextItemOpen(true);
    rt.tool_shown = s.tool;
  }
  if (!ImGui::CollapsingHeader("measure, filter, clip, export")) {
    ImGui::End();
    inspect_window(main, s);
    profile_window(main, s, rt);
    return;
  }
  static constexpr const char* kKeys[kToolCount] = {"0", "1", "2", "3", "4", "5",
                                                    "6", "7", "8", "9", "B", "G"};
  for (int t = 0; t < kToolCount; ++t) {
    if (t % 3) ImGui::SameLine();
    if (ImGui::RadioButton(fmt::format("{} ({})", tool_name(Tool(t)), kKeys[t]).c_str(),
                           s.tool == Tool(t))) {
      cancel_active(s);
      s.tool = Tool(t);
    }
  }
  if (s.tool == Tool::Profile) {
    float width = float(s.profile_width);
    if (ImGui::DragFloat("corridor width", &width, 0.1f, 0.0f, 1e6f, "%.2f (0: 1% of the scene)"))
      s.profile_width = std::max(0.0f, width);
  }
  if (s.tool == Tool::Volume)
    ImGui::TextDisabled("volume: click the reference height, then a box: two corners, a width");
  else if (s.tool == Tool::ClipBox)
    ImGui::TextDisabled("clip box: two corners, then a width");
  ImGui::Separator();
  const std::string unit = s.frame.unit;
  int remove = -1;
  for (size_t i = 0; i < s.items.size(); ++i) {
    Measurement& m = s.items[i];
    ImGui::PushID(int(i));
    if (ImGui::Selectable(fmt::format("{} {}", tool_name(m.tool),
                                      m.tool == Tool::Annotation ? "" : value_text(m, unit))
                              .c_str(),
                          s.selected == int(i)))
      s.selected = int(i);
    if (s.selected == int(i)) {
      char text[256];
      std::snprintf(text, sizeof(text), "%s", m.label.c_str());
      if (ImGui::InputText("label", text, sizeof(text))) m.label = text;
      if (m.tool == Tool::Distance && m.complete) {
        for (size_t k = 0; k < m.values.segments_3d.size(); ++k)
          ImGui::Text("  segment %zu: %.3f (horizontal %.3f)", k + 1, m.values.segments_3d[k],
                      m.values.segments_horizontal[k]);
        ImGui::Text("  total %.3f (horizontal %.3f), height %+.3f", m.values.length_3d,
                    m.values.length_horizontal, m.values.height);
      }
      if (m.tool == Tool::Height && m.complete)
        ImGui::Text("  horizontal %.3f, slope %.3f", m.values.length_horizontal,
                    m.values.length_3d);
      if ((m.tool == Tool::Area || m.tool == Tool::ClipPolygon) && m.complete)
        ImGui::Text("  perimeter %.3f", m.values.perimeter);
      if (m.tool == Tool::Circle && m.complete)
        ImGui::Text("  centre %.3f, %.3f, %.3f", m.values.center.x, m.values.center.y,
                    m.values.center.z);
      if (m.tool == Tool::Volume && m.complete) {
        double plane = m.points[0].z;
        if (ImGui::InputDouble("plane z", &plane, 0.1, 1.0, "%.3f")) {
          m.points[0].z = plane;
          remeasure(main, m);
          ++s.version;
        }
        ImGui::Text("  footprint %.3f, cells covered %.0f%%", m.values.area_horizontal,
                    m.values.covered_fraction * 100);
      }
      if (m.tool == Tool::Profile && m.complete) {
        float width = float(m.width);
        if (ImGui::DragFloat("width", &width, 0.1f, 0.01f, 1e6f, "%.2f")) {
          m.width = std::max(0.01f, width);
          ++s.version;
        }
      }
      if (ImGui::SmallButton("delete")) remove = int(i);
    }
    ImGui::PopID();
  }
  if (remove >= 0) {
    s.items.erase(s.items.begin() + remove);
    s.selected = -1;
    if (s.active == remove) s.active = -1;
    if (s.active > remove) --s.active;
    ++s.version;
  }
  ImGui::Separator();
  ImGui::InputText("file", rt.save_path.data(), rt.save_path.size());
  if (ImGui::Button("save GeoJSON")) {
    try {
      save_measurements(s, rt.save_path.data());
      s.message = fmt::format("saved {}", rt.save_path.data());
    } catch (const Error& e) {
      s.message = e.what();
    }
  }
  ImGui::SameLine();
  if (ImGui::Button("load GeoJSON")) {
    try {
      load_measurements(s, rt.save_path.data());
      for (Measurement& m : s.items) remeasure(main, m);
    } catch (const Error& e) {
      s.message = e.what();
    }
  }
  ImGui::SameLine();
  if (ImGui::Button("clear")) {
    s.items.clear();
    s.active = s.selected = -1;
    s.inspected.reset();
    ++s.version;
  }
  filter_panel(main, rt);
  if (ImGui::TreeNode("export")) {
    export_panel(main, rt);
    ImGui::TreePop();
  }
  ImGui::End();
  inspect_window(main, s);
  profile_window(main, s, rt);
}

}  // namespace

void ToolsPlugin::build(Engine& engine) {
  Registry& main = engine.main();
  main.insert_resource(ToolsState{});
  ToolsRuntime rt;
  rt.measurements_out = measurements_out;
  set_text(rt.clip_path, "clip.laz");
  set_text(rt.profile_png, "profile.png");
  set_text(rt.profile_csv, "profile.csv");
  set_text(rt.profile_las, "");
  set_text(rt.save_path, measurements_out.empty() ? "measurements.geojson" : measurements_out);
  main.insert_resource(std::move(rt));
  engine.add_system(MainStage::PreUpdate, tools_input, "tools_input");
  engine.add_system(MainStage::Update, tools_panel, "tools_panel");
  engine.add_system(MainStage::Update, tools_overlay, "tools_overlay");
  engine.add_system(MainStage::PostUpdate, tools_sync, "tools_sync");
}

void ToolsPlugin::finish(Engine& engine) {
  Registry& main = engine.main();
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  // Where points come from and in which CRS.
  main.view<pc::PointCloudData>().each([&](const pc::PointCloudData& d) {
    if (rt.records.cloud || !d.cloud) return;
    rt.records.cloud = d.cloud.get();
    rt.records.scene = d.scene;
    if (d.scene) {
      rt.records.crs.epsg = d.scene->epsg;
      rt.records.crs.linear_unit = "metre";
    } else if (!d.cloud->files.empty()) {
      rt.records.crs = io::read_las_header(d.cloud->files.front()).crs;
    }
    s.frame.enu_origin = d.cloud->enu_origin;
    // GPS time's extent, for the filter panel's starting range.
    glm::dvec2 gps(std::numeric_limits<double>::infinity(),
                   -std::numeric_limits<double>::infinity());
    for (const pc::PointChunk& c : d.cloud->chunks)
      for (const pc::PointChunk::Extra& e : c.extras)
        gps = {std::min(gps.x, c.gps_origin + e.gps), std::max(gps.y, c.gps_origin + e.gps)};
    if (gps.x <= gps.y) rt.gps_extent = gps;
  });
  s.frame.epsg = rt.records.crs.epsg;
  s.frame.unit = rt.records.crs.geographic || s.frame.enu_origin ? "metre"
                 : rt.records.crs.linear_unit.empty()            ? "metre"
                                                                 : rt.records.crs.linear_unit;
  if (auto* settings = main.try_resource<pc::PointDrawSettings>())
    rt.base_clip = settings->render.clip;
  if (!measurements_in.empty()) {
    load_measurements(s, measurements_in);
    for (Measurement& m : s.items) remeasure(main, m);
  }
}

}  // namespace stipple::viewer
