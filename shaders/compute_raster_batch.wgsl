// What the compute rasterizer's geometry passes share: the frame's parameters, the batches and
// the split positions (bindings 0-4), the batch's precision for the workgroup, and the loop over
// a batch's points at that precision (seed 001, section 3.3: only the needed words are read).
// The including shader defines draw_point(position, index), end_run() (called after a thread's
// last point: see compute_raster_write.wgsl) and count_batch(...).
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> batches: array<GpuBatch>;
// Four points' words per element (the arrays are padded to 16 bytes).
@group(0) @binding(2) var<storage, read> coarse: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> medium: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read> fine: array<vec4<u32>>;

// PREFETCH (seed 001, section 3.4): each thread loads four consecutive points with one 128-bit
// load per precision word and draws them, instead of one point per iteration.
// CONTIGUOUS: each thread takes one contiguous range of the batch (its share of the 16-byte
// words) instead of every WORKGROUP-th word: consecutive points of a spatially sorted batch
// fall on the same pixel at overview distances, and a thread merges them (MERGE) before
// touching memory.
override PREFETCH: bool = true;
override CONTIGUOUS: bool = false;

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
  let v = index >> 2u;
  let k = index & 3u;
  let c = coarse[v][k];
  var m = 0u;
  var f = 0u;
  if (bits >= 20u) {
    m = medium[v][k];
  }
  if (bits >= 30u) {
    f = fine[v][k];
  }
  return b.offset + box_fraction(bits, c, m, f) * b.size;
}

// Calls draw_point for every point of batch `b` this thread handles.
fn draw_batch_points(b: GpuBatch, bits: u32, lid: u32) {
  if (!PREFETCH) {
    for (var i = lid; i < b.count; i += WORKGROUP) {
      let index = b.first + i;
      draw_point(load_position(b, bits, index), index);
    }
    end_run();
    return;
  }
  // The aligned 16-byte words that cover the batch (the first and last may hold other
  // batches' points: skipped).
  let end = b.first + b.count;
  let first_word = b.first / 4u;
  let words = (end + 3u) / 4u - first_word;
  var v = first_word + lid;
  var stop = first_word + words;
  var step = WORKGROUP;
  if (CONTIGUOUS) {
    let share = (words + WORKGROUP - 1u) / WORKGROUP;
    v = first_word + min(lid * share, words);
    stop = first_word + min((lid + 1u) * share, words);
    step = 1u;
  }
  for (; v < stop; v += step) {
    let c4 = coarse[v];
    var m4 = vec4<u32>(0u);
    var f4 = vec4<u32>(0u);
    if (bits >= 20u) {
      m4 = medium[v];
    }
    if (bits >= 30u) {
      f4 = fine[v];
    }
    for (var k = 0u; k < 4u; k++) {
      let index = v * 4u + k;
      if (index >= b.first && index < end) {
        draw_point(b.offset + box_fraction(bits, c4[k], m4[k], f4[k]) * b.size, index);
      }
    }
  }
  end_run();
}
