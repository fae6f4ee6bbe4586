// Compute rasterizer fallback without 64-bit atomics (seed 003, section 4.2): the depth pass
// keeps the nearest depth per pixel with a 32-bit atomicMin; colours follow in the
// accumulation pass. Same batch culling and precision choice as compute_raster64.wgsl.
#include "compute_raster_batch.wgsl"

@group(0) @binding(5) var<storage, read_write> depth_buffer: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> counters: array<atomic<u32>>;


@compute @workgroup_size(128)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
  if (group.x >= params.batch_count) {
    return;
  }
  let b = batches[group.x];
  if (lid == 0u) {
    var skipped = false;
    let bits = classify(params, b, &skipped);
    batch_bits = bits;
    atomicAdd(&counters[C_PROCESSED], 1u);
    if (bits == 0u) {
      atomicAdd(&counters[select(C_CULLED, C_LOD_SKIPPED, skipped)], 1u);
    } else {
      let k = bits / 10u - 1u;
      atomicAdd(&counters[C_RENDERED], 1u);
      atomicAdd(&counters[C_POINTS], b.count);
      atomicAdd(&counters[C_BATCHES_BITS + k], 1u);
      atomicAdd(&counters[C_POINTS_BITS + k], b.count);
    }
  }
  let bits = workgroupUniformLoad(&batch_bits);
  if (bits == 0u) {
    return;
  }
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
