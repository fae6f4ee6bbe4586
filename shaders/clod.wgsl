// CLOD filter (seed 000, 6.1) as a compute pass: one thread per point of a chunk; survivors'
// indices are appended to the chunk's survivor buffer and counted in its indirect draw
// arguments (vertex_count += 6 per survivor). One global atomic per workgroup, not per point.
#include "point_common.wgsl"

@group(1) @binding(0) var<storage, read> points: array<Point>;
@group(2) @binding(0) var<storage, read_write> survivors: array<u32>;
// {vertex_count, instance_count, first_vertex, first_instance}
@group(2) @binding(1) var<storage, read_write> args: array<atomic<u32>, 4>;

var<workgroup> group_count: atomic<u32>;
var<workgroup> group_base: u32;

@compute @workgroup_size(256)
fn cs_clod(@builtin(global_invocation_id) gid: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
  if (lid == 0u) {
    atomicStore(&group_count, 0u);
  }
  workgroupBarrier();
  let i = gid.x;
  var keep = false;
  var slot = 0u;
  if (i < chunk.count) {
    let p = points[i];
    keep = clod_keep(vec3<f32>(p.x, p.y, p.z), frame.clod_k);
    if (keep) {
      slot = atomicAdd(&group_count, 1u);
    }
  }
  workgroupBarrier();
  if (lid == 0u) {
    group_base = atomicAdd(&args[0], atomicLoad(&group_count) * 6u) / 6u;
  }
  let base = workgroupUniformLoad(&group_base);
  if (keep) {
    survivors[base + slot] = i;
  }
}
