// The stipple command line: render, view, info, generate, bench, plugins, tile, pointlets, clip,
// profile.
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "stipple/app/commands.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"

int main(int argc, char** argv) {
  CLI::App cli{
      "stipple: a point-cloud engine on WebGPU (LAS/LAZ/COPC, headless rendering, viewer)"};
  cli.set_version_flag("--version", "stipple 0.1.0");
  cli.require_subcommand(1);
  int verbosity = 0;
  cli.add_flag("-v,--verbose", verbosity, "More log output (repeat for more)");
  cli.parse_complete_callback([&] { stipple::init_logging(verbosity); });
  stipple::app::add_render_command(cli);
  stipple::app::add_view_command(cli);
  stipple::app::add_info_command(cli);
  stipple::app::add_generate_command(cli);
  stipple::app::add_bench_command(cli);
  stipple::app::add_plugins_command(cli);
  stipple::app::add_tile_command(cli);
  stipple::app::add_pointlets_command(cli);
  stipple::app::add_clip_command(cli);
  stipple::app::add_profile_command(cli);
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return cli.exit(e);
  } catch (const stipple::Error& e) {
    std::fprintf(stderr, "stipple: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stipple: unexpected error: %s\n", e.what());
    return 2;
  }
  return 0;
}
