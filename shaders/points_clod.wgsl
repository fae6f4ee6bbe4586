// Draws the CLOD survivors of a chunk (indirect draw): slot i holds a point index.
#include "point_draw.wgsl"

@group(2) @binding(0) var<storage, read> survivors: array<u32>;

const kHasExtra = false;

fn point_index(slot: u32) -> u32 {
  return survivors[slot];
}

fn point_extra(index: u32) -> PointExtra {
  return PointExtra(0.0, 0u);
}
