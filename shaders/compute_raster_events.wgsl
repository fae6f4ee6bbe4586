// raster-events: the 32-bit fallback's winner events (compute_raster_depth32_events_pass.wgsl)
// made into the visibility buffer the resolve pass reads (compute_raster_resolve.wgsl: point
// index, depth bits per pixel), without a second pass over the points. Three entry points,
// dispatched in this order in one compute pass:
//   overflow_main (one workgroup): whether a region's events outgrew its slots. The flag goes to
//     the depth buffer's word after the last pixel and, with the number of events, to the
//     counters (RasterCounters::events); without overflow the colour pass's indirect dispatch
//     sizes become 0 workgroups.
//   init_main (a thread a pixel): the pixel's depth from the depth buffer (empty everywhere on
//     overflow, so that the resolve pass writes zeros for the colour pass to add to), no index.
//   events_main (a workgroup a region): each event at its pixel's nearest depth lowers the
//     pixel's index with an atomicMin, so ties go to the lowest index, as with the 64-bit key.
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> depth_buffer: array<u32>;  // pixels + 1 words
@group(0) @binding(2) var<storage, read> events: array<u32>;
@group(0) @binding(3) var<storage, read_write> visibility: array<atomic<u32>>;  // 2 a pixel
@group(0) @binding(4) var<storage, read_write> counters: array<u32>;
// The colour pass's indirect dispatch, (x, y, z) a segment, its full size written each frame.
@group(0) @binding(5) var<storage, read_write> colour_dispatch: array<u32>;

const EVENT_REGIONS: u32 = 1024u;  // as in compute_raster_depth32_events_pass.wgsl

fn region_capacity() -> u32 {
  return (arrayLength(&events) - EVENT_REGIONS) / (3u * EVENT_REGIONS);
}

fn overflow_word() -> u32 {
  return params.width * params.height;
}

var<workgroup> overflowed: atomic<u32>;
var<workgroup> total: atomic<u32>;

@compute @workgroup_size(256)
fn overflow_main(@builtin(local_invocation_index) lid: u32) {
  if (lid == 0u) {
    atomicStore(&overflowed, 0u);
    atomicStore(&total, 0u);
  }
  workgroupBarrier();
  let capacity = region_capacity();
  var sum = 0u;
  for (var r = lid; r < EVENT_REGIONS; r += 256u) {
    sum += events[r];
    if (events[r] > capacity) {
      atomicOr(&overflowed, 1u);
    }
  }
  atomicAdd(&total, sum);
  workgroupBarrier();
  if (lid == 0u) {
    let flag = atomicLoad(&overflowed);
    depth_buffer[overflow_word()] = flag;
    counters[C_EVENTS] = atomicLoad(&total);
    counters[C_EVENTS_OVERFLOW] = flag;
    if (flag == 0u) {
      for (var i = 0u; i < arrayLength(&colour_dispatch); i += 3u) {
        colour_dispatch[i] = 0u;
      }
    }
  }
}

@compute @workgroup_size(16, 16)
fn init_main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= params.width || id.y >= params.height) {
    return;
  }
  let pixel = id.y * params.width + id.x;
  var depth = depth_buffer[pixel];
  if (depth_buffer[overflow_word()] != 0u) {
    depth = 0xffffffffu;
  }
  atomicStore(&visibility[pixel * 2u], 0xffffffffu);
  atomicStore(&visibility[pixel * 2u + 1u], depth);
}

@compute @workgroup_size(256)
fn events_main(@builtin(workgroup_id) group: vec3<u32>,
               @builtin(local_invocation_index) lid: u32) {
  if (depth_buffer[overflow_word()] != 0u) {
    return;
  }
  let region = group.x;
  let capacity = region_capacity();
  let count = events[region];
  for (var s = lid; s < count; s += 256u) {
    let o = EVENT_REGIONS + (region * capacity + s) * 3u;
    let pixel = events[o];
    if (events[o + 1u] == depth_buffer[pixel]) {
      atomicMin(&visibility[pixel * 2u], events[o + 2u]);
    }
  }
}
