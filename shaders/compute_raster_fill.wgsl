// Seed 002, III-D, on the resolved pixels (colour sums and counts, and the nearest depth of each
// pixel), two entry points run in order when enabled:
//   occlusion_main: the visibility check of eq. 4. A point is dropped when a nearer neighbour
//     within the radius sees it at an angle beta = |atan(lateral / (d1 - d2))| of at most the
//     threshold, with lateral = 2 max(d1, d2) tan(FOV_x / width) times the pixel distance:
//     background points that show through gaps of a surface in front.
//   fill_main: hole filling. An empty pixel with at least one non-empty pixel in its n x n
//     neighbourhood (n = 2 radius + 1) takes the mean colour of those pixels; larger holes and
//     the background beyond the cloud's edge stay empty.
// And before them, for points larger than one pixel:
//   dilate_main: depth-aware dilation of the visibility buffer. Every drawn pixel stands for a
//     disc of the point size (offsets with dx^2 + dy^2 <= radius2); a pixel takes the nearest
//     of the discs that cover it, colour and depth, as a depth test of splats would.
//   dilate_depth_main, dilate_offset_main, dilate_resolve_main: the same result by scatter, in
//     three dispatches: each drawn pixel writes its depth into every pixel of its disc
//     (atomic), then its offset where its depth is the nearest there (atomic: the first in
//     dilate_main's scan order wins a tie, as there), then each pixel copies the winner's colour
//     and depth. Work follows the drawn pixels, not the window over every pixel: points larger
//     than a pixel leave most pixels empty before dilation. Where the display is the only
//     reader, it reads through the winners itself and the resolve does not run (WINNER in
//     compute_raster_display_common.wgsl).

#include "compute_raster_dilate_code.wgsl"

struct FillParams {
  width: u32,
  height: u32,
  radius: u32,
  depth_stride: u32,  // u32 words per pixel of the depth buffer (2: 64-bit visibility buffer)
  depth_word: u32,    // which word holds the depth
  beta: f32,          // occlusion threshold, radians
  pixel_tan: f32,     // tan(FOV_x / width)
  radius2: f32,       // dilation: squared disc radius (pixels)
}

@group(0) @binding(0) var<uniform> fp: FillParams;
@group(0) @binding(1) var<storage, read> depth_buffer: array<u32>;
@group(0) @binding(2) var<storage, read> accum_in: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> accum_out: array<vec4<u32>>;
// dilate_main only: the dilated depth buffer, in the input's layout.
@group(0) @binding(4) var<storage, read_write> depth_out: array<u32>;

fn depth_of(pixel: u32) -> f32 {
  return bitcast<f32>(depth_buffer[pixel * fp.depth_stride + fp.depth_word]);
}

@compute @workgroup_size(16, 16)
fn occlusion_main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= fp.width || id.y >= fp.height) {
    return;
  }
  let pixel = id.y * fp.width + id.x;
  let a = accum_in[pixel];
  if (a.w == 0u) {
    accum_out[pixel] = a;
    return;
  }
  let d1 = depth_of(pixel);
  let r = i32(fp.radius);
  for (var dy = -r; dy <= r; dy++) {
    for (var dx = -r; dx <= r; dx++) {
      let x = i32(id.x) + dx;
      let y = i32(id.y) + dy;
      if ((dx == 0 && dy == 0) || x < 0 || y < 0 || x >= i32(fp.width) || y >= i32(fp.height)) {
        continue;
      }
      let q = u32(y) * fp.width + u32(x);
      if (accum_in[q].w == 0u) {
        continue;
      }
      let d2 = depth_of(q);
      if (d2 >= d1) {
        continue;
      }
      let lateral = 2.0 * max(d1, d2) * fp.pixel_tan * length(vec2<f32>(f32(dx), f32(dy)));
      if (abs(atan(lateral / (d1 - d2))) <= fp.beta) {
        accum_out[pixel] = vec4<u32>(0u);  // behind a nearer surface: dropped
        return;
      }
    }
  }
  accum_out[pixel] = a;
}

@compute @workgroup_size(16, 16)
fn fill_main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= fp.width || id.y >= fp.height) {
    return;
  }
  let pixel = id.y * fp.width + id.x;
  let a = accum_in[pixel];
  if (a.w != 0u) {
    accum_out[pixel] = a;
    return;
  }
  // The mean of the neighbours' colours (each a sum over its count), kept at 8-bit scale.
  var sum = vec3<f32>(0.0);
  var n = 0u;
  let r = i32(fp.radius);
  for (var dy = -r; dy <= r; dy++) {
    for (var dx = -r; dx <= r; dx++) {
      let x = i32(id.x) + dx;
      let y = i32(id.y) + dy;
      if (x < 0 || y < 0 || x >= i32(fp.width) || y >= i32(fp.height)) {
        continue;
      }
      let b = accum_in[u32(y) * fp.width + u32(x)];
      if (b.w == 0u) {
        continue;
      }
      sum += vec3<f32>(b.xyz) / f32(b.w);
      n++;
    }
  }
  if (n == 0u) {
    accum_out[pixel] = vec4<u32>(0u);
    return;
  }
  accum_out[pixel] = vec4<u32>(vec3<u32>(round(sum / f32(n))), 1u);
}

// The disc's half-width in row dy (|dy| <= r): the largest dx with dx^2 + dy^2 <= radius2, as
// f32 (the disc's own test, so the scan visits exactly its offsets, in the same order), or -1
// where the row misses it. Loops over the disc alone instead of the (2r + 1)^2 window: on
// SwiftShader the scatter 1.4x faster at 3.5 px (9 offsets of 25).
fn disc_span(dy: i32, r: i32) -> i32 {
  var span = r;
  while (span >= 0 && f32(span * span + dy * dy) > fp.radius2) {
    span--;
  }
  return span;
}

@compute @workgroup_size(16, 16)
fn dilate_main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= fp.width || id.y >= fp.height) {
    return;
  }
  let pixel = id.y * fp.width + id.x;
  // Depths are positive floats: their bits order as u32s (the clear value is the largest).
  var best = pixel;
  var best_depth = 0xffffffffu;
  if (accum_in[pixel].w != 0u) {
    best_depth = depth_buffer[pixel * fp.depth_stride + fp.depth_word];
  }
  let r = i32(fp.radius);
  for (var dy = -r; dy <= r; dy++) {
    let span = disc_span(dy, r);
    for (var dx = -span; dx <= span; dx++) {
      let x = i32(id.x) + dx;
      let y = i32(id.y) + dy;
      if (x < 0 || y < 0 || x >= i32(fp.width) || y >= i32(fp.height)) {
        continue;
      }
      let q = u32(y) * fp.width + u32(x);
      if (accum_in[q].w == 0u) {
        continue;
      }
      let d = depth_buffer[q * fp.depth_stride + fp.depth_word];
      if (d < best_depth) {
        best = q;
        best_depth = d;
      }
    }
  }
  accum_out[pixel] = accum_in[best];
  for (var w = 0u; w < fp.depth_stride; w++) {
    depth_out[pixel * fp.depth_stride + w] = depth_buffer[best * fp.depth_stride + w];
  }
}


// The scatter's per-pixel words, cleared to 0 before the first dispatch: [2p] the nearest
// covering depth and [2p + 1] the winner's offset code, each stored complemented so that
// atomicMax keeps the least and 0 stands for none.
@group(0) @binding(5) var<storage, read_write> dilate_winner: array<atomic<u32>>;


// The drawn pixel at `id` (or none), as its depth bits; the caller's work follows from it.
fn dilate_source_depth(id: vec3<u32>) -> u32 {
  if (id.x >= fp.width || id.y >= fp.height) {
    return 0xffffffffu;
  }
  let pixel = id.y * fp.width + id.x;
  if (accum_in[pixel].w == 0u) {
    return 0xffffffffu;
  }
  return depth_buffer[pixel * fp.depth_stride + fp.depth_word];
}

// The pixel that the drawn pixel at `id` covers at the scan offset (dx, dy) of the disc (this
// one less the offset), or -1 where that is outside the image: both scatter passes walk the same
// disc.
fn dilate_covered(id: vec3<u32>, dx: i32, dy: i32) -> i32 {
  let x = i32(id.x) - dx;
  let y = i32(id.y) - dy;
  if (x < 0 || y < 0 || x >= i32(fp.width) || y >= i32(fp.height)) {
    return -1;
  }
  return y * i32(fp.width) + x;
}

@compute @workgroup_size(16, 16)
fn dilate_depth_main(@builtin(global_invocation_id) id: vec3<u32>) {
  let d = dilate_source_depth(id);
  if (d == 0xffffffffu) {
    return;
  }
  let r = i32(fp.radius);
  for (var dy = -r; dy <= r; dy++) {
    let span = disc_span(dy, r);
    for (var dx = -span; dx <= span; dx++) {
      let covered = dilate_covered(id, dx, dy);
      if (covered >= 0) {
        atomicMax(&dilate_winner[2u * u32(covered)], ~d);
      }
    }
  }
}

@compute @workgroup_size(16, 16)
fn dilate_offset_main(@builtin(global_invocation_id) id: vec3<u32>) {
  let d = dilate_source_depth(id);
  if (d == 0xffffffffu) {
    return;
  }
  let r = i32(fp.radius);
  for (var dy = -r; dy <= r; dy++) {
    let span = disc_span(dy, r);
    for (var dx = -span; dx <= span; dx++) {
      let covered = dilate_covered(id, dx, dy);
      if (covered >= 0 && atomicLoad(&dilate_winner[2u * u32(covered)]) == ~d) {
        atomicMax(&dilate_winner[2u * u32(covered) + 1u], ~dilate_offset_code(dx, dy));
      }
    }
  }
}

@compute @workgroup_size(16, 16)
fn dilate_resolve_main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= fp.width || id.y >= fp.height) {
    return;
  }
  let pixel = id.y * fp.width + id.x;
  var source = pixel;  // covered by none: the pixel as it is, as in dilate_main
  if (atomicLoad(&dilate_winner[2u * pixel]) != 0u) {
    let code = ~atomicLoad(&dilate_winner[2u * pixel + 1u]);
    if (code != 0u) {
      let d = dilate_offset_of(code);
      source = u32(i32(id.y) + d.y) * fp.width + u32(i32(id.x) + d.x);
    }
  }
  accum_out[pixel] = accum_in[source];
  for (var w = 0u; w < fp.depth_stride; w++) {
    depth_out[pixel * fp.depth_stride + w] = depth_buffer[source * fp.depth_stride + w];
  }
}
