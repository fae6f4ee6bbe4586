#include "stipple/viewer/tools_plugin.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include <fmt/format.h>
#include <imgui.h>
#include <glm/geometric.hpp>

#include "stipple/core/error.hpp"
#include "stipple/engine/engine.hpp"
#include "stipple/engine/world.hpp"
#include "stipple/platform/input.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/scene.hpp"
#include "stipple/viewer/camera_controller.hpp"
#include "stipple/viewer/ui_plugin.hpp"
#include "stipple/viewer/window_plugins.hpp"

namespace stipple::viewer {

namespace {

using platform::Key;
using platform::MouseButton;
using tools::Measurement;
using tools::Tool;
using tools::ToolsState;

// Main-world resource: what the window's layer keeps between frames.
struct ToolsUi {
  Tool tool_shown = Tool::None;  // the tool the panel last showed
  // Profile window: the image drawn for (item, version), and two clicks measured in it.
  int profile_item = -1;
  uint64_t profile_version = ~uint64_t(0);
  uintptr_t profile_texture = 0;
  pc::ProfileFrame profile_frame;
  glm::uvec2 profile_size{900, 320};
  std::vector<glm::dvec2> profile_clicks;  // along, height
  // Export and save paths.
  std::array<char, 512> clip_path{}, profile_png{}, profile_csv{}, profile_las{}, save_path{};
};

void set_text(std::array<char, 512>& buffer, const std::string& text) {
  std::snprintf(buffer.data(), buffer.size(), "%s", text.c_str());
}

tools::ViewPoint view_point(Registry& main, const glm::dvec2& cursor) {
  return {cursor, glm::dvec2(main.resource<WindowState>().window_size)};
}

void tools_input(Registry& main) {
  auto& s = main.resource<ToolsState>();
  auto& ui = main.resource<ToolsUi>();
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
      if (input.pressed(key)) tools::set_tool(main, tool);
    if (input.pressed(Key::Enter)) tools::finish(main);
    if (input.pressed(Key::X)) tools::start_clip_export(main, ui.clip_path.data());
    if (input.pressed(Key::R))
      tools::start_profile_export(
          main, tools::current_profile(s),
          {ui.profile_png.data(), ui.profile_csv.data(), ui.profile_las.data()});
    if (input.pressed(Key::Backspace)) tools::undo_point(main);
    if (input.pressed(Key::Escape) && s.active >= 0) {
      tools::cancel(main);
      input.key_pressed[size_t(Key::Escape)] = false;  // not a quit: it cancelled the tool
    }
    if (input.pressed(Key::Delete) && s.active < 0) tools::remove(main);
  }
  // Clicks belong to the tools while one is chosen; dragging a vertex holds the mouse.
  capture->double_click = s.tool != Tool::None;
  if (ui_mouse) {
    tools::pointer_cancel(main);
    return;
  }
  const tools::ViewPoint at = view_point(main, input.cursor);
  if (input.pressed(MouseButton::Left)) tools::pointer_down(main, at, tools::Button::Left);
  if (input.pressed(MouseButton::Right)) tools::pointer_down(main, at, tools::Button::Right);
  if (tools::pointer_holds(main)) capture->mouse = true;
  if (glm::length(input.cursor_delta) > 0) tools::pointer_move(main, at);
  if (input.button_released[size_t(MouseButton::Left)])
    tools::pointer_up(main, at, tools::Button::Left);
  if (input.button_released[size_t(MouseButton::Right)])
    tools::pointer_up(main, at, tools::Button::Right);
}

// ---- drawing over the view ----------------------------------------------------------------

ImU32 im_color(Tool tool, float alpha = 1.0f) {
  const glm::vec3 c = tools::tool_color(tool);
  return ImColor(c.r, c.g, c.b, alpha);
}

ImVec2 im(const glm::dvec2& p) {
  return ImVec2(float(p.x), float(p.y));
}

void label(ImDrawList* draw, const glm::dvec2& at, const std::string& text, ImU32 color) {
  const ImVec2 size = ImGui::CalcTextSize(text.c_str());
  const ImVec2 p(float(at.x) + 6, float(at.y) - size.y - 4);
  draw->AddRectFilled(ImVec2(p.x - 3, p.y - 2), ImVec2(p.x + size.x + 3, p.y + size.y + 2),
                      IM_COL32(0, 0, 0, 170), 3.0f);
  draw->AddText(p, color, text.c_str());
}

void tools_overlay(Registry& main) {
  if (!main.try_resource<UiSettings>()) return;  // no ImGui frame
  const tools::Overlay o =
      tools::overlay(main, glm::dvec2(main.resource<WindowState>().window_size));
  ImDrawList* draw = ImGui::GetBackgroundDrawList();
  for (const auto& l : o.lines)
    draw->AddLine(im(l.a), im(l.b), im_color(l.tool, l.faint ? 0.5f : 1.0f), l.width);
  for (const auto& d : o.dots) draw->AddCircleFilled(im(d.at), 4.0f, im_color(d.tool));
  for (const auto& l : o.labels) label(draw, l.at, l.text, im_color(l.tool));
  if (o.inspected) draw->AddCircle(im(*o.inspected), 7.0f, IM_COL32(255, 255, 255, 255), 0, 2.0f);
}

// ---- the panel ---------------------------------------------------------------------------

void export_panel(Registry& main, ToolsUi& ui) {
  if (!tools::can_export(main)) {
    ImGui::TextDisabled("export: needs LAS/LAZ/COPC inputs");
    return;
  }
  ImGui::InputText("clip file", ui.clip_path.data(), ui.clip_path.size());
  if (ImGui::Button("export clip (X): filters and clip region"))
    tools::start_clip_export(main, ui.clip_path.data());
  const tools::ExportProgress progress = tools::export_progress(main);
  if (progress.running)
    ImGui::ProgressBar(progress.total ? float(progress.done) / float(progress.total) : 0.0f);
}

void profile_window(Registry& main, ToolsState& s, ToolsUi& ui) {
  const int item = tools::current_profile(s);
  if (item < 0) return;
  const Measurement& m = s.items[size_t(item)];
  auto& images = main.resource<UiImages>();
  if (ui.profile_item != item || ui.profile_version != s.version) {
    ui.profile_item = item;
    ui.profile_version = s.version;
    ui.profile_clicks.clear();
    tools::ProfileView view = tools::profile_view(main, item, ui.profile_size);
    ui.profile_frame = view.frame;
    auto ui_image = std::make_shared<UiImage>();
    ui_image->width = view.image.width;
    ui_image->height = view.image.height;
    ui_image->rgba = std::move(view.image.rgba);
    if (!ui.profile_texture) ui.profile_texture = images.next_id++;
    images.images[ui.profile_texture] = std::move(ui_image);
  }
  ImGui::SetNextWindowSize(ImVec2(float(ui.profile_size.x) + 20, float(ui.profile_size.y) + 150),
                           ImGuiCond_FirstUseEver);
  ImGui::Begin("profile");
  ImGui::Text("length %.3f, width %.3f; heights %.3f to %.3f; grid %g along, %g up",
              ui.profile_frame.length, m.width, ui.profile_frame.z_range.x,
              ui.profile_frame.z_range.y, ui.profile_frame.grid_step.x,
              ui.profile_frame.grid_step.y);
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  ImGui::Image(reinterpret_cast<ImTextureID>(ui.profile_texture),
               ImVec2(float(ui.profile_size.x), float(ui.profile_size.y)));
  if (ImGui::IsItemHovered()) {
    const ImVec2 mouse = ImGui::GetMousePos();
    const glm::dvec2 at =
        ui.profile_frame.from_pixel({mouse.x - origin.x, mouse.y - origin.y}, ui.profile_size);
    ImGui::SetTooltip("distance %.3f, height %.3f", at.x, at.y);
    // Two clicks in the profile measure between them (distance along, height, slope).
    if (ImGui::IsMouseClicked(0)) {
      if (ui.profile_clicks.size() == 2) ui.profile_clicks.clear();
      ui.profile_clicks.push_back(at);
    }
  }
  ImDrawList* draw = ImGui::GetWindowDrawList();
  for (const glm::dvec2& c : ui.profile_clicks) {
    const glm::dvec2 p = ui.profile_frame.to_pixel(c.x, c.y, ui.profile_size);
    draw->AddCircleFilled(ImVec2(origin.x + float(p.x), origin.y + float(p.y)), 4,
                          IM_COL32(255, 220, 50, 255));
  }
  if (ui.profile_clicks.size() == 2) {
    const glm::dvec2 a = ui.profile_clicks[0], b = ui.profile_clicks[1];
    const glm::dvec2 pa = ui.profile_frame.to_pixel(a.x, a.y, ui.profile_size);
    const glm::dvec2 pb = ui.profile_frame.to_pixel(b.x, b.y, ui.profile_size);
    draw->AddLine(ImVec2(origin.x + float(pa.x), origin.y + float(pa.y)),
                  ImVec2(origin.x + float(pb.x), origin.y + float(pb.y)),
                  IM_COL32(255, 220, 50, 255), 2);
    ImGui::Text("in the profile: along %.3f, height %+.3f, slope distance %.3f", b.x - a.x,
                b.y - a.y, glm::length(b - a));
  }
  if (tools::can_export(main)) {
    ImGui::InputText("image", ui.profile_png.data(), ui.profile_png.size());
    ImGui::InputText("csv", ui.profile_csv.data(), ui.profile_csv.size());
    ImGui::InputText("las", ui.profile_las.data(), ui.profile_las.size());
    if (ImGui::Button("export profile (R)"))
      tools::start_profile_export(
          main, item, {ui.profile_png.data(), ui.profile_csv.data(), ui.profile_las.data()});
  }
  ImGui::End();
}

void filter_panel(Registry& main) {
  auto& settings = main.resource<pc::PointDrawSettings>();
  const auto& s = main.resource<ToolsState>();
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
    f.gps_time = gps ? std::optional<glm::dvec2>(s.gps_extent) : std::nullopt;
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
  const glm::dvec2 viewport(main.resource<WindowState>().window_size);
  ImGui::SetNextWindowPos(ImVec2(float(viewport.x) - 370, float(viewport.y) - 330),
                          ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowSize(ImVec2(360, 320), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.85f);
  ImGui::Begin("inspected point");
  const tools::PointRecord& r = *s.inspected;
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
  const auto* settings = main.try_resource<UiSettings>();
  if (!settings || !settings->visible) return;
  auto& s = main.resource<ToolsState>();
  auto& ui = main.resource<ToolsUi>();
  ImGui::Begin("stipple");
  if (s.tool != Tool::None) {
    ImGui::Text("tool: %s", tools::tool_name(s.tool));
    if (s.active >= 0) {
      ImGui::SameLine();
      ImGui::TextDisabled("(Enter/right click: finish, Backspace: undo, Esc: cancel)");
    }
  }
  if (!s.message.empty()) ImGui::TextColored(ImVec4(1, 0.7f, 0.3f, 1), "%s", s.message.c_str());
  if (ui.tool_shown != s.tool) {
    // A tool chosen by its key opens the section once.
    if (s.tool != Tool::None) ImGui::SetNextItemOpen(true);
    ui.tool_shown = s.tool;
  }
  if (!ImGui::CollapsingHeader("measure, filter, clip, export")) {
    ImGui::End();
    inspect_window(main, s);
    profile_window(main, s, ui);
    return;
  }
  static constexpr const char* kKeys[tools::kToolCount] = {"0", "1", "2", "3", "4", "5",
                                                           "6", "7", "8", "9", "B", "G"};
  for (int t = 0; t < tools::kToolCount; ++t) {
    if (t % 3) ImGui::SameLine();
    if (ImGui::RadioButton(fmt::format("{} ({})", tools::tool_name(Tool(t)), kKeys[t]).c_str(),
                           s.tool == Tool(t)))
      tools::set_tool(main, Tool(t));
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
    const Measurement& m = s.items[i];
    ImGui::PushID(int(i));
    if (ImGui::Selectable(fmt::format("{} {}", tools::tool_name(m.tool),
                                      m.tool == Tool::Annotation ? "" : value_text(m, unit))
                              .c_str(),
                          s.selected == int(i)))
      tools::select(main, int(i));
    if (s.selected == int(i)) {
      char text[256];
      std::snprintf(text, sizeof(text), "%s", m.label.c_str());
      if (ImGui::InputText("label", text, sizeof(text))) tools::set_label(main, int(i), text);
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
        if (ImGui::InputDouble("plane z", &plane, 0.1, 1.0, "%.3f"))
          tools::set_plane_z(main, int(i), plane);
        ImGui::Text("  footprint %.3f, cells covered %.0f%%", m.values.area_horizontal,
                    m.values.covered_fraction * 100);
      }
      if (m.tool == Tool::Profile && m.complete) {
        float width = float(m.width);
        if (ImGui::DragFloat("width", &width, 0.1f, 0.01f, 1e6f, "%.2f"))
          tools::set_width(main, int(i), std::max(0.01f, width));
      }
      if (ImGui::SmallButton("delete")) remove = int(i);
    }
    ImGui::PopID();
  }
  if (remove >= 0) tools::remove(main, remove);
  ImGui::Separator();
  ImGui::InputText("file", ui.save_path.data(), ui.save_path.size());
  if (ImGui::Button("save GeoJSON")) {
    try {
      tools::save_measurements(s, ui.save_path.data());
      s.message = fmt::format("saved {}", ui.save_path.data());
    } catch (const Error& e) {
      s.message = e.what();
    }
  }
  ImGui::SameLine();
  if (ImGui::Button("load GeoJSON")) {
    try {
      tools::load_measurements(main, ui.save_path.data());
    } catch (const Error& e) {
      s.message = e.what();
    }
  }
  ImGui::SameLine();
  if (ImGui::Button("clear")) tools::clear(main);
  filter_panel(main);
  if (ImGui::TreeNode("export")) {
    export_panel(main, ui);
    ImGui::TreePop();
  }
  ImGui::End();
  inspect_window(main, s);
  profile_window(main, s, ui);
}

}  // namespace

void ToolsPlugin::build(Engine& engine) {
  engine.add_plugin(tools::ToolsCorePlugin{measurements_in, measurements_out});
  ToolsUi ui;
  set_text(ui.clip_path, "clip.laz");
  set_text(ui.profile_png, "profile.png");
  set_text(ui.profile_csv, "profile.csv");
  set_text(ui.profile_las, "");
  set_text(ui.save_path, measurements_out.empty() ? "measurements.geojson" : measurements_out);
  engine.main().insert_resource(std::move(ui));
  engine.add_system(MainStage::PreUpdate, tools_input, "tools_input");
  engine.add_system(MainStage::Update, tools_panel, "tools_panel");
  engine.add_system(MainStage::Update, tools_overlay, "tools_overlay");
}

}  // namespace stipple::viewer
