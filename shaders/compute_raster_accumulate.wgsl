// Colour accumulation (seed 003 section 4.3; high-quality shading, seed 001 section 3.6): every
// point within a relative depth tolerance of the pixel's nearest depth adds its colour (shaded
// in the frame's mode) and a count with 32-bit atomicAdd; the display pass divides. The depth
// comes from the 32-bit depth buffer or from the high word of the 64-bit visibility buffer
// (depth_stride / depth_word).
#include "compute_raster_batch.wgsl"
#include "compute_raster_shading.wgsl"

@group(0) @binding(5) var<storage, read> colors: array<u32>;
@group(0) @binding(6) var<storage, read> depth_buffer: array<u32>;
@group(0) @binding(7) var<storage, read_write> accum: array<atomic<u32>>;

// The geometry passes count batches; accumulation does not.
fn count_batch(b: GpuBatch, bits: u32, skipped: bool) {}

@compute @workgroup_size(128)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
        @builtin(local_invocation_index) lid: u32) {
  let batch = batch_index(group, groups);
  let bits = batch_prologue(batch, lid);
  if (bits == 0u) {
    return;
  }
  let b = batches[batch];
  for (var i = lid; i < b.count; i += WORKGROUP) {
    let index = b.first + i;
    let position = load_position(b, bits, index);
    let pr = project(params, position);
    if (!pr.valid) {
      continue;
    }
    let nearest = bitcast<f32>(depth_buffer[pr.pixel * params.depth_stride + params.depth_word]);
    if (pr.depth > nearest * (1.0 + params.depth_tolerance)) {
      continue;
    }
    let c = channels(shade(colors[index], attributes_of(index), position.y));
    let o = pr.pixel * 4u;
    atomicAdd(&accum[o], c.x);
    atomicAdd(&accum[o + 1u], c.y);
    atomicAdd(&accum[o + 2u], c.z);
    atomicAdd(&accum[o + 3u], 1u);
  }
}
