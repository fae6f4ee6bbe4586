#pragma once
// The point filters and the clip region as the command line and the Python binding give them
// (the flags are parsed into FilterArgs by the app; polygons are read when the scene is set up).
#include <string>
#include <vector>

#include "stipple/pointcloud/filters.hpp"

namespace stipple::scene {

struct FilterArgs {
  pc::PointFilter filter;  // values already checked
  std::vector<pc::ClipBox> boxes;
  std::vector<pc::ClipPlane> planes;
  std::vector<std::string> polygon_files;  // GeoJSON, read by make_region
  pc::ClipMode mode = pc::ClipMode::Inside;
};

pc::PointFilter make_filter(const FilterArgs& args);
// Reads the polygon files (stipple::Error naming the file and the problem).
pc::ClipRegion make_region(const FilterArgs& args);

}  // namespace stipple::scene
