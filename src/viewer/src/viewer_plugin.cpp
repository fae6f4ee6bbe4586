#include "stipple/viewer/viewer_plugin.hpp"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <imgui.h>

#include "stipple/engine/engine.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/engine/time.hpp"
#include "stipple/platform/input.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "stipple/viewer/camera_controller.hpp"
#include "stipple/viewer/tools_plugin.hpp"
#include "stipple/viewer/ui_plugin.hpp"
#include "stipple/viewer/window_plugins.hpp"

namespace stipple::viewer {
namespace {

using platform::Key;

// Main-world resource.
struct ViewerState {
  uint64_t exit_after_frames = 0;
  std::string screenshot;
  uint64_t frame = 0;
  double fps = 0;  // frames per second over the last half second
  double window_seconds = 0;
  uint32_t window_frames = 0;
};

void viewer_keys(Registry& main) {
  auto& state = main.resource<ViewerState>();
  const auto& input = main.resource<platform::InputState>();
  const auto* capture = main.try_resource<UiCapture>();
  // --frames counts from when a cache building in the background is in: the last frame (and
  // its screenshot) shows the virtualized cloud, not the sample drawn meanwhile.
  const auto* cache = main.try_resource<pc::VirtualCacheProgress>();
  const bool building = cache && cache->building;
  const uint64_t frame = building ? 0 : state.frame++;
  if (!building && state.exit_after_frames > 0 && frame + 1 >= state.exit_after_frames) {
    if (!state.screenshot.empty())
      main.resource<ScreenshotRequests>().paths.push_back(state.screenshot);
    main.resource<AppExit>().requested = true;
  }
  if (capture && capture->keyboard) return;
  // Escape quits, unless it cancels a measurement being drawn (the tools see it first).
  const auto* tool_state = main.try_resource<tools::ToolsState>();
  if (input.pressed(Key::Escape) && !(tool_state && tool_state->active >= 0))
    main.resource<AppExit>().requested = true;
  if (input.pressed(Key::P))
    main.resource<ScreenshotRequests>().paths.push_back(next_screenshot_name());
  if (input.pressed(Key::V))
    if (auto* surface = main.try_resource<SurfaceSettings>()) surface->vsync ^= true;
  if (input.pressed(Key::F1))
    if (auto* ui = main.try_resource<UiSettings>()) ui->visible ^= true;
}

// In pc::ColorMode's order.
const char* kColorModes[] = {"auto",      "rgb",    "intensity", "classification",
                             "elevation", "return", "constant"};

// A tileset's knobs are the streamer's: its memory budget (what stays resident) and the maximum
// screen-space error (how fine the drawn tiles are); PointDrawSettings::budget is unused there.
void tileset_controls(tiles3d::TilesetStream& stream, const tiles3d::TilesetStats& stats) {
  constexpr double kMiB = 1 << 20;
  ImGui::Text("tiles: %u drawn (%.2f M points), %u resident", stats.drawn_tiles,
              stats.drawn_points / 1e6, stats.resident_tiles);
  ImGui::Text("resident %.1f MiB of %.1f MiB (peak %.1f)", stats.resident_bytes / kMiB,
              stats.memory_budget / kMiB, stats.peak_resident_bytes / kMiB);
  tiles3d::TraversalOptions options = stream.streamer->traversal_options();
  bool changed = false;
  float budget = float(options.memory_budget / kMiB);
  if (ImGui::SliderFloat("memory budget", &budget, 1.0f, std::max(8192.0f, budget), "%.0f MiB",
                         ImGuiSliderFlags_Logarithmic)) {
    options.memory_budget = uint64_t(double(std::max(budget, 1.0f)) * kMiB);
    changed = true;
  }
  float sse = float(options.max_sse);
  if (ImGui::SliderFloat("max SSE", &sse, 0.5f, 128.0f, "%.1f px", ImGuiSliderFlags_Logarithmic)) {
    options.max_sse = std::max(sse, 0.5f);
    changed = true;
  }
  if (changed) stream.streamer->set_traversal_options(options);
  if (const auto streamer = stream.streamer->stats(); streamer.budget_limited)
    ImGui::TextDisabled("budget limits detail: SSE %.1f px", streamer.sse_threshold);
}

void viewer_panel(Registry& main) {
  auto& state = main.resource<ViewerState>();
  if (const auto* time = main.try_resource<Time>(); time && time->delta_seconds > 0) {
    state.window_seconds += time->delta_seconds;
    ++state.window_frames;
    if (state.window_seconds >= 0.5 || state.fps == 0) {
      state.fps = state.window_frames / state.window_seconds;
      state.window_seconds = 0;
      state.window_frames = 0;
    }
  }
  auto* ui = main.try_resource<UiSettings>();
  if (!ui || !ui->visible) return;
  const auto& stats = main.resource<RenderStatsSnapshot>();
  const auto& gpu = main.resource<GpuContext>()->description;
  const auto& scene = main.resource<pc::SceneInfo>();
  auto& settings = main.resource<pc::PointDrawSettings>();
  auto* surface = main.try_resource<SurfaceSettings>();  // absent with a headless target

  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.8f);
  ImGui::Begin("stipple", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  ImGui::Text("%s", scene.name.c_str());
  ImGui::Text("%.1f FPS (%.2f ms)", state.fps, state.fps > 0 ? 1e3 / state.fps : 0.0);
  double gpu_total = 0;
  for (const auto& [pass, ms] : stats.pass_ms) {
    ImGui::Text("  GPU %-8s %7.3f ms", pass.c_str(), ms);
    gpu_total += ms;
  }
  if (stats.pass_ms.empty())
    ImGui::TextDisabled("  GPU pass times: no timestamp queries");
  else
    ImGui::Text("  GPU total    %7.3f ms", gpu_total);
  ImGui::Text("points: %.2f M of %.2f M drawn", stats.points_drawn / 1e6, scene.points / 1e6);
  ImGui::Text("%s on %s (%s)", gpu.backend.c_str(), gpu.device.c_str(), gpu.graphics_api.c_str());
  if (const auto* info = main.try_resource<SurfaceInfo>())
    ImGui::Text("%ux%u, present %s", info->size.x, info->size.y, info->present_mode.c_str());
  ImGui::Separator();

  const auto* cache = main.try_resource<pc::VirtualCacheProgress>();
  if (cache && cache->building) {
    // A sample of the input is drawn while the pointlet cache builds (view --virtual).
    ImGui::Text("pointlet cache: %s", pc::describe_cache_progress(*cache).c_str());
    ImGui::ProgressBar(float(cache->fraction), ImVec2(-1, 0));
    ImGui::TextDisabled("a sample read across the input is drawn until then");
  } else if (auto* stream = main.try_resource<tiles3d::TilesetStream>()) {
    tileset_controls(*stream, main.resource<tiles3d::TilesetStats>());
  } else if (const auto* v = main.try_resource<pc::VirtualCloudStats>()) {
    // The virtualized path (seed 002): what the last camera change selected and cost.
    const auto& cache = main.resource<pc::VirtualCloudCache>();
    ImGui::Text("pointlets: %llu of k = %llu", static_cast<unsigned long long>(cache.pointlets),
                static_cast<unsigned long long>(cache.pointlet_points));
    ImGui::Text("bucket B %.2f M; selected %.2f M in %u pointlets", v->bucket / 1e6,
                v->selected_points / 1e6, v->visible_pointlets);
    ImGui::Text("host %.1f MiB, GPU %.1f MiB, staging %.1f MiB", v->host_bytes / 1048576.0,
                v->gpu_bytes / 1048576.0, v->staging_bytes / 1048576.0);
    ImGui::Text("loads queued %u; last update kept %.2f M, sent %.2f M", v->pending_loads,
                v->kept_points / 1e6, v->new_points / 1e6);
    ImGui::Text("CPU: LoD %.2f ms, update %.2f ms", v->lod_ms, v->upload_ms);
    for (size_t i = 0; i < v->stage_ms.size(); ++i)
      ImGui::Text("GPU %-10s %.3f ms", std::string(pc::kStageNames[i]).c_str(), v->stage_ms[i]);
  } else {
    bool limit = settings.budget > 0;
    if (ImGui::Checkbox("point budget", &limit))
      settings.budget = limit ? std::max<uint64_t>(scene.points / 2, 1) : 0;
    if (limit) {
      float millions = float(settings.budget / 1e6);
      if (ImGui::SliderFloat("M points", &millions, 0.01f, float(scene.points / 1e6), "%.2f",
                             ImGuiSliderFlags_Logarithmic))
        settings.budget = std::max<uint64_t>(uint64_t(double(millions) * 1e6), 1);
    }
  }
  pc::PointRenderSettings& render = settings.render;
  ImGui::SliderFloat("point size", &render.point_size, 1.0f, 16.0f, "%.1f px");
  ImGui::Checkbox("round points", &render.round);
  int color = int(render.color);
  if (ImGui::Combo("colour", &color, kColorModes, IM_ARRAYSIZE(kColorModes)))
    render.color = pc::ColorMode(color);
  bool blend = render.splat == pc::SplatMode::Blend;
  if (ImGui::Checkbox("blend splats", &blend))
    render.splat = blend ? pc::SplatMode::Blend : pc::SplatMode::Naive;
  ImGui::Checkbox("eye-dome lighting", &render.edl);
  if (render.edl) ImGui::SliderFloat("EDL strength", &render.edl_strength, 1.0f, 300.0f, "%.0f");
  ImGui::SliderFloat("CLOD k (0 = off)", &render.clod_k, 0.0f, 0.01f, "%.4f");
  if (surface) ImGui::Checkbox("vsync (V)", &surface->vsync);
  main.view<CameraController>().each([&](CameraController& c) {
    int mode = int(c.mode);
    ImGui::Text("camera:");
    ImGui::SameLine();
    bool changed = ImGui::RadioButton("orbit", &mode, 0);
    ImGui::SameLine();
    changed |= ImGui::RadioButton("fly (F/Tab)", &mode, 1);
    if (changed && mode != int(c.mode)) toggle_mode(c);
  });
  if (ImGui::CollapsingHeader("controls")) {
    ImGui::TextUnformatted(
        "orbit: left drag rotate, right/middle drag pan, wheel zoom to cursor\n"
        "fly: WASD move, Q/E down/up, shift faster, drag to look\n"
        "double click: focus the point under the cursor\n"
        "F/Tab camera mode, P screenshot, V vsync, F1 hide panel, Esc quit");
  }
  ImGui::End();
}

}  // namespace

std::string next_screenshot_name() {
  for (int n = 1;; ++n) {
    std::string name = fmt::format("stipple-screenshot-{}.png", n);
    if (!std::filesystem::exists(name)) return name;
  }
}

void ViewerPlugin::require(Engine& engine) {
  if (!engine.has_plugin("PointCloudPlugin") && !engine.has_plugin("TilesetPlugin") &&
      !engine.has_plugin("VirtualPointCloudPlugin"))
    fail(
        "ViewerPlugin needs PointCloudPlugin, VirtualPointCloudPlugin or TilesetPlugin (the "
        "scene it shows)");
}

void ViewerPlugin::build(Engine& engine) {
  engine.main().insert_resource(ViewerState{exit_after_frames, screenshot});
  engine.add_system(MainStage::PreUpdate, viewer_keys, "viewer_keys");
  engine.add_system(MainStage::Update, viewer_panel, "viewer_panel");
}

}  // namespace stipple::viewer
