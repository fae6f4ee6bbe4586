#pragma once
// Upper levels phase: the nodes above the chunk roots, down to the part level (the root in a
// whole tiling). From the deepest roots up, a parent subsamples the union of its children's
// points at its spacing; the selected points move up (additive refinement) and the children's
// content is final and written. Parents are a task graph run on the pool within a quarter of
// the budget. The merge of a split tiling runs the same phase above the parts' roots.
#include "tiler_build.hpp"

namespace stipple::tiler::detail {

// Consumes b.pending_roots. A whole tiling writes every node; a part leaves its part-level
// roots in b.pending_roots, as raw points for the merge.
void build_upper_levels(Build& b);

}  // namespace stipple::tiler::detail
