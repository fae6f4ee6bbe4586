// Compute rasterizer, geometry pass with a 64-bit visibility buffer (seed 001, sections 3.2-3.4):
// one workgroup per batch culls it against the frustum, picks the precision from its size on
// screen, and its threads project the batch's points, keeping the nearest per pixel with a
// 64-bit atomicMin of (depth << 32 | point index). Needs ShaderInt64AtomicMinMax (wgpu-native).
// Variants as pipeline constants: PREFETCH, CONTIGUOUS (compute_raster_batch.wgsl), PLAIN_EARLY,
// MERGE and SUBGROUP_REDUCE (compute_raster_write.wgsl), TILE (compute_raster_tile.wgsl). The
// shader is compute_raster64.wgsl, compute_raster64_subgroups.wgsl where the device has
// subgroups, or compute_raster64_key.wgsl (the early test on the whole key); each includes this
// file after the subgroup_write() and the early test (early_value, early_hidden) it has.
#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"
#include "compute_raster_tile.wgsl"

// The tile's point index per pixel (segment_base + index, as in the key), after its depth.
var<workgroup> tile_index: array<atomic<u32>, TILE_PIXELS>;

fn tile_clear_extra(i: u32) {
  atomicStore(&tile_index[i], 0xffffffffu);
}

@group(0) @binding(5) var<storage, read_write> visibility: array<atomic<u64>>;
// The same buffer as 32-bit words for the early depth test: only min/max are allowed on 64-bit
// atomics, so the depth (high) word is read through a 32-bit view, atomic or plain.
@group(0) @binding(6) var<storage, read_write> visibility_words: array<atomic<u32>>;
@group(0) @binding(8) var<storage, read_write> visibility_plain: array<u32>;

alias Key = u64;

fn point_key(depth: u32, index: u32) -> u64 {
  return (u64(depth) << 32u) | u64(params.segment_base + index);
}

fn key_less(a: u64, b: u64) -> bool {
  return a < b;
}

fn depth_word(pixel: u32) -> u32 {
  if (PLAIN_EARLY) {
    return visibility_plain[pixel * 2u + 1u];
  }
  return atomicLoad(&visibility_words[pixel * 2u + 1u]);
}

fn key_depth(key: u64) -> u32 {
  return u32(key >> 32u);
}

fn key_index(key: u64) -> u32 {
  return u32(key);
}

fn write_key(pixel: u32, key: u64) {
  if (TILE && tile_phase != 0u) {
    let i = tile_entry(pixel);
    if (i < TILE_PIXELS) {
      let depth = key_depth(key);
      if (tile_phase == 1u) {
        if (depth < atomicLoad(&tile_depth[i])) {
          atomicMin(&tile_depth[i], depth);
        }
      } else if (depth == atomicLoad(&tile_depth[i])) {
        atomicMin(&tile_index[i], u32(key));
      }
      return;
    }
    if (tile_phase == 2u) {
      return;  // written to the screen in phase 1
    }
  }
  // ABLATE (a measurement, wrong images): 2 leaves out the early test and the atomic, 1 the
  // atomic; the write that stays behind a condition that never holds keeps the work alive.
  if (ABLATE == 2u) {
    if (key == u64(0u)) {
      atomicMin(&visibility[pixel], key);
    }
    return;
  }
  // Early depth test: most occluded points never reach the atomic.
  if (EARLY_TEST && early_hidden(key, early_value(pixel))) {
    return;
  }
  if (ABLATE == 1u && key != u64(0u)) {
    return;
  }
  atomicMin(&visibility[pixel], key);
}

// write_key with the early test's value already read (`early`: early_value).
fn write_key_tested(pixel: u32, key: u64, early: Early) {
  if (early_hidden(key, early)) {
    return;
  }
  atomicMin(&visibility[pixel], key);
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
    tile_phase = 2u;
    draw_batch_points(b, bits, lid);
    workgroupBarrier();
    tile_phase = 0u;
    for (var i = lid; i < tile_size.x * tile_size.y; i += WORKGROUP) {
      let depth = atomicLoad(&tile_depth[i]);
      if (depth != 0xffffffffu) {
        write_key(tile_pixel(i), (u64(depth) << 32u) | u64(atomicLoad(&tile_index[i])));
      }
    }
    return;
  }
  draw_batch(b, bits, lid);
}
