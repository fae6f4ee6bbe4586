#pragma once
// Indexing phase: the chunks in parallel on the pool, biggest first. Each chunk builds its
// subtree top-down, in place on its points: a node of more than max_node_points (and above the
// maximum level) keeps a grid subsample at its level's spacing and passes the rest to its 8
// children; a smaller node keeps everything (a leaf). Every point lands in exactly one node.
// The nodes below a chunk's root are written at once (tiler_content); the root's points go to a
// temporary file (Build::pending_roots), as the upper levels take their share of them.
#include "tiler_build.hpp"

namespace stipple::tiler::detail {

// Indexes every chunk (reading back those in temporary files), then frees the resident points.
// Starts b.index_progress, which the upper levels go on advancing.
void index_chunks(Build& b);

}  // namespace stipple::tiler::detail
