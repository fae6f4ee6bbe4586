// What the compute rasterizer's geometry passes share: the frame's parameters, the batches and
// the split positions (bindings 0-4), the batch's precision for the workgroup, and the loop over
// a batch's points at that precision (seed 001, section 3.3: only the needed words are read).
// The including shader defines draw_point(cells, index) (the point in cells of its batch box,
// which project_point() takes to its pixel), end_run() (called after a thread's last point: see
// compute_raster_write.wgsl) and count_batch(...).
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
// With PREFETCH: 16-byte words a thread loads per iteration (1 or 2).
override PREFETCH_WORDS: u32 = 1u;
// A measurement only (wrong images): the coarse words are made from their index, not loaded,
// which tells the loads' share of the loop from the projection's.
override ABLATE_LOAD: bool = false;

// FAST_CONVERT (compute_raster_common.wgsl) also takes the pixel out of the float's bits
// (project_point). UNCLIPPED: a batch whose box lies inside the viewport and in front of the
// near plane, with a pixel to spare, skips the per-point clipping tests.
override UNCLIPPED: bool = false;

fn coarse_word(v: u32) -> vec4<u32> {
  if (ABLATE_LOAD) {
    let h = v * 2654435761u;
    return vec4<u32>(h, h ^ 0x5bd1e995u, h * 3u, h * 5u) & vec4<u32>(0x3fffffffu);
  }
  return coarse[v];
}


var<workgroup> batch_bits: u32;  // precision; BATCH_INSIDE added where UNCLIPPED holds
var<workgroup> batch_matrix: mat4x4<f32>;
const BATCH_INSIDE: u32 = 256u;
var<private> batch_inside: bool = false;
// The workgroup's batch_screen_matrix(), each thread's copy (set by batch_prologue), and the
// batch's box in cells (set by draw_batch_points) for point_position().
var<private> to_screen: mat4x4<f32>;
var<private> cells_origin: vec3<f32>;
var<private> cell_size: vec3<f32>;
// The column and row of the last point project_point() took to a pixel.
var<private> point_xy: vec2<u32>;

// Batches are dispatched as rows of workgroups (more than one dimension's limit of batches).
fn batch_index(group: vec3<u32>, groups: vec3<u32>) -> u32 {
  return group.y * groups.x + group.x;
}

// The batch's screen matrix as the passes use it.
fn prologue_matrix(b: GpuBatch, bits: u32) -> mat4x4<f32> {
  var m = batch_screen_matrix(params, b, bits);
  if (FAST_CONVERT) {
    // Half a pixel less in x and y: rounding to the nearest then gives the floor.
    for (var j = 0u; j < 4u; j++) {
      m[j].x -= 0.5 * m[j].w;
      m[j].y -= 0.5 * m[j].w;
    }
  }
  return m;
}

// PARALLEL_PROLOGUE: see batch_prologue. BATCHES_PER_GROUP (the depth passes without TILE; needs
// PARALLEL_PROLOGUE): each workgroup draws that many batches, a grid stride apart, so that
// fewer workgroups start and end.
override PARALLEL_PROLOGUE: bool = false;
override BATCHES_PER_GROUP: u32 = 1u;
// LEAN: the lean loops for 10-bit batches (the depth passes': compute_raster_write.wgsl; the
// accumulation's: compute_raster_accumulate.wgsl), for which the prologue also finds whether
// the batch lies inside the view.
override LEAN: bool = true;

// How every geometry pass starts: thread 0 classifies the workgroup's batch (frustum, LOD,
// precision) and reports it to count_batch(), which the including shader defines (counters, or
// nothing); then every thread gets the precision in bits, 0 when the batch is culled or skipped
// (or past the last batch). Call it from uniform control flow.
fn batch_prologue(group: u32, lid: u32) -> u32 {
  if (group >= params.batch_count) {
    return 0u;
  }
  if (PARALLEL_PROLOGUE) {
    // Every thread classifies the batch and makes its matrix (the same values from the same
    // uniform data): no thread waits on thread 0's serial work, and no barrier.
    let b = batches[group];
    var skipped = false;
    let bits = classify(params, b, &skipped);
    if (lid == 0u) {
      count_batch(b, bits, skipped);
    }
    if (bits == 0u) {
      return 0u;
    }
    to_screen = prologue_matrix(b, bits);
    batch_inside = (UNCLIPPED || LEAN) && box_inside(to_screen);
    return bits;
  }
  if (lid == 0u) {
    let b = batches[group];
    var skipped = false;
    let bits = classify(params, b, &skipped);
    let m = prologue_matrix(b, bits);
    batch_matrix = m;
    batch_bits = bits;
    if ((UNCLIPPED || LEAN) && bits != 0u && box_inside(m)) {
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

// One 10-bit point of the lean loops (compute_raster_write.wgsl, compute_raster_accumulate.wgsl)
// to its pixel, as project_point takes it: `inside` is a literal at every call, so each loop
// keeps only its own tests.
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
  var xy: vec2<u32>;
  if (FAST_CONVERT) {
    xy = bitcast<vec2<u32>>(s + 12582912.0) - vec2<u32>(0x4b400000u);
    if (!inside && (xy.x >= params.width || xy.y >= params.height)) {
      return r;
    }
  } else {
    if (!inside && (s.x < 0.0 || s.y < 0.0 || s.x >= lean_size.x || s.y >= lean_size.y)) {
      return r;
    }
    xy = vec2<u32>(s);
  }
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

// Point `index` of a batch in cells of its box (cell_position), from 10, 20 or 30 bits per axis.
fn load_cells(bits: u32, index: u32) -> vec3<f32> {
  let v = index >> 2u;
  let k = index & 3u;
  let c = coarse_word(v)[k];
  var m = 0u;
  var f = 0u;
  if (bits >= 20u) {
    m = medium[v][k];
  }
  if (bits >= 30u) {
    f = fine[v][k];
  }
  return cell_position(bits, c, m, f);
}

// draw_point's projection: `q` (cells of the workgroup's batch) to its pixel and depth.
fn project_point(q: vec3<f32>) -> Projected {
  if (!FAST_CONVERT && !UNCLIPPED) {
    let r = project_cell(params, to_screen, q);
    point_xy = r.xy;
    return r;
  }
  var r: Projected;
  r.valid = false;
  let m = to_screen;
  let c = m[3] + m[0] * q.x + m[1] * q.y + m[2] * q.z;
  let clip = !(UNCLIPPED && batch_inside);
  if (clip && (c.w <= 0.0 || c.z > c.w)) {
    return r;
  }
  let s = c.xy * (1.0 / c.w);
  if (FAST_CONVERT) {
    // s is half a pixel less than the pixel position (batch_prologue). Added to 1.5 * 2^23 it
    // lies in [2^23, 2^24) where floats are the integers: the sum is rounded to the nearest,
    // which is in its low bits. Left of or above the screen it comes out negative, so huge.
    r.xy = bitcast<vec2<u32>>(s + 12582912.0) - vec2<u32>(0x4b400000u);
    if (clip && (r.xy.x >= params.width || r.xy.y >= params.height)) {
      return r;
    }
  } else {
    if (clip && (s.x < 0.0 || s.y < 0.0 || s.x >= f32(params.width) ||
                 s.y >= f32(params.height))) {
      return r;
    }
    r.xy = vec2<u32>(s);
  }
  r.pixel = r.xy.y * params.width + r.xy.x;
  r.depth = c.w;
  r.valid = true;
  point_xy = r.xy;
  return r;
}

// `q` (cells of the workgroup's batch) relative to the camera, for shading by elevation.
fn point_position(q: vec3<f32>) -> vec3<f32> {
  return cells_origin + q * cell_size;
}

// The four points of one 16-byte word (points first..first+3) that lie in [lo, end): written
// out, not a loop over an array of the four positions: an array indexed in a loop may be kept
// in local memory, the suspect of the 2-3.6x slower prefetch runs on the H200.
fn draw_word(bits: u32, c: vec4<u32>, m: vec4<u32>, f: vec4<u32>, first: u32, lo: u32, end: u32) {
  if (first >= lo && first < end) {
    draw_point(cell_position(bits, c.x, m.x, f.x), first);
  }
  if (first + 1u >= lo && first + 1u < end) {
    draw_point(cell_position(bits, c.y, m.y, f.y), first + 1u);
  }
  if (first + 2u >= lo && first + 2u < end) {
    draw_point(cell_position(bits, c.z, m.z, f.z), first + 2u);
  }
  if (first + 3u < end) {
    draw_point(cell_position(bits, c.w, m.w, f.w), first + 3u);
  }
}

// Calls draw_point for every point of batch `b` this thread handles.
fn draw_batch_points(b: GpuBatch, bits: u32, lid: u32) {
  cell_size = b.size * (1.0 / 1024.0);
  cells_origin = b.offset;
  if (bits == 10u) {
    cells_origin += 0.5 * cell_size;
  } else if (bits == 20u) {
    cells_origin += (0.5 / 1024.0) * cell_size;
  }
  if (!PREFETCH) {
    for (var i = lid; i < b.count; i += WORKGROUP) {
      let index = b.first + i;
      draw_point(load_cells(bits, index), index);
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
  // PREFETCH_WORDS 2: the next word's loads are issued before the first word's points are
  // drawn, two 128-bit loads in flight a thread.
  for (; v < stop; v += step * PREFETCH_WORDS) {
    let c = coarse_word(v);
    var m = vec4<u32>(0u);
    var f = vec4<u32>(0u);
    if (bits >= 20u) {
      m = medium[v];
    }
    if (bits >= 30u) {
      f = fine[v];
    }
    let v2 = v + step;
    let second = PREFETCH_WORDS > 1u && v2 < stop;
    var c2 = vec4<u32>(0u);
    var m2 = vec4<u32>(0u);
    var f2 = vec4<u32>(0u);
    if (second) {
      c2 = coarse_word(v2);
      if (bits >= 20u) {
        m2 = medium[v2];
      }
      if (bits >= 30u) {
        f2 = fine[v2];
      }
    }
    draw_word(bits, c, m, f, v * 4u, b.first, end);
    if (second) {
      draw_word(bits, c2, m2, f2, v2 * 4u, b.first, end);
    }
  }
  end_run();
}
