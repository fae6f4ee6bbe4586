// Draws the CLOD survivors of a chunk (indirect draw): slot i holds a point index.
#include "point_draw.wgsl"

@group(2) @binding(0) var<storage, read> survivors: array<u32>;

fn point_index(slot: u32) -> u32 {
  return survivors[slot];
}
