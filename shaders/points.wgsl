// Draws every point of a chunk (no CLOD): slot i is point i.
#include "point_draw.wgsl"

const kHasExtra = false;

fn point_index(slot: u32) -> u32 {
  return slot;
}

fn point_extra(index: u32) -> PointExtra {
  return PointExtra(0.0, 0u);
}
