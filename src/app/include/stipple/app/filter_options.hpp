#pragma once
// The filter and clip flags of `clip`, `profile`, `render` and `view`: one syntax everywhere.
// `clip` and `profile` name the region --box/--polygon/--plane; `render` and `view` name it
// --clip-box/--clip-polygon/--clip-plane with --clip-mode. `render` and `view` already use
// --intensity-range for the colour ramp, so their intensity filter is --intensity-filter (which
// `clip` and `profile` accept too, beside --intensity-range).
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "stipple/pointcloud/filters.hpp"

namespace stipple::app {

struct FilterArgs {
  pc::PointFilter filter;  // filled while the flags are parsed (values checked there)
  std::vector<pc::ClipBox> boxes;
  std::vector<pc::ClipPlane> planes;
  std::vector<std::string> polygon_files;  // GeoJSON, read by make_region
  pc::ClipMode mode = pc::ClipMode::Inside;
};

enum class FilterFlags { Clip, Render };

void add_filter_options(CLI::App* cmd, FilterArgs& args, FilterFlags flags);

pc::PointFilter make_filter(const FilterArgs& args);
// Reads the polygon files (stipple::Error naming the file and the problem).
pc::ClipRegion make_region(const FilterArgs& args);

}  // namespace stipple::app
