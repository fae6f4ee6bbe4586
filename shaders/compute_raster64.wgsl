// Compute rasterizer, geometry pass with a 64-bit visibility buffer (seed 001, sections 3.2-3.3):
// one workgroup per batch culls it against the frustum, picks the precision from its size on
// screen, and each thread projects ~80 points, keeping the nearest per pixel with a 64-bit
// atomicMin of (depth << 32 | point index). Needs ShaderInt64AtomicMinMax (wgpu-native).
#include "compute_raster_batch.wgsl"
#include "compute_raster_counted.wgsl"

@group(0) @binding(5) var<storage, read_write> visibility: array<atomic<u64>>;
// The same buffer as 32-bit words: only min/max are allowed on 64-bit atomics, so the early
// depth test loads the depth (high) word through this view.
@group(0) @binding(6) var<storage, read_write> visibility_words: array<atomic<u32>>;

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
    let depth = bitcast<u32>(pr.depth);  // positive floats order like their bits
    // Early depth test: most occluded points never reach the atomic.
    if (depth > atomicLoad(&visibility_words[pr.pixel * 2u + 1u])) {
      continue;
    }
    atomicMin(&visibility[pr.pixel], (u64(depth) << 32u) | u64(params.segment_base + index));
  }
}
