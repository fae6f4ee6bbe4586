// What the compute rasterizer's geometry passes share: the frame's parameters, the batches and
// the split positions (bindings 0-4), the batch's precision for the workgroup, and the load of
// a point at that precision (seed 001, section 3.3: only the needed buffers are read).
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> batches: array<GpuBatch>;
@group(0) @binding(2) var<storage, read> coarse: array<u32>;
@group(0) @binding(3) var<storage, read> medium: array<u32>;
@group(0) @binding(4) var<storage, read> fine: array<u32>;

var<workgroup> batch_bits: u32;

// Batches are dispatched as rows of workgroups (more than one dimension's limit of batches).
fn batch_index(group: vec3<u32>, groups: vec3<u32>) -> u32 {
  return group.y * groups.x + group.x;
}

// How every geometry pass starts: thread 0 classifies the workgroup's batch (frustum, LOD,
// precision) and reports it to count_batch(), which the including shader defines (counters, or
// nothing); then every thread gets the precision in bits, 0 when the batch is culled or skipped
// (or past the last batch). Call it from uniform control flow.
fn batch_prologue(group: u32, lid: u32) -> u32 {
  if (group >= params.batch_count) {
    return 0u;
  }
  if (lid == 0u) {
    let b = batches[group];
    var skipped = false;
    let bits = classify(params, b, &skipped);
    batch_bits = bits;
    count_batch(b, bits, skipped);
  }
  return workgroupUniformLoad(&batch_bits);
}

// Point `index` of batch `b` relative to the camera, from 10, 20 or 30 bits per axis.
fn load_position(b: GpuBatch, bits: u32, index: u32) -> vec3<f32> {
  let c = coarse[index];
  var m = 0u;
  var f = 0u;
  if (bits >= 20u) {
    m = medium[index];
  }
  if (bits >= 30u) {
    f = fine[index];
  }
  return b.offset + box_fraction(bits, c, m, f) * b.size;
}
