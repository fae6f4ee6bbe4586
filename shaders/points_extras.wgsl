// points.wgsl with the per-point extras bound (GPS-time and point-source filters).
#include "point_draw.wgsl"

@group(1) @binding(1) var<storage, read> extras: array<PointExtra>;

const kHasExtra = true;

fn point_index(slot: u32) -> u32 {
  return slot;
}

fn point_extra(index: u32) -> PointExtra {
  return extras[index];
}
