// Draws every point of a chunk (no CLOD): slot i is point i.
#include "point_draw.wgsl"

fn point_index(slot: u32) -> u32 {
  return slot;
}
