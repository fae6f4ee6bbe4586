#include "stipple/tools/tools.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <tuple>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/world.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/scene.hpp"

namespace stipple::tools {

namespace {

constexpr double kPickPixels = 3.0;   // cone radius of a tool's click
constexpr double kGrabPixels = 8.0;   // how near a vertex must be to drag it
constexpr double kClickPixels = 4.0;  // a press and release this close are a click

// Main-world resource: what the systems keep between frames.
struct ToolsRuntime {
  std::string measurements_out;
  bool written = false;
  bool background_exports = true;
  RecordSource records;
  pc::ClipRegion base_clip;  // the command line's shapes
  uint64_t clip_version = ~uint64_t(0);
  std::shared_ptr<std::atomic<uint64_t>> progress = std::make_shared<std::atomic<uint64_t>>(0);
  uint64_t progress_total = 0;
  // Exports in order: each waits for the one before, so exports asked for in a row all run.
  std::vector<std::shared_future<std::string>> jobs;
  // Pointer input.
  glm::dvec2 press{0.0}, right_press{0.0};
  bool left_down = false, right_down = false;
  int drag_item = -1, drag_vertex = -1;  // the vertex under the last left press
  bool dragging = false;                 // ... and the pointer has moved it
};

const Camera* first_camera(Registry& main) {
  const Camera* camera = nullptr;
  main.view<Camera>().each([&](const Camera& c) {
    if (!camera) camera = &c;
  });
  return camera;
}

// View pixels of a local-frame point; nullopt behind the camera.
std::optional<glm::dvec2> project(const Camera& camera, const glm::dvec2& viewport,
                                  const glm::dvec3& local) {
  const glm::dvec3 rel = z_up_to_y_up(local) - camera.position;
  const glm::dvec4 clip = camera.projection(viewport.x / std::max(viewport.y, 1.0)) *
                          camera.view_rotation() * glm::dvec4(rel, 1.0);
  if (clip.w <= 1e-9) return std::nullopt;
  return glm::dvec2((clip.x / clip.w + 1) * 0.5 * viewport.x,
                    (1 - clip.y / clip.w) * 0.5 * viewport.y);
}

std::optional<pc::PickHit> pick_at(Registry& main, const ViewPoint& at) {
  const Camera* camera = first_camera(main);
  if (!camera) return std::nullopt;
  const double tan_radius =
      kPickPixels * 2.0 * std::tan(camera->fov_y * 0.5) / std::max(at.view_size.y, 1.0);
  return pc::pick_scene(
      main, {camera->position, cursor_ray(*camera, at.cursor, at.view_size), tan_radius});
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
std::optional<glm::dvec3> point_under(Registry& main, const ViewPoint& at,
                                      std::optional<PointRecord>* record = nullptr) {
  const auto hit = pick_at(main, at);
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

bool valid_item(const ToolsState& s, int item) {
  return item >= 0 && item < int(s.items.size());
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
  auto* settings = main.try_resource<pc::PointDrawSettings>();
  if (!settings) return;
  if (rt.clip_version != s.version) {
    const pc::ClipMode mode = settings->render.clip.mode;
    settings->render.clip = clip_region(main, s, rt.base_clip);
    settings->render.clip.mode = mode;
    rt.clip_version = s.version;
  }
  main.insert_resource(pc::PickFilter{settings->render.filter, settings->render.clip});
  // Finished exports report; those in flight finish before the app goes.
  const bool exiting = main.resource<AppExit>().requested;
  for (const std::string& result : take_export_results(main, exiting)) {
    std::printf("%s\n", result.c_str());
    std::fflush(stdout);
  }
  if (!rt.measurements_out.empty() && !rt.written && exiting) {
    rt.written = true;
    try {
      save_measurements(s, rt.measurements_out);
    } catch (const Error& e) {
      STIPPLE_ERROR("{}", e.what());
    }
  }
}

void run_in_background(ToolsRuntime& rt, ToolsState& s, uint64_t total,
                       std::function<std::string()> work) {
  std::shared_future<std::string> before;
  if (!rt.jobs.empty()) before = rt.jobs.back();
  rt.progress_total = total;
  s.message = "exporting ...";
  auto progress = rt.progress;
  if (!rt.background_exports) {
    std::promise<std::string> done;
    progress->store(0);
    try {
      done.set_value(work());
    } catch (const Error& e) {
      done.set_value(std::string("export failed: ") + e.what());
    }
    rt.jobs.push_back(done.get_future().share());
    return;
  }
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

}  // namespace

// ---- actions ------------------------------------------------------------------------------

void set_tool(Registry& main, Tool tool) {
  auto& s = main.resource<ToolsState>();
  if (s.tool == tool) return;
  cancel(main);
  s.tool = tool;
}

bool click(Registry& main, const ViewPoint& at) {
  auto& s = main.resource<ToolsState>();
  if (s.tool == Tool::None) {
    s.message = "no tool chosen";
    return false;
  }
  std::optional<PointRecord> record;
  const auto point = point_under(main, at, &record);
  if (!point) {
    s.message = "no point under the cursor";
    return false;
  }
  if (s.tool == Tool::Inspect) {
    s.inspected = std::move(record);
    if (!s.inspected) {
      PointRecord r;
      r.local = r.position = *point;
      s.inspected = r;
    }
    s.message.clear();
    ++s.version;
    return true;
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
  if (tool_points(m.tool) > 0 && int(m.points.size()) >= tool_points(m.tool)) finish(main);
  return true;
}

void finish(Registry& main) {
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

void undo_point(Registry& main) {
  auto& s = main.resource<ToolsState>();
  if (s.active < 0) return;
  auto& points = s.items[size_t(s.active)].points;
  if (!points.empty()) points.pop_back();
  if (points.empty()) {
    cancel(main);
    return;
  }
  compute_values(s.items[size_t(s.active)]);
  ++s.version;
}

void cancel(Registry& main) {
  auto& s = main.resource<ToolsState>();
  if (s.active < 0) return;
  s.items.erase(s.items.begin() + s.active);
  s.active = -1;
  s.selected = -1;
  ++s.version;
}

void remove(Registry& main, int item) {
  auto& s = main.resource<ToolsState>();
  if (item < 0) item = s.selected;
  if (!valid_item(s, item)) return;
  s.items.erase(s.items.begin() + item);
  s.selected = -1;
  if (s.active == item) s.active = -1;
  if (s.active > item) --s.active;
  ++s.version;
}

void clear(Registry& main) {
  auto& s = main.resource<ToolsState>();
  s.items.clear();
  s.active = s.selected = -1;
  s.inspected.reset();
  ++s.version;
}

void select(Registry& main, int item) {
  auto& s = main.resource<ToolsState>();
  s.selected = valid_item(s, item) ? item : -1;
}

void set_label(Registry& main, int item, std::string label) {
  auto& s = main.resource<ToolsState>();
  if (!valid_item(s, item)) return;
  s.items[size_t(item)].label = std::move(label);
  ++s.version;
}

void set_width(Registry& main, int item, double width) {
  auto& s = main.resource<ToolsState>();
  if (!valid_item(s, item) || !(width > 0) || !std::isfinite(width)) return;
  s.items[size_t(item)].width = width;
  ++s.version;
}

void set_plane_z(Registry& main, int item, double z) {
  auto& s = main.resource<ToolsState>();
  if (!valid_item(s, item) || !std::isfinite(z)) return;
  Measurement& m = s.items[size_t(item)];
  if (m.tool != Tool::Volume || m.points.empty()) return;
  m.points[0].z = z;
  if (m.complete) remeasure(main, m);
  ++s.version;
}

std::pair<int, int> vertex_near(Registry& main, const ViewPoint& at) {
  const Camera* camera = first_camera(main);
  const auto& s = main.resource<ToolsState>();
  std::pair<int, int> best{-1, -1};
  if (!camera) return best;
  double best_d = kGrabPixels;
  for (size_t i = 0; i < s.items.size(); ++i) {
    if (!s.items[i].complete) continue;
    for (size_t v = 0; v < s.items[i].points.size(); ++v) {
      const auto px = project(*camera, at.view_size, s.items[i].points[v]);
      if (!px) continue;
      const double d = glm::distance(*px, at.cursor);
      if (d <= best_d) best_d = d, best = {int(i), int(v)};
    }
  }
  return best;
}

void move_vertex(Registry& main, int item, int vertex, const ViewPoint& at) {
  auto& s = main.resource<ToolsState>();
  if (!valid_item(s, item)) return;
  Measurement& m = s.items[size_t(item)];
  if (vertex < 0 || vertex >= int(m.points.size())) return;
  if (const auto p = point_under(main, at)) {
    m.points[size_t(vertex)] = *p;
    compute_values(m);
    ++s.version;
  }
}

void put_vertex(Registry& main, int item) {
  auto& s = main.resource<ToolsState>();
  if (!valid_item(s, item)) return;
  remeasure(main, s.items[size_t(item)]);  // volumes are summed once the vertex is put down
  s.selected = item;
  ++s.version;
}

// ---- pointer input -----------------------------------------------------------------------

void pointer_down(Registry& main, const ViewPoint& at, Button button) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  if (button == Button::Right) {
    rt.right_press = at.cursor;
    rt.right_down = true;
    return;
  }
  rt.press = at.cursor;
  rt.left_down = true;
  rt.dragging = false;
  rt.drag_item = rt.drag_vertex = -1;
  if (s.active < 0) std::tie(rt.drag_item, rt.drag_vertex) = vertex_near(main, at);
}

void pointer_move(Registry& main, const ViewPoint& at) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  if (!rt.left_down || !valid_item(s, rt.drag_item)) return;
  if (!rt.dragging && glm::distance(at.cursor, rt.press) <= kClickPixels) return;
  rt.dragging = true;
  move_vertex(main, rt.drag_item, rt.drag_vertex, at);
}

void pointer_up(Registry& main, const ViewPoint& at, Button button) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  if (button == Button::Right) {
    if (rt.right_down && glm::distance(at.cursor, rt.right_press) <= kClickPixels) finish(main);
    rt.right_down = false;
    return;
  }
  const bool clicked = rt.left_down && glm::distance(at.cursor, rt.press) <= kClickPixels;
  if (rt.dragging && valid_item(s, rt.drag_item))
    put_vertex(main, rt.drag_item);
  else if (clicked && s.tool != Tool::None)
    click(main, at);
  pointer_cancel(main);
}

void pointer_cancel(Registry& main) {
  auto& rt = main.resource<ToolsRuntime>();
  rt.left_down = rt.right_down = rt.dragging = false;
  rt.drag_item = rt.drag_vertex = -1;
}

bool pointer_holds(Registry& main) {
  const auto& s = main.resource<ToolsState>();
  const auto& rt = main.resource<ToolsRuntime>();
  return rt.left_down && valid_item(s, rt.drag_item);
}

// ---- measurements as GeoJSON --------------------------------------------------------------

namespace {
std::vector<io::GeoFeature> features_of(const ToolsState& state) {
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
  return features;
}

void add_document(Registry& main, const io::GeoDocument& doc, const std::string& name) {
  auto& s = main.resource<ToolsState>();
  std::vector<Measurement> loaded;
  for (size_t i = 0; i < doc.features.size(); ++i) {
    if (doc.features[i].text("tool") == "inspect") continue;  // a record, not a measurement
    loaded.push_back(from_feature(doc.features[i], s.frame, i, name));
  }
  for (Measurement& m : loaded) {
    if (main.try_resource<pc::PointDrawSettings>()) remeasure(main, m);
    s.items.push_back(std::move(m));
  }
  ++s.version;
}
}  // namespace

std::string measurements_geojson(const ToolsState& state) {
  return io::geojson_text(features_of(state), state.frame.epsg);
}

void save_measurements(const ToolsState& state, const std::string& path) {
  io::write_geojson(path, features_of(state), state.frame.epsg);
}

void add_measurements(Registry& main, std::string_view geojson, const std::string& name) {
  add_document(main, io::parse_geojson(geojson, name), name);
}

void load_measurements(Registry& main, const std::string& path) {
  add_document(main, io::read_geojson(path), path);
}

// ---- drawing over the view ----------------------------------------------------------------

glm::vec3 tool_color(Tool tool) {
  switch (tool) {
    case Tool::Distance:
      return {1.0f, 0.85f, 0.2f};
    case Tool::Height:
      return {0.3f, 0.9f, 1.0f};
    case Tool::Area:
      return {0.4f, 1.0f, 0.4f};
    case Tool::Angle:
    case Tool::Circle:
      return {1.0f, 0.5f, 0.9f};
    case Tool::Volume:
      return {1.0f, 0.55f, 0.2f};
    case Tool::Profile:
      return {0.6f, 0.7f, 1.0f};
    case Tool::ClipBox:
    case Tool::ClipPolygon:
      return {1.0f, 0.3f, 0.3f};
    default:
      return {1.0f, 1.0f, 1.0f};
  }
}

Overlay overlay(Registry& main, const glm::dvec2& view_size) {
  Overlay out;
  const Camera* camera = first_camera(main);
  if (!camera) return out;
  const auto& s = main.resource<ToolsState>();
  auto px = [&](const glm::dvec3& p) { return project(*camera, view_size, p); };
  auto line = [&](const glm::dvec3& a, const glm::dvec3& b, Tool tool, float width,
                  bool faint = false) {
    const auto pa = px(a), pb = px(b);
    if (pa && pb) out.lines.push_back({*pa, *pb, tool, width, faint});
  };
  const std::string unit = s.frame.unit;
  for (size_t i = 0; i < s.items.size(); ++i) {
    const Measurement& m = s.items[i];
    const Tool tool = m.tool;
    const float width = int(i) == s.selected ? 3.0f : 2.0f;
    const auto& p = m.points;
    if (tool == Tool::ClipBox && p.size() == 3) {
      const pc::ClipBox box = box_from_clicks(p[0], p[1], p[2], std::min({p[0].z, p[1].z, p[2].z}),
                                              std::max({p[0].z, p[1].z, p[2].z}) + 1);
      const auto c = box.corners();
      for (int k = 0; k < 4; ++k) {
        line(c[size_t(k)], c[size_t((k + 1) % 4)], tool, width);
        line(c[size_t(k + 4)], c[size_t((k + 1) % 4 + 4)], tool, width);
        line(c[size_t(k)], c[size_t(k + 4)], tool, width);
      }
    } else if (tool == Tool::Volume && p.size() == 4) {
      const pc::ClipBox box = box_from_clicks(p[1], p[2], p[3], p[0].z, p[0].z);
      const auto c = box.corners();
      for (int k = 0; k < 4; ++k) line(c[size_t(k)], c[size_t((k + 1) % 4)], tool, width);
    } else {
      const bool closed = (tool == Tool::Area || tool == Tool::ClipPolygon) && p.size() >= 3;
      for (size_t k = 0; k + 1 < p.size(); ++k) line(p[k], p[k + 1], tool, width);
      if (closed) line(p.back(), p.front(), tool, width);
      if (tool == Tool::Circle && m.values.radius > 0) {
        // The circle in its plane, as 64 segments.
        const glm::dvec3 c = m.values.center;
        const glm::dvec3 n = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
        const glm::dvec3 u = glm::normalize(p[0] - c), w = glm::cross(n, u);
        for (int k = 0; k < 64; ++k) {
          const double a0 = k * 2 * M_PI / 64, a1 = (k + 1) * 2 * M_PI / 64;
          line(c + m.values.radius * (std::cos(a0) * u + std::sin(a0) * w),
               c + m.values.radius * (std::cos(a1) * u + std::sin(a1) * w), tool, 1.5f);
        }
      }
      if (tool == Tool::Height && p.size() == 2) {
        // The vertical and horizontal legs.
        const glm::dvec3 corner(p[1].x, p[1].y, p[0].z);
        line(p[0], corner, tool, 1.0f, true);
        line(corner, p[1], tool, 1.0f, true);
      }
    }
    for (size_t v = 0; v < p.size(); ++v)
      if (const auto at = px(p[v])) out.dots.push_back({*at, tool, int(i), int(v)});
    if (p.empty()) continue;
    std::string text = tool == Tool::Annotation ? m.label : value_text(m, unit);
    if (!m.label.empty() && tool != Tool::Annotation) text = m.label + ": " + text;
    if (tool == Tool::Distance && m.complete && p.size() > 2)
      for (size_t k = 0; k + 1 < p.size(); ++k)
        if (const auto mid = px((p[k] + p[k + 1]) * 0.5))
          out.labels.push_back({*mid, fmt::format("{:.2f}", m.values.segments_3d[k]), tool});
    glm::dvec3 anchor = p.back();
    if (tool == Tool::Circle && m.values.radius > 0) anchor = m.values.center;
    if (const auto at = px(anchor)) out.labels.push_back({*at, text, tool});
  }
  if (s.inspected) out.inspected = px(s.inspected->local);
  return out;
}

// ---- the profile window -------------------------------------------------------------------

int current_profile(const ToolsState& s) {
  if (valid_item(s, s.selected) && s.items[size_t(s.selected)].tool == Tool::Profile &&
      s.items[size_t(s.selected)].complete)
    return s.selected;
  int item = -1;
  for (size_t i = 0; i < s.items.size(); ++i)
    if (s.items[i].tool == Tool::Profile && s.items[i].complete) item = int(i);
  return item;
}

ProfileView profile_view(Registry& main, int item, const glm::uvec2& size) {
  const auto& s = main.resource<ToolsState>();
  ProfileView view;
  if (!valid_item(s, item) || s.items[size_t(item)].tool != Tool::Profile ||
      s.items[size_t(item)].points.size() < 2)
    return view;
  const Measurement& m = s.items[size_t(item)];
  const pc::PointCloud* cloud = loaded_cloud(main);
  const auto& settings = main.resource<pc::PointDrawSettings>();
  pc::ProfileLine line;
  for (const glm::dvec3& p : m.points) line.vertices.emplace_back(p.x, p.y);
  line.width = m.width;
  const double z0 = m.points[0].z;
  std::vector<pc::ProfileSample> samples;
  if (cloud)
    samples = pc::profile_samples(*cloud, line, settings.render.filter, settings.render.clip, z0);
  glm::dvec2 z(std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity());
  for (const auto& p : samples) z = {std::min(z.x, z0 + p.height), std::max(z.y, z0 + p.height)};
  if (samples.empty()) z = {z0 - 1, z0 + 1};
  view.item = item;
  view.width = m.width;
  view.points = samples.size();
  view.version = s.version;
  view.frame = pc::make_profile_frame(line.length(), z, z0, size);
  pc::ProfileImageOptions options;
  options.width = size.x;
  options.height = size.y;
  const pc::CloudAttributes attributes = cloud ? cloud->attributes : pc::CloudAttributes{};
  options.color = pc::resolve_color_mode(attributes, settings.render.color);
  options.background = settings.render.background;
  view.image = pc::draw_profile(samples, view.frame, options, attributes);
  return view;
}

// ---- exports ------------------------------------------------------------------------------

bool can_export(Registry& main) {
  const pc::PointCloud* cloud = loaded_cloud(main);
  return cloud && !cloud->files.empty();
}

void start_clip_export(Registry& main, const std::string& path) {
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
  job.output = path;
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

void start_profile_export(Registry& main, int item, const ProfileFiles& files) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  const pc::PointCloud* cloud = loaded_cloud(main);
  if (!cloud || cloud->files.empty()) {
    s.message = "export needs LAS/LAZ/COPC inputs";
    return;
  }
  if (!valid_item(s, item) || s.items[size_t(item)].tool != Tool::Profile ||
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
  job.png = files.png;
  job.csv = files.csv;
  job.las = files.las;
  job.image.color = settings.render.color;
  job.progress = false;
  job.points_done = rt.progress.get();
  auto progress = rt.progress;
  run_in_background(rt, s, input_points(*cloud), [job, progress] {
    const pc::ProfileResult r = pc::run_profile(job);
    return fmt::format("profile: {} points in the corridor", r.points_in_corridor);
  });
}

ExportProgress export_progress(Registry& main) {
  const auto& rt = main.resource<ToolsRuntime>();
  return {!rt.jobs.empty(), rt.progress->load(), rt.progress_total};
}

std::vector<std::string> take_export_results(Registry& main, bool wait) {
  auto& s = main.resource<ToolsState>();
  auto& rt = main.resource<ToolsRuntime>();
  std::vector<std::string> results;
  while (!rt.jobs.empty() &&
         (wait || rt.jobs.front().wait_for(std::chrono::seconds(0)) == std::future_status::ready)) {
    results.push_back(rt.jobs.front().get());
    s.message = results.back();
    rt.jobs.erase(rt.jobs.begin());
  }
  return results;
}

// ---- the plugin ---------------------------------------------------------------------------

void ToolsCorePlugin::build(Engine& engine) {
  Registry& main = engine.main();
  main.insert_resource(ToolsState{});
  ToolsRuntime rt;
  rt.measurements_out = measurements_out;
  rt.background_exports = background_exports;
  main.insert_resource(std::move(rt));
  engine.add_system(MainStage::PostUpdate, tools_sync, "tools_sync");
}

void ToolsCorePlugin::finish(Engine& engine) {
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
    // GPS time's extent, for a filter's starting range.
    glm::dvec2 gps(std::numeric_limits<double>::infinity(),
                   -std::numeric_limits<double>::infinity());
    for (const pc::PointChunk& c : d.cloud->chunks)
      for (const pc::PointChunk::Extra& e : c.extras)
        gps = {std::min(gps.x, c.gps_origin + e.gps), std::max(gps.y, c.gps_origin + e.gps)};
    if (gps.x <= gps.y) s.gps_extent = gps;
  });
  s.frame.epsg = rt.records.crs.epsg;
  s.frame.unit = rt.records.crs.geographic || s.frame.enu_origin ? "metre"
                 : rt.records.crs.linear_unit.empty()            ? "metre"
                                                                 : rt.records.crs.linear_unit;
  if (auto* settings = main.try_resource<pc::PointDrawSettings>())
    rt.base_clip = settings->render.clip;
  if (!measurements_in.empty()) load_measurements(main, measurements_in);
}

}  // namespace stipple::tools
