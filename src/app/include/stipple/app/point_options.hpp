#pragma once
// The command-line flags of the point pipeline (PointRenderSettings), shared by `stipple render`
// and `stipple view` so that both accept the same options with the same meaning.
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "stipple/pointcloud/point_renderer.hpp"
#include "stipple/scene/scene.hpp"

namespace stipple::app {

// Registers --color, --constant-color, --elevation-range, --intensity-range, --point-size,
// --point-size-mode, --size-scale, --clod-k, --splat, --blend-depth, --no-edl, --edl-radius,
// --edl-strength, --background, --sky, --sun, --sky-exposure on `cmd`; parsed values land in
// `settings` (which must outlive the parse). Malformed lists ("r,g,b") throw CLI::ValidationError
// naming the flag.
void add_point_render_options(CLI::App* cmd, pc::PointRenderSettings& settings);

// "1,2,3" -> {1, 2, 3} (stipple::Error naming `what` unless exactly `expected` finite numbers).
using scene::parse_numbers;

}  // namespace stipple::app
