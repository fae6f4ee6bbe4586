// Colour accumulation (seed 003 section 4.3; high-quality shading, seed 001 section 3.6): every
// point within a relative depth tolerance of the pixel's nearest depth adds its colour (shaded
// in the frame's mode) and a count; the display pass divides. The depth comes from the 32-bit
// depth buffer or from the high word of the 64-bit visibility buffer (depth_stride /
// depth_word).
//
// PACKED (seed 001, 3.6: one 64-bit add for up to 255 points, with overflow protection; here in
// two 32-bit words): a pixel's first 255 points add red | green << 16 to one word and
// blue | 1 << 16 to the other, two atomics instead of four. A point that finds 255 counted
// already takes its blue and count back and adds all four channels to the pixel's overflow
// words instead (add and subtract commute, so the packed sums end exact). raster-hqs-finish
// then writes the plain layout (sums, count) that the later passes read.
#include "compute_raster_batch.wgsl"
#include "compute_raster_shading.wgsl"

override PACKED: bool = false;

@group(0) @binding(5) var<storage, read> colors: array<u32>;
@group(0) @binding(6) var<storage, read> depth_buffer: array<u32>;
// Plain: four words a pixel (r, g, b, count); packed: eight (rg, b|count, then r, g, b, count
// of the overflow).
@group(0) @binding(7) var<storage, read_write> accum: array<atomic<u32>>;

// The geometry passes count batches; accumulation does not.
fn count_batch(b: GpuBatch, bits: u32, skipped: bool) {}

fn draw_point(position: vec3<f32>, index: u32) {
  let pr = project(params, position);
  if (!pr.valid) {
    return;
  }
  let nearest = bitcast<f32>(depth_buffer[pr.pixel * params.depth_stride + params.depth_word]);
  if (pr.depth > nearest * (1.0 + params.depth_tolerance)) {
    return;
  }
  let c = channels(shade(colors[index], attributes_of(index), position.y));
  if (!PACKED) {
    let o = pr.pixel * 4u;
    atomicAdd(&accum[o], c.x);
    atomicAdd(&accum[o + 1u], c.y);
    atomicAdd(&accum[o + 2u], c.z);
    atomicAdd(&accum[o + 3u], 1u);
    return;
  }
  let o = pr.pixel * 8u;
  let blue_count = c.z | (1u << 16u);
  let before = atomicAdd(&accum[o + 1u], blue_count);
  if ((before >> 16u) < 255u) {
    atomicAdd(&accum[o], c.x | (c.y << 16u));
    return;
  }
  atomicSub(&accum[o + 1u], blue_count);
  atomicAdd(&accum[o + 2u], c.x);
  atomicAdd(&accum[o + 3u], c.y);
  atomicAdd(&accum[o + 4u], c.z);
  atomicAdd(&accum[o + 5u], 1u);
}

@compute @workgroup_size(WORKGROUP)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
        @builtin(local_invocation_index) lid: u32) {
  let batch = batch_index(group, groups);
  let bits = batch_prologue(batch, lid);
  if (bits == 0u) {
    return;
  }
  draw_batch_points(batches[batch], bits, lid);
}
