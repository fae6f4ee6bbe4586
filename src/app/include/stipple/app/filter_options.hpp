#pragma once
// The filter and clip flags of `clip`, `profile`, `render` and `view`: one syntax everywhere.
// `clip` and `profile` name the region --box/--polygon/--plane; `render` and `view` name it
// --clip-box/--clip-polygon/--clip-plane with --clip-mode. `render` and `view` already use
// --intensity-range for the colour ramp, so their intensity filter is --intensity-filter (which
// `clip` and `profile` accept too, beside --intensity-range).
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "stipple/scene/filter_args.hpp"

namespace stipple::app {

using scene::FilterArgs;
using scene::make_filter;
using scene::make_region;

enum class FilterFlags { Clip, Render };

void add_filter_options(CLI::App* cmd, FilterArgs& args, FilterFlags flags);

}  // namespace stipple::app
