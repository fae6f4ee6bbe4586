#pragma once
// Parts phase (split tiling, Entwine's subset + merge): which part of the cube a run tiles
// (--subset I/N: the octree nodes of level log8 N or the columns of level log4 N), the part's
// output (its tiles, its part roots' raw points in roots/ and part.json), and the merge's own
// steps: the parts' part.json files checked against each other and the tiling's ranges, the
// settings taken from them, their tiles linked into the output and their roots handed to the
// upper levels (tiler_upper), which then build the levels above the parts.
#include <filesystem>
#include <vector>

#include <nlohmann/json.hpp>

#include "tiler_build.hpp"

namespace stipple::tiler::detail {

// b.part_level and b.part_columns from the options' subset (none: level 0, the whole cube).
void plan_part(Build& b);

// A part's tiles are written already; this moves its roots' raw points to roots/LEVEL-X-Y-Z.bin
// and writes part.json: what the merge needs to go on as build_tileset would above the part.
void write_part(Build& b);

// The parts of a merge, checked (every part of one split, once, each part.json of the shape and
// ranges write_part gives it, all of one tiling), and the options of the merged tileset.
struct PartSet {
  TileOptions options;
  std::vector<nlohmann::json> parts;
  std::vector<std::filesystem::path> dirs;
};
PartSet read_parts(const MergeOptions& options);

// The cube, spacing, levels, content options and frame of the tiling, from its first part.
void settings_from_part(Build& b, const nlohmann::json& first);
// The parts' nodes into b.nodes (their points into b.written), their tiles linked (or copied)
// into the output, their roots copied to temporary files in b.pending_roots.
void link_parts(Build& b, const std::vector<nlohmann::json>& parts,
                const std::vector<std::filesystem::path>& dirs);
// After the upper levels: throws unless the merged nodes hold the parts' points and form one
// tree.
void check_merged(const Build& b);

}  // namespace stipple::tiler::detail
