// Compute rasterizer fallback without 64-bit atomics (seed 003, section 4.2): the depth pass
// keeps the nearest depth per pixel with a 32-bit atomicMin; colours follow in the
// accumulation pass. Same batch culling and precision choice as compute_raster64.wgsl.
#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"

@group(0) @binding(5) var<storage, read_write> depth_buffer: array<atomic<u32>>;

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
    let pr = project(params, load_position(b, bits, index));
    if (!pr.valid) {
      continue;
    }
    let depth = bitcast<u32>(pr.depth);
    if (depth >= atomicLoad(&depth_buffer[pr.pixel])) {
      continue;
    }
    atomicMin(&depth_buffer[pr.pixel], depth);
  }
}
