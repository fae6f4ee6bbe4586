// The compute rasterizer's translucent points (raster-translucent), for clouds that have some in
// the RGB mode: the batch passes (SPLIT 1) drew the opaque points; this pass (SPLIT 2) draws the
// points whose coarse word carries the translucent bit, as weighted blended order-independent
// transparency (McGuire and Bavoil 2013) resolved over the opaque visibility buffer. Each point
// covers the disc of the point size around its pixel (as the dilation widens the opaque points);
// at each covered pixel in front of the opaque depth (after dilation) it adds, with atomics in
// fixed point, its alpha-weighted colour and its alpha (bytes, exact) and -ln(1 - alpha) in units
// of 1 / REVEAL_SCALE: the revealage, the product of (1 - alpha), is exp(-sum), whatever order
// the threads add in. The display pass lays the average colour over the opaque image by the
// coverage 1 - revealage (compute_raster_display_translucent.wgsl). The weight is the alpha
// alone, as the billboard path's (point_draw.wgsl): the sums stay exact and bounded.
#include "compute_raster_batch.wgsl"
#include "compute_raster_filter.wgsl"

@group(0) @binding(5) var<storage, read> colors: array<u32>;
// The opaque depth the display shows (dilated where points are larger than a pixel).
@group(0) @binding(6) var<storage, read> depth_buffer: array<u32>;
// Four words a pixel (sum of r * a, g * a, b * a, sum of a), then a word a pixel (sum of
// -ln(1 - a) * REVEAL_SCALE).
@group(0) @binding(7) var<storage, read_write> sums: array<atomic<u32>>;

struct DiscParams {
  width: u32,
  height: u32,
  radius: u32,        // pixels each side of the point's pixel
  depth_stride: u32,  // u32 words per pixel of the depth buffer (2: 64-bit visibility buffer)
  depth_word: u32,    // which word holds the depth
  pad0: f32,
  pad1: f32,
  radius2: f32,       // squared disc radius: offsets with dx^2 + dy^2 <= radius2
}
@group(0) @binding(8) var<uniform> disc: DiscParams;

// No counters: the depth pass counted the batches.
fn count_batch(b: GpuBatch, bits: u32, skipped: bool) {}
fn end_run() {}

// Above this the revealage is 0 to any precision (exp(-64)): later points stop adding, so the
// word cannot overflow however many points a pixel holds.
const REVEAL_CAP: u32 = 64u * 4096u;

fn add_translucent(pixel: u32, sum: vec4<u32>, cover: u32) {
  let o = pixel * 4u;
  atomicAdd(&sums[o], sum.x);
  atomicAdd(&sums[o + 1u], sum.y);
  atomicAdd(&sums[o + 2u], sum.z);
  atomicAdd(&sums[o + 3u], sum.w);
  let r = disc.width * disc.height * 4u + pixel;
  if (atomicLoad(&sums[r]) < REVEAL_CAP) {
    atomicAdd(&sums[r], cover);
  }
}

fn draw_point(cells: vec3<f32>, index: u32) {
  let pr = project_point(cells);
  if (!pr.valid) {
    return;
  }
  let state = raster_filter(index, point_position(cells));
  if (state == 0u) {
    return;
  }
  let c = colors[index];
  let a = c >> 24u;
  if (a == 0u || a == 255u) {
    return;
  }
  var rgb = vec3<u32>(c & 0xffu, (c >> 8u) & 0xffu, (c >> 16u) & 0xffu);
  if (state == 2u) {
    let tinted = highlighted(vec3<f32>(rgb) / 255.0);
    rgb = vec3<u32>(round(clamp(tinted, vec3<f32>(0.0), vec3<f32>(1.0)) * 255.0));
  }
  let sum = vec4<u32>(rgb * a, a);
  let cover = u32(round(-log(1.0 - f32(a) / 255.0) * REVEAL_SCALE));
  // Positive floats order as their bits; an empty pixel's depth (all ones) is the furthest.
  let depth = bitcast<u32>(pr.depth);
  let r = i32(disc.radius);
  for (var dy = -r; dy <= r; dy++) {
    for (var dx = -r; dx <= r; dx++) {
      let x = i32(pr.xy.x) + dx;
      let y = i32(pr.xy.y) + dy;
      if (f32(dx * dx + dy * dy) > disc.radius2 || x < 0 || y < 0 || x >= i32(disc.width) ||
          y >= i32(disc.height)) {
        continue;
      }
      let q = u32(y) * disc.width + u32(x);
      if (depth < depth_buffer[q * disc.depth_stride + disc.depth_word]) {
        add_translucent(q, sum, cover);
      }
    }
  }
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
