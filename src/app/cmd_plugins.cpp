// `stipple plugins`: the engine's built-in plugins and their dependencies, as text and as
// Graphviz DOT (the paper's Figure 3 for this engine).
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "app/camera_controller.hpp"
#include "app/commands.hpp"
#include "app/point_cloud_plugin.hpp"
#include "app/tileset_plugin.hpp"
#include "app/ui_plugin.hpp"
#include "app/viewer_plugin.hpp"
#include "app/window_plugins.hpp"
#include "core/error.hpp"
#include "engine/plugins.hpp"
#include "engine/render_plugins.hpp"

namespace stipple::app {
namespace {

std::string join(const std::vector<std::string>& names) {
  return names.empty() ? "-" : fmt::format("{}", fmt::join(names, ", "));
}

// Every built-in plugin, engine ones first, in an order where dependencies come first.
std::vector<PluginInfo> builtin_plugins() {
  return {plugin_info<TimePlugin>(),
          plugin_info<TransformPlugin>(),
          plugin_info<CameraPlugin>(),
          plugin_info<PipelinedRenderingPlugin>(),
          plugin_info<GpuPlugin>(),
          plugin_info<RenderGraphPlugin>(),
          plugin_info<HeadlessTargetPlugin>(),
          plugin_info<PointCloudPlugin>(),
          plugin_info<TilesetPlugin>(),
          plugin_info<WindowPlugin>(),
          plugin_info<InputPlugin>(),
          plugin_info<SurfaceTargetPlugin>(),
          plugin_info<UiPlugin>(),
          plugin_info<CameraControllerPlugin>(),
          plugin_info<ViewerPlugin>()};
}

void run_plugins(const std::string& dot_path) {
  // Listed from the plugin types themselves (building them would open windows and devices), so
  // names and dependencies cannot drift from the code.
  std::vector<PluginInfo> plugins = builtin_plugins();
  std::printf("Built-in plugins (dependencies first):\n");
  for (const auto& p : plugins) {
    std::printf("  %s\n      %s\n", p.name.c_str(), p.description.c_str());
    std::printf("      requires: %s\n", join(p.dependencies).c_str());
    std::printf("      optional: %s\n", join(p.optional_dependencies).c_str());
  }
  std::printf(
      "Engine core (not a plugin): ECS registry, main and render worlds with their stages,"
      " relations, SyncTo<Render>.\n");
  std::printf(
      "stipple render: TimePlugin, TransformPlugin, CameraPlugin, [PipelinedRenderingPlugin "
      "with --pipelined], GpuPlugin, RenderGraphPlugin, PointCloudPlugin (TilesetPlugin for a "
      "tileset), "
      "HeadlessTargetPlugin\n");
  std::printf(
      "stipple view:   TimePlugin, TransformPlugin, CameraPlugin, PipelinedRenderingPlugin "
      "[not with --single-thread], GpuPlugin, RenderGraphPlugin, PointCloudPlugin (TilesetPlugin "
      "for a tileset), WindowPlugin, "
      "InputPlugin, SurfaceTargetPlugin, UiPlugin [not with --no-ui], CameraControllerPlugin, "
      "ViewerPlugin\n");
  if (dot_path.empty()) return;
  std::string dot = plugins_dot(plugins);
  if (dot_path == "-") {
    std::fputs(dot.c_str(), stdout);
    return;
  }
  std::ofstream out(dot_path, std::ios::binary);
  if (!out || !(out << dot)) fail("cannot write {}", dot_path);
}

}  // namespace

void add_plugins_command(CLI::App& cli) {
  auto dot_path = std::make_shared<std::string>();
  auto* cmd = cli.add_subcommand(
      "plugins", "List the engine's built-in plugins and their dependencies (required, optional)");
  cmd->add_option("--dot", *dot_path,
                  "Also write the dependency graph as Graphviz DOT to FILE ('-' for stdout)");
  cmd->callback([dot_path] { run_plugins(*dot_path); });
}

}  // namespace stipple::app
