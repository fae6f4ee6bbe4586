// `stipple plugins`: the engine's built-in plugins and their dependencies, as text and as
// Graphviz DOT (the paper's Figure 3 for this engine).
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "app/commands.hpp"
#include "core/error.hpp"
#include "engine/plugins.hpp"

namespace stipple::app {
namespace {

std::string join(const std::vector<std::string>& names) {
  return names.empty() ? "-" : fmt::format("{}", fmt::join(names, ", "));
}

void run_plugins(const std::string& dot_path) {
  // The list comes from an engine composed like an application's, so it cannot drift from code.
  Engine engine;
  engine.add_plugins(default_plugins());
  std::vector<PluginInfo> plugins = engine.plugins();
  std::printf("Built-in plugins (default_plugins(), in build order):\n");
  for (const auto& p : plugins) {
    std::printf("  %s\n      %s\n", p.name.c_str(), p.description.c_str());
    std::printf("      requires: %s\n", join(p.dependencies).c_str());
    std::printf("      optional: %s\n", join(p.optional_dependencies).c_str());
  }
  std::printf(
      "Engine core (not a plugin): ECS registry, main and render worlds with their stages,"
      " relations, SyncTo<Render>.\n");
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
