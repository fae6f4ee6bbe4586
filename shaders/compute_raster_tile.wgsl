// TILE: a batch that covers few pixels is first rasterized into workgroup memory, then written
// to the screen once per covered pixel. At overview distances hundreds of a batch's points fall
// on each of its pixels; without the tile every one of them reads (and some write) the screen
// buffer in global memory, which bounds the geometry pass by those accesses, not by the 4 bytes
// a point it loads. Included by the batch passes after compute_raster_batch.wgsl; they call
// tile_begin(), draw the batch once per phase and flush the tile. Geometry: phase 1 keeps the
// nearest depth per tile pixel, phase 2 (64-bit pass only) the smallest index at that depth, the
// global key order. Accumulation: phase 1 sums colours against the tile's depth limits. Points
// that round outside the tile take the global path (in phase 1).
override TILE: bool = false;

const TILE_PIXELS: u32 = 512u;
var<workgroup> tile_depth: array<atomic<u32>, TILE_PIXELS>;
var<workgroup> tile_rect: vec4<u32>;  // x0, y0, width, height; width 0: the batch is too large
var<private> tile_phase: u32 = 0u;    // 0: global writes
var<private> tile_origin: vec2<u32>;
var<private> tile_size: vec2<u32>;

// The batch's box corners on screen (as classify() projects them) widened by a pixel for
// rounding, clamped to the viewport; width 0 where it is behind the camera or too large.
fn tile_rect_of(b: GpuBatch) -> vec4<u32> {
  var lo = vec2<f32>(1e30);
  var hi = vec2<f32>(-1e30);
  let viewport = vec2<f32>(f32(params.width), f32(params.height));
  for (var i = 0u; i < 8u; i++) {
    let corner = b.offset + b.size * vec3<f32>(f32(i & 1u), f32((i >> 1u) & 1u), f32((i >> 2u) & 1u));
    let c = params.view_proj * vec4<f32>(corner, 1.0);
    if (c.w <= 0.0) {
      return vec4<u32>(0u);
    }
    let s = vec2<f32>(c.x / c.w * 0.5 + 0.5, 0.5 - c.y / c.w * 0.5) * viewport;
    lo = min(lo, s);
    hi = max(hi, s);
  }
  lo = clamp(floor(lo) - 1.0, vec2<f32>(0.0), viewport - 1.0);
  hi = clamp(floor(hi) + 1.0, vec2<f32>(0.0), viewport - 1.0);
  let size = vec2<u32>(hi - lo) + 1u;
  if (size.x * size.y > TILE_PIXELS || hi.x < lo.x || hi.y < lo.y) {
    return vec4<u32>(0u);
  }
  return vec4<u32>(vec2<u32>(lo), size);
}

// Whether the workgroup draws batch `b` through the tile; clears it. Uniform control flow.
fn tile_begin(b: GpuBatch, lid: u32) -> bool {
  if (lid == 0u) {
    tile_rect = tile_rect_of(b);
  }
  let r = workgroupUniformLoad(&tile_rect);
  if (r.z == 0u) {
    return false;
  }
  tile_origin = r.xy;
  tile_size = r.zw;
  for (var i = lid; i < r.z * r.w; i += WORKGROUP) {
    atomicStore(&tile_depth[i], 0xffffffffu);
    tile_clear_extra(i);
  }
  workgroupBarrier();
  return true;
}

// The tile entry of the pixel at column and row `xy`, or TILE_PIXELS outside the tile.
fn tile_entry_xy(xy: vec2<u32>) -> u32 {
  let d = xy - tile_origin;  // wraps past the size when left of or above the tile
  if (d.x >= tile_size.x || d.y >= tile_size.y) {
    return TILE_PIXELS;
  }
  return d.y * tile_size.x + d.x;
}

// The tile entry of screen pixel `pixel`. Without MERGE the pixel is the last projected
// point's (point_xy), which saves the division.
fn tile_entry(pixel: u32) -> u32 {
  if (MERGE) {
    return tile_entry_xy(vec2<u32>(pixel % params.width, pixel / params.width));
  }
  return tile_entry_xy(point_xy);
}

// Screen pixel of tile entry `i`.
fn tile_pixel(i: u32) -> u32 {
  let y = i / tile_size.x;
  return (tile_origin.y + y) * params.width + tile_origin.x + (i - y * tile_size.x);
}
