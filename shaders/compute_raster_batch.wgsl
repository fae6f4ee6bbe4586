// What the compute rasterizer's batch passes share (seed 001, sections 3.2-3.4): the frame's
// parameters, the batches and the split positions (bindings 0-4), the prologue that classifies
// a workgroup's batch, and the loops over a batch's points. One workgroup draws one batch; its
// threads take the batch's aligned 16-byte words in a stride, each loading four points with one
// 128-bit load per precision word it needs (the coarse word for 10 bits, also the medium one for
// 20, the fine one for 30: seed 001, section 3.3).
//
// The including shader defines draw_point(cells, index) (the point in cells of its batch box,
// which project_point() takes to its pixel), end_run() (called after a thread's last point) and
// count_batch(...). Its 10-bit batches without filters take a lean loop of its own (lean_batch
// in compute_raster_write.wgsl, lean_sums_batch in compute_raster_accumulate.wgsl), built from
// lean_project() and lean_partial_word() below.
#include "compute_raster_common.wgsl"

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> batches: array<GpuBatch>;
// Four points' words per element (the arrays are padded to 16 bytes).
@group(0) @binding(2) var<storage, read> coarse: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read> medium: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read> fine: array<vec4<u32>>;

// LEAN: whether the pass takes the lean loop for 10-bit batches without filters (the depth
// passes always; the accumulation for the fallback's colours, not for HQS's sums), for which the
// prologue also finds whether the batch lies inside the view.
override LEAN: bool = true;

// SPLIT: which points the pass draws by the coarse word's translucent bit (bit 30, set only in
// clouds that have translucent points: BatchingOptions::mark_translucent). 0: every point (the
// default pipelines: the test folds away), 1: the opaque ones (the batch passes of a frame that
// blends the translucent points), 2: the translucent ones (raster-translucent).
override SPLIT: u32 = 0u;
const TRANSLUCENT_BIT: u32 = 0x40000000u;

// Whether the pass draws the point of coarse word `c`.
fn selected(c: u32) -> bool {
  if (SPLIT == 0u) {
    return true;
  }
  return ((c & TRANSLUCENT_BIT) != 0u) == (SPLIT == 2u);
}

fn coarse_word(v: u32) -> vec4<u32> {
  if (ablated(ABLATE_LOAD)) {
    let h = v * 2654435761u;
    return vec4<u32>(h, h ^ 0x5bd1e995u, h * 3u, h * 5u) & vec4<u32>(0x3fffffffu);
  }
  return coarse[v];
}

var<workgroup> batch_bits: u32;  // precision; BATCH_INSIDE added where box_inside holds
var<workgroup> batch_matrix: mat4x4<f32>;
const BATCH_INSIDE: u32 = 256u;
var<private> batch_inside: bool = false;
// The workgroup's batch_screen_matrix(), each thread's copy (set by batch_prologue), and the
// batch's box in cells (set by draw_batch_points) for point_position().
var<private> to_screen: mat4x4<f32>;
var<private> cells_origin: vec3<f32>;
var<private> cell_size: vec3<f32>;

// Batches are dispatched as rows of workgroups (more than one dimension's limit of batches).
fn batch_index(group: vec3<u32>, groups: vec3<u32>) -> u32 {
  return group.y * groups.x + group.x;
}

// PROLOGUE_PER_THREAD: every thread classifies the batch itself, and the pass has no barrier
// and no workgroup memory. For CPU adapters (SwiftShader, lavapipe), where a workgroup with a
// barrier runs each group of lanes as a coroutine: on SwiftShader the depth pass and HQS 1.5x
// faster so (bench/RESULTS.md, "The page on SwiftShader"). The same result either way.
override PROLOGUE_PER_THREAD: bool = false;

// How every batch pass starts: thread 0 classifies the workgroup's batch (frustum, LOD,
// precision), makes its screen matrix and reports it to count_batch(), which the including
// shader defines (counters, or nothing); then every thread gets the precision in bits, 0 when
// the batch is culled or skipped (or past the last batch). Call it from uniform control flow.
fn batch_prologue(group: u32, lid: u32) -> u32 {
  if (group >= params.batch_count) {
    return 0u;
  }
  if (PROLOGUE_PER_THREAD) {
    let b = batches[group];
    var skipped = false;
    let bits = classify(params, b, &skipped);
    let m = batch_screen_matrix(params, b, bits);
    to_screen = m;
    if (lid == 0u) {
      count_batch(b, bits, skipped);
    }
    batch_inside = LEAN && bits != 0u && box_inside(m);
    return bits;
  }
  if (lid == 0u) {
    let b = batches[group];
    var skipped = false;
    let bits = classify(params, b, &skipped);
    let m = batch_screen_matrix(params, b, bits);
    batch_matrix = m;
    batch_bits = bits;
    if (LEAN && bits != 0u && box_inside(m)) {
      batch_bits = bits | BATCH_INSIDE;
    }
    count_batch(b, bits, skipped);
  }
  // The uniform load is also the barrier after which the matrix is visible.
  let word = workgroupUniformLoad(&batch_bits);
  to_screen = batch_matrix;
  batch_inside = (word & BATCH_INSIDE) != 0u;
  return word & (BATCH_INSIDE - 1u);
}

// Whether every point of the batch (cells -1..1025 of its screen matrix `m`: the box with a
// cell to spare) projects in front of the near plane and at least a pixel inside the viewport.
// A projective map keeps the points between its corners when all lie in front of the eye.
fn box_inside(m: mat4x4<f32>) -> bool {
  for (var i = 0u; i < 8u; i++) {
    let q = vec3<f32>(f32(i & 1u), f32((i >> 1u) & 1u), f32((i >> 2u) & 1u)) * 1026.0 - 1.0;
    let c = m[3] + m[0] * q.x + m[1] * q.y + m[2] * q.z;
    if (c.w <= 0.0 || c.z > c.w * 0.999) {
      return false;
    }
    let s = c.xy / c.w;
    if (s.x < 1.0 || s.y < 1.0 || s.x > f32(params.width) - 2.0 ||
        s.y > f32(params.height) - 2.0) {
      return false;
    }
  }
  return true;
}

var<private> lean_size: vec2<f32>;

struct LeanProjected {
  pixel: u32,
  xy: vec2<u32>,  // the pixel's column and row (the accumulation's tile)
  depth: f32,
  valid: bool,
}

// One 10-bit point of the lean loops to its pixel, as project_point takes it: `inside` is a
// literal at every call, so each loop keeps only its own tests (none in a batch inside the view).
fn lean_project(v: u32, inside: bool) -> LeanProjected {
  var r: LeanProjected;
  r.valid = false;
  let q = unpack10(v);
  let m = to_screen;
  let c = m[3] + m[0] * q.x + m[1] * q.y + m[2] * q.z;
  if (!inside && (c.w <= 0.0 || c.z > c.w)) {
    return r;
  }
  let s = c.xy * (1.0 / c.w);
  if (!inside && (s.x < 0.0 || s.y < 0.0 || s.x >= lean_size.x || s.y >= lean_size.y)) {
    return r;
  }
  let xy = vec2<u32>(s);
  r.pixel = xy.y * params.width + xy.x;
  r.xy = xy;
  r.depth = c.w;
  r.valid = true;
  return r;
}

// The lean loops draw the 16-byte words wholly inside a batch's points [lo, end) without range
// tests; its partial first and last words (at most two) go to threads 0 and 1: the word this
// thread draws after the loop, or 0xffffffff for none.
fn lean_partial_word(lo: u32, end: u32, lid: u32) -> u32 {
  if (lid == 0u && (lo & 3u) != 0u) {
    return lo / 4u;
  }
  if (lid == 1u && (end & 3u) != 0u && (end / 4u != lo / 4u || (lo & 3u) == 0u)) {
    return end / 4u;
  }
  return 0xffffffffu;
}

// draw_point's projection: `q` (cells of the workgroup's batch) to its pixel and depth.
fn project_point(q: vec3<f32>) -> Projected {
  return project_cell(params, to_screen, q);
}

// `q` (cells of the workgroup's batch) relative to the camera, for shading by elevation.
fn point_position(q: vec3<f32>) -> vec3<f32> {
  return cells_origin + q * cell_size;
}

// The four points of one 16-byte word (points first..first+3) that lie in [lo, end) and that the
// pass draws (SPLIT): written
// out, not a loop over an array of the four positions, which the compiler may keep in local
// memory (2-3.6x slower on the H200: bench/RESULTS.md, runs C-F and K).
fn draw_word(bits: u32, c: vec4<u32>, m: vec4<u32>, f: vec4<u32>, first: u32, lo: u32, end: u32) {
  if (first >= lo && first < end && selected(c.x)) {
    draw_point(cell_position(bits, c.x, m.x, f.x), first);
  }
  if (first + 1u >= lo && first + 1u < end && selected(c.y)) {
    draw_point(cell_position(bits, c.y, m.y, f.y), first + 1u);
  }
  if (first + 2u >= lo && first + 2u < end && selected(c.z)) {
    draw_point(cell_position(bits, c.z, m.z, f.z), first + 2u);
  }
  if (first + 3u < end && selected(c.w)) {
    draw_point(cell_position(bits, c.w, m.w, f.w), first + 3u);
  }
}

// The general loop: calls draw_point for every point of batch `b` this thread handles, at any
// precision and with filters.
fn draw_batch_points(b: GpuBatch, bits: u32, lid: u32) {
  cell_size = b.size * (1.0 / 1024.0);
  cells_origin = b.offset;
  if (bits == 10u) {
    cells_origin += 0.5 * cell_size;
  } else if (bits == 20u) {
    cells_origin += (0.5 / 1024.0) * cell_size;
  }
  // The aligned 16-byte words that cover the batch (the first and last may hold other
  // batches' points: skipped).
  let end = b.first + b.count;
  let first_word = b.first / 4u;
  let stop = (end + 3u) / 4u;
  for (var v = first_word + lid; v < stop; v += WORKGROUP) {
    let c = coarse_word(v);
    var m = vec4<u32>(0u);
    var f = vec4<u32>(0u);
    if (bits >= 20u) {
      m = medium[v];
    }
    if (bits >= 30u) {
      f = fine[v];
    }
    draw_word(bits, c, m, f, v * 4u, b.first, end);
  }
  end_run();
}
