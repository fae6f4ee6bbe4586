// Compute rasterizer fallback without 64-bit atomics (seed 003, section 4.2): the depth pass
// keeps the nearest depth per pixel with a 32-bit atomicMin; colours follow in the
// accumulation pass. Same batch culling, precision choice and variants as
// compute_raster64_pass.wgsl but SUBGROUP_REDUCE. The including shader (compute_raster_depth32
// or _depth32_plain.wgsl) defines depth_word(pixel), the early test's load.
#include "compute_raster_reduce_none.wgsl"
#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"
#include "compute_raster_tile.wgsl"

fn tile_clear_extra(i: u32) {}

@group(0) @binding(5) var<storage, read_write> depth_buffer: array<atomic<u32>>;

alias Key = u32;

fn point_key(depth: u32, index: u32) -> u32 {
  return depth;
}

fn key_less(a: u32, b: u32) -> bool {
  return a < b;
}

fn write_key(pixel: u32, depth: u32) {
  if (TILE && tile_phase != 0u) {
    let i = tile_entry(pixel);
    if (i < TILE_PIXELS) {
      if (depth < atomicLoad(&tile_depth[i])) {
        atomicMin(&tile_depth[i], depth);
      }
      return;
    }
  }
  if (EARLY_TEST && depth >= depth_word(pixel)) {
    return;
  }
  atomicMin(&depth_buffer[pixel], depth);
}

alias Early = u32;

fn early_value(pixel: u32) -> u32 {
  return depth_word(pixel);
}

// write_key with the early test's depth already read (`early`: early_value).
fn write_key_tested(pixel: u32, depth: u32, early: u32) {
  if (depth >= early) {
    return;
  }
  atomicMin(&depth_buffer[pixel], depth);
}

#include "compute_raster_write.wgsl"

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
        @builtin(local_invocation_index) lid: u32) {
  if (BATCHES_PER_GROUP > 1u) {
    draw_batch_group(group, groups, lid);
    return;
  }
  let batch = batch_index(group, groups);
  let bits = batch_prologue(batch, lid);
  if (bits == 0u) {
    return;
  }
  let b = batches[batch];
  if (TILE && tile_begin(b, lid)) {
    tile_phase = 1u;
    draw_batch_points(b, bits, lid);
    workgroupBarrier();
    tile_phase = 0u;
    for (var i = lid; i < tile_size.x * tile_size.y; i += WORKGROUP) {
      let depth = atomicLoad(&tile_depth[i]);
      if (depth != 0xffffffffu) {
        write_key(tile_pixel(i), depth);
      }
    }
    return;
  }
  draw_batch(b, bits, lid);
}
