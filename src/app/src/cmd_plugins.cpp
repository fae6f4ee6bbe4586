// `stipple plugins`: the engine's built-in plugins and their dependencies, as text and as
// Graphviz DOT (the paper's Figure 3 for this engine).
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "stipple/app/commands.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/engine/plugins.hpp"
#include "stipple/engine/render_plugins.hpp"
#include "stipple/pointcloud/point_cloud_plugin.hpp"
#include "stipple/pointcloud/virtual_cloud.hpp"
#include "stipple/splats/splat_plugin.hpp"
#include "stipple/tiles3d/tileset_plugin.hpp"
#include "stipple/viewer/camera_controller.hpp"
#include "stipple/viewer/script.hpp"
#include "stipple/viewer/tools_plugin.hpp"
#include "stipple/viewer/ui_plugin.hpp"
#include "stipple/viewer/viewer_plugin.hpp"
#include "stipple/viewer/window_plugins.hpp"

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
          plugin_info<pc::PointCloudPlugin>(),
          plugin_info<pc::VirtualPointCloudPlugin>(),
          plugin_info<tiles3d::TilesetPlugin>(),
          plugin_info<splats::SplatPlugin>(),
          plugin_info<viewer::WindowPlugin>(),
          plugin_info<viewer::InputPlugin>(),
          plugin_info<viewer::SurfaceTargetPlugin>(),
          plugin_info<viewer::UiPlugin>(),
          plugin_info<viewer::ScriptedInputPlugin>(),
          plugin_info<tools::ToolsCorePlugin>(),
          plugin_info<viewer::ToolsPlugin>(),
          plugin_info<viewer::CameraControllerPlugin>(),
          plugin_info<viewer::ViewerPlugin>()};
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
      "tileset, VirtualPointCloudPlugin over the host budget or with --virtual), "
      "HeadlessTargetPlugin\n");
  std::printf(
      "stipple view:   TimePlugin, TransformPlugin, CameraPlugin, PipelinedRenderingPlugin "
      "[not with --single-thread], GpuPlugin, RenderGraphPlugin, PointCloudPlugin (TilesetPlugin "
      "for a tileset, VirtualPointCloudPlugin over the host budget or with --virtual), "
      "WindowPlugin, [ScriptedInputPlugin with --script], "
      "InputPlugin, SurfaceTargetPlugin, UiPlugin [not with --no-ui], ToolsPlugin (adds "
      "ToolsCorePlugin), "
      "CameraControllerPlugin, ViewerPlugin\n");
  if (dot_path.empty()) return;
  std::string dot = plugins_dot(plugins);
  if (dot_path == "-") {
    std::fputs(dot.c_str(), stdout);
    return;
  }
  write_file_atomically(dot_path, dot);
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
