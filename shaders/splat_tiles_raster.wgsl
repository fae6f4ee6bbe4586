// The tile rasterizer's blending pass (see splat_tiles.wgsl): one 16x16 workgroup per tile, one
// invocation per pixel; the tile's splats front to back, 256 at a time through workgroup memory;
// (colour, 1 - transmittance) per pixel into `out`.
#include "splat_common.wgsl"

struct TileParams {
  tiles_x: u32,
  tiles_y: u32,
  capacity: u32,
  pair_capacity: u32,
  blocks: u32,
  has_depth: u32,
  pad0: u32,
  pad1: u32,
}

@group(0) @binding(0) var<uniform> frame: SplatFrame;
@group(0) @binding(1) var<uniform> params: TileParams;
@group(0) @binding(2) var<storage, read> projected: array<Projected>;
@group(0) @binding(3) var<storage, read> sorted_keys: array<u32>;
@group(0) @binding(4) var<storage, read> sorted_values: array<u32>;
@group(0) @binding(5) var<storage, read> pair_values: array<u32>;  // ranks, sorted by tile
@group(0) @binding(6) var<storage, read> tile_data: array<u32>;
@group(0) @binding(7) var<storage, read_write> out: array<vec4<f32>>;
@group(0) @binding(8) var point_depth: texture_depth_2d;

// A batch's splats in the order the pixel loop reads them: the box test's words first (centre,
// radius and depth in one 16-byte read, as most of a tile's splats miss a given pixel), then
// the shape, then the colour.
var<workgroup> batch_box: array<vec4<f32>, 256>;    // centre x, y; radius; depth (reverse Z)
var<workgroup> batch_shape: array<vec4<f32>, 256>;  // conic a, b, c; opacity
var<workgroup> batch_color: array<vec3<f32>, 256>;
var<workgroup> done_count: atomic<u32>;
var<workgroup> all_done: u32;

@compute @workgroup_size(16, 16)
fn cs_raster(@builtin(workgroup_id) wid: vec3<u32>,
             @builtin(local_invocation_id) local: vec3<u32>,
             @builtin(local_invocation_index) lid: u32) {
  let tile = wid.x + wid.y * params.tiles_x;
  let pixel = wid.xy * 16u + local.xy;
  let size = vec2<u32>(frame.viewport);
  let inside = pixel.x < size.x && pixel.y < size.y;
  let start = tile_data[1u + 2u * tile];
  let end = tile_data[2u + 2u * tile];
  var behind = 0.0;
  if (params.has_depth == 1u && inside) {
    behind = textureLoad(point_depth, vec2<i32>(pixel), 0);
  }
  if (lid == 0u) {
    atomicStore(&done_count, 0u);
  }
  workgroupBarrier();
  var done = !inside;
  if (done) {
    atomicAdd(&done_count, 1u);
  }
  let pf = vec2<f32>(pixel) + 0.5;
  var t = 1.0;
  var c = vec3<f32>(0.0);
  var top = end;
  loop {
    if (top <= start) {
      break;
    }
    let n = min(256u, top - start);
    workgroupBarrier();
    if (lid < n) {
      let rank = pair_values[top - 1u - lid];
      let p = projected[sorted_values[rank]];
      let ba = unpack2x16float(p.color_b_opacity);
      batch_box[lid] = vec4<f32>(p.centre, p.radius, frame.near / key_depth(sorted_keys[rank]));
      batch_shape[lid] = vec4<f32>(p.conic_xy, p.conic_z, ba.y);
      batch_color[lid] = vec3<f32>(unpack2x16float(p.color_rg), ba.x);
    }
    workgroupBarrier();
    if (!done) {
      for (var k = 0u; k < n; k = k + 1u) {
        let box = batch_box[k];
        let d = box.xy - pf;
        // Reverse Z: a splat behind the points' depth is hidden.
        if (abs(d.x) > box.z || abs(d.y) > box.z || box.w <= behind) {
          continue;
        }
        let s = batch_shape[k];
        let power = -0.5 * (s.x * d.x * d.x + s.z * d.y * d.y) - s.y * d.x * d.y;
        if (power > 0.0) {
          continue;
        }
        let alpha = min(0.99, s.w * exp(power));
        if (alpha < MIN_ALPHA) {
          continue;
        }
        let next = t * (1.0 - alpha);
        if (next < 1e-4) {
          done = true;
          break;
        }
        c = c + batch_color[k] * alpha * t;
        t = next;
      }
      if (done) {
        atomicAdd(&done_count, 1u);
      }
    }
    top = top - n;
    workgroupBarrier();
    if (lid == 0u) {
      all_done = atomicLoad(&done_count);
    }
    if (workgroupUniformLoad(&all_done) == 256u) {
      break;
    }
  }
  if (inside) {
    out[pixel.y * size.x + pixel.x] = vec4<f32>(c, 1.0 - t);
  }
}
