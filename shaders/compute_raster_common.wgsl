// Shared by the compute rasterizer's passes (seed 001, sections 3.2-3.3): per-segment
// parameters, the batch table, workgroup-wise frustum culling and precision choice, and the
// reconstruction of positions from the coarse/medium/fine words.
#include "sky.wgsl"

struct Params {
  view_proj: mat4x4<f32>,  // rotation-only view times projection (camera-relative)
  width: u32,
  height: u32,
  segment_base: u32,       // global index of this segment's first point
  batch_count: u32,        // batches in this segment
  force_bits: u32,         // 0: from the projected size, else 10, 20 or 30
  min_batch_px: f32,       // LOD: skip batches smaller than this on screen
  depth_tolerance: f32,    // relative: accumulate points up to d0 * (1 + tolerance)
  depth_stride: u32,       // u32 words per pixel in the depth buffer (2: 64-bit visibility)
  depth_word: u32,         // which word holds the depth
  segment_points: u32,    // points in this segment
  edl_strength: f32,       // eye-dome lighting in the display pass; 0: off
  edl_radius: f32,         // its neighbour distance in pixels
  background: vec4<f32>,
  sky: Sky,  // the display pass's background where nothing was drawn, when on (sky.wgsl)
}

// The translucent points' coverage sums (compute_raster_translucent.wgsl): -ln(1 - alpha) in
// units of 1 / REVEAL_SCALE.
const REVEAL_SCALE: f32 = 4096.0;

// Per frame: offset = batch min - camera position (double on the CPU, then float).
struct GpuBatch {
  offset: vec3<f32>,
  count: u32,
  size: vec3<f32>,
  first: u32,  // within the segment
}

// Threads per batch workgroup: the depth passes take the seed's 128, the accumulation pass 256
// (compute_raster.cpp).
override WORKGROUP: u32 = 128u;

// Measurements only (`stipple bench raster`'s no-* variants; wrong images or counters): parts
// of the batch passes left out to see what they cost. 0 in every frame that is shown.
override ABLATE: u32 = 0u;
const ABLATE_ATOMIC: u32 = 1u;  // the 64-bit depth pass without its atomicMin
const ABLATE_WRITE: u32 = 2u;   // the 64-bit depth pass without its early test and atomicMin
const ABLATE_EARLY: u32 = 4u;   // the depth passes without the early test: every point's atomic
const ABLATE_LOAD: u32 = 8u;    // the coarse words made from their index, not loaded
const ABLATE_SUMS: u32 = 16u;   // the accumulation's sums made but not added
const ABLATE_COUNT: u32 = 32u;  // the batch counters' atomics left out

fn ablated(part: u32) -> bool {
  return (ABLATE & part) != 0u;
}

const C_PROCESSED: u32 = 0u;
const C_RENDERED: u32 = 1u;
const C_CULLED: u32 = 2u;
const C_LOD_SKIPPED: u32 = 3u;
const C_POINTS: u32 = 4u;
const C_BATCHES_BITS: u32 = 5u;  // 3 entries: 10, 20, 30 bits
const C_POINTS_BITS: u32 = 8u;   // 3 entries
const C_EVENTS: u32 = 11u;       // the fallback's winner events (compute_raster_events.wgsl)
const C_EVENTS_OVERFLOW: u32 = 12u;

// 0 when culled or skipped, else the precision in bits; `skipped` is set for LOD skips.
fn classify(p: Params, b: GpuBatch, skipped: ptr<function, bool>) -> u32 {
  var out_l = true;
  var out_r = true;
  var out_b = true;
  var out_t = true;
  var out_n = true;
  var behind = false;
  var lo = vec2<f32>(1e30);
  var hi = vec2<f32>(-1e30);
  let viewport = vec2<f32>(f32(p.width), f32(p.height));
  for (var i = 0u; i < 8u; i++) {
    let corner = b.offset + b.size * vec3<f32>(f32(i & 1u), f32((i >> 1u) & 1u), f32((i >> 2u) & 1u));
    let c = p.view_proj * vec4<f32>(corner, 1.0);
    out_l = out_l && c.x < -c.w;
    out_r = out_r && c.x > c.w;
    out_b = out_b && c.y < -c.w;
    out_t = out_t && c.y > c.w;
    out_n = out_n && c.z > c.w;
    if (c.z > c.w || c.w <= 0.0) {
      behind = true;
    } else {
      let s = vec2<f32>(c.x / c.w * 0.5 + 0.5, 0.5 - c.y / c.w * 0.5) * viewport;
      lo = min(lo, s);
      hi = max(hi, s);
    }
  }
  *skipped = false;
  if (out_l || out_r || out_b || out_t || out_n) {
    return 0u;
  }
  var size_px = max(hi.x - lo.x, hi.y - lo.y);
  if (behind) {
    size_px = 3.0e38;
  }
  if (size_px < p.min_batch_px) {
    *skipped = true;
    return 0u;
  }
  if (p.force_bits != 0u) {
    return p.force_bits;
  }
  if (size_px < 500.0) {
    return 10u;
  }
  if (size_px < 500000.0) {
    return 20u;
  }
  return 30u;
}

fn unpack10(v: u32) -> vec3<f32> {
  return vec3<f32>(f32(v & 1023u), f32((v >> 10u) & 1023u), f32((v >> 20u) & 1023u));
}

// The point's position in the batch box as a fraction, at the cell centre of `bits` bits.
fn box_fraction(bits: u32, c: u32, m: u32, f: u32) -> vec3<f32> {
  var q = unpack10(c) * (1.0 / 1024.0);
  if (bits == 10u) {
    return q + 0.5 / 1024.0;
  }
  q += unpack10(m) * (1.0 / 1048576.0);
  if (bits == 20u) {
    return q + 0.5 / 1048576.0;
  }
  return q + unpack10(f) * (1.0 / 1073741824.0);
}

struct Projected {
  pixel: u32,
  xy: vec2<u32>,  // the pixel's column and row
  depth: f32,  // linear view depth (clip w)
  valid: bool,
}

// A batch's points go to the screen through one matrix (seed 001, section 3.3, with the box and
// the viewport folded in): the viewport transform times view_proj times the batch's box, taking
// a point in units of its 10-bit cells (centred at the batch's precision). A point then costs
// 12 multiply-adds and one reciprocal, not a box transform, a matrix and two divisions.
fn batch_screen_matrix(p: Params, b: GpuBatch, bits: u32) -> mat4x4<f32> {
  let cell = b.size * (1.0 / 1024.0);
  var half = 0.0;
  if (bits == 10u) {
    half = 0.5;
  } else if (bits == 20u) {
    half = 0.5 / 1024.0;
  }
  let box = mat4x4<f32>(vec4<f32>(cell.x, 0.0, 0.0, 0.0), vec4<f32>(0.0, cell.y, 0.0, 0.0),
                        vec4<f32>(0.0, 0.0, cell.z, 0.0), vec4<f32>(b.offset + half * cell, 1.0));
  let w = f32(p.width) * 0.5;
  let h = f32(p.height) * 0.5;
  let viewport = mat4x4<f32>(vec4<f32>(w, 0.0, 0.0, 0.0), vec4<f32>(0.0, -h, 0.0, 0.0),
                             vec4<f32>(0.0, 0.0, 1.0, 0.0), vec4<f32>(w, h, 0.0, 1.0));
  return viewport * p.view_proj * box;
}

// A point's position in 10-bit cells of its batch box, from the words its precision reads.
fn cell_position(bits: u32, c: u32, m: u32, f: u32) -> vec3<f32> {
  var q = unpack10(c);
  if (bits >= 20u) {
    q += unpack10(m) * (1.0 / 1024.0);
  }
  if (bits >= 30u) {
    q += unpack10(f) * (1.0 / 1048576.0);
  }
  return q;
}

// `q` (cell units) through the batch's screen matrix `m`: its pixel and linear depth.
fn project_cell(p: Params, m: mat4x4<f32>, q: vec3<f32>) -> Projected {
  var r: Projected;
  r.valid = false;
  let c = m[3] + m[0] * q.x + m[1] * q.y + m[2] * q.z;
  // Behind the near plane (reverse Z: z > w) or outside the viewport.
  if (c.w <= 0.0 || c.z > c.w) {
    return r;
  }
  let s = c.xy * (1.0 / c.w);
  if (s.x < 0.0 || s.y < 0.0 || s.x >= f32(p.width) || s.y >= f32(p.height)) {
    return r;
  }
  r.xy = vec2<u32>(s);
  r.pixel = r.xy.y * p.width + r.xy.x;
  r.depth = c.w;
  r.valid = true;
  return r;
}
