#pragma once
// Content phase: one node's points become its tile file, tiles/LEVEL-X-Y-Z.glb or .pnts (with
// the chosen compression), and its entry in Build::nodes (point count and content box, which
// tileset.json and part.json read). Called by the indexing and the upper levels, from any
// thread.
#include <span>

#include "tiler_build.hpp"

namespace stipple::tiler::detail {

// Records the node (an empty node too: it is a tile without content) and writes its content.
void write_content(Build& b, const NodeKey& key, std::span<const TilePoint> pts);

}  // namespace stipple::tiler::detail
