#pragma once
// Each `stipple` subcommand registers its options on the CLI and runs from a callback.
#include <CLI/CLI.hpp>

namespace stipple::app {

void add_render_command(CLI::App& cli);
void add_info_command(CLI::App& cli);
void add_generate_command(CLI::App& cli);
void add_bench_command(CLI::App& cli);
void add_bench_raster_command(CLI::App& bench);     // `bench raster`, cmd_bench_raster.cpp
void add_bench_virtual_command(CLI::App& bench);    // `bench virtual`, cmd_bench_virtual.cpp
void add_bench_stream_command(CLI::App& bench);     // `bench stream`, cmd_bench_stream.cpp
void add_bench_batches_command(CLI::App& bench);    // `bench batches`, cmd_bench_batches.cpp
void add_bench_bandwidth_command(CLI::App& bench);  // `bench bandwidth`, bench_bandwidth.cpp
void add_bench_splats_command(CLI::App& bench);     // `bench splats`, cmd_bench_splats.cpp
void add_plugins_command(CLI::App& cli);
void add_tile_command(CLI::App& cli);
// `stipple bench points`, a subcommand of `bench`.
void add_bench_points_command(CLI::App* bench);
void add_view_command(CLI::App& cli);
void add_pointlets_command(CLI::App& cli);
void add_clip_command(CLI::App& cli);
void add_profile_command(CLI::App& cli);

}  // namespace stipple::app
