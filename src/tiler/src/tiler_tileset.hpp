#pragma once
// Tileset phase: tileset.json over Build::nodes. Explicit, every tile listed with its box (the
// content box united with its children's, padded a little) and geometric error (its level's
// spacing); or implicit (3D Tiles 1.1 implicit tiling): one octree over the cube whose
// availability is written in subtree files of `subtree_levels` levels. The root transform maps
// the local ENU frame to ECEF.
#include "tiler_build.hpp"

namespace stipple::tiler::detail {

void write_tileset(Build& b);

}  // namespace stipple::tiler::detail
