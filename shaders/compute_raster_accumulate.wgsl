// Colour accumulation (seed 003 section 4.3; high-quality shading, seed 001 section 3.6): every
// point within a relative depth tolerance of the pixel's nearest depth adds its colour (shaded
// in the frame's mode) and a count; the display pass divides. The depth comes from the 32-bit
// depth buffer or from the high word of the 64-bit visibility buffer (depth_stride /
// depth_word). Two pipelines of this shader run: HQS's sums (TILE on, the general loop) and the
// 32-bit fallback's colours, the nearest points only (TILE off, the lean loop for 10-bit
// batches: LEAN, compute_raster_batch.wgsl).
//
// A thread sums the points it finds in a row on one pixel (a run: at overview distances hundreds
// of a batch's points share a pixel, and consecutive points of a sorted batch mostly do), reads
// the pixel's depth limit once for them, and adds the run's sums with one set of four atomics
// (3.5x faster HQS than atomics a point on the H200: bench/RESULTS.md, run A).
#include "compute_raster_batch.wgsl"
#include "compute_raster_shading.wgsl"
#include "compute_raster_filter.wgsl"

@group(0) @binding(5) var<storage, read> colors: array<u32>;
@group(0) @binding(6) var<storage, read> depth_buffer: array<u32>;
// Four words a pixel: r, g, b, count.
@group(0) @binding(7) var<storage, read_write> accum: array<atomic<u32>>;

// The geometry passes count batches; accumulation does not.
fn count_batch(b: GpuBatch, bits: u32, skipped: bool) {}

const NO_PIXEL: u32 = 0xffffffffu;
var<private> run_pixel: u32 = NO_PIXEL;
var<private> run_limit: f32;        // the pixel's nearest depth, widened by the tolerance
var<private> run_sum: vec4<u32>;    // r, g, b, count
var<private> run_entry: u32;        // its tile entry (TILE_PIXELS: none)

// TILE: a batch that covers at most TILE_PIXELS pixels on screen sums into workgroup memory
// first (each tile pixel's depth limit, then its sums), and the tile is added to the screen once
// per covered pixel when the batch is done: at overview distances the screen-wide atomics of
// hundreds of runs a pixel are what bound HQS (1.8x faster there on the H200, 4 % slower close
// up: bench/RESULTS.md, runs G-H). Points that round outside the tile take the screen's sums.
override TILE: bool = false;

const TILE_PIXELS: u32 = 512u;
var<workgroup> tile_depth: array<atomic<u32>, TILE_PIXELS>;  // depth limits, as bits
var<workgroup> tile_sums: array<array<atomic<u32>, 4>, TILE_PIXELS>;
var<workgroup> tile_rect: vec4<u32>;  // x0, y0, width, height; width 0: the batch is too large
var<private> tile_phase: u32 = 0u;    // 1 while the batch sums into the tile
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

// Whether the workgroup sums batch `b` through the tile; fills the tile's depth limits from the
// screen's and clears its sums. Uniform control flow.
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
    atomicStore(&tile_depth[i], bitcast<u32>(limit_of(tile_pixel(i))));
    for (var c = 0u; c < 4u; c++) {
      atomicStore(&tile_sums[i][c], 0u);
    }
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

// Screen pixel of tile entry `i`.
fn tile_pixel(i: u32) -> u32 {
  let y = i / tile_size.x;
  return (tile_origin.y + y) * params.width + tile_origin.x + (i - y * tile_size.x);
}

fn add_sums(pixel: u32, sum: vec4<u32>) {
  let o = pixel * 4u;
  atomicAdd(&accum[o], sum.x);
  atomicAdd(&accum[o + 1u], sum.y);
  atomicAdd(&accum[o + 2u], sum.z);
  atomicAdd(&accum[o + 3u], sum.w);
}

fn end_run() {
  // ABLATE_SUMS: the sums are made but not added (kept alive behind a condition that never
  // holds).
  if (ablated(ABLATE_SUMS) && run_sum.x != 0xfffffff0u) {
    run_pixel = NO_PIXEL;
    return;
  }
  if (run_pixel != NO_PIXEL && run_sum.w > 0u) {
    if (run_entry < TILE_PIXELS) {
      for (var c = 0u; c < 4u; c++) {
        atomicAdd(&tile_sums[run_entry][c], run_sum[c]);
      }
    } else {
      add_sums(run_pixel, run_sum);
    }
  }
  run_pixel = NO_PIXEL;
}

fn limit_of(pixel: u32) -> f32 {
  let nearest = bitcast<f32>(depth_buffer[pixel * params.depth_stride + params.depth_word]);
  return nearest * (1.0 + params.depth_tolerance);
}

// The tile entry of the pixel at column and row `xy` while the batch draws into the tile, else
// TILE_PIXELS (the screen's).
fn drawing_entry(xy: vec2<u32>) -> u32 {
  if (TILE && tile_phase != 0u) {
    return tile_entry_xy(xy);
  }
  return TILE_PIXELS;
}

// The depth limit of `pixel`: its tile entry's (`entry`: drawing_entry) or the screen's.
fn entry_limit(entry: u32, pixel: u32) -> f32 {
  if (entry < TILE_PIXELS) {
    return bitcast<f32>(atomicLoad(&tile_depth[entry]));
  }
  return limit_of(pixel);
}

fn draw_point(cells: vec3<f32>, index: u32) {
  let pr = project_point(cells);
  if (!pr.valid) {
    return;
  }
  let position = point_position(cells);
  let state = raster_filter(index, position);
  if (state == 0u) {
    return;
  }
  if (pr.pixel != run_pixel) {
    end_run();
    run_pixel = pr.pixel;
    run_entry = drawing_entry(pr.xy);
    run_limit = entry_limit(run_entry, pr.pixel);
    run_sum = vec4<u32>(0u);
  }
  if (pr.depth > run_limit) {
    return;
  }
  if (shading.mode == 1u && state == 1u) {
    // In the RGB mode the source colour's bytes are what shading it and taking its 8-bit
    // channels gives (round(x / 255 * 255) = x), without the float round trip (HQS 1.13x
    // faster on the H200: bench/RESULTS.md, run Q).
    let c = colors[index];
    run_sum += vec4<u32>(c & 0xffu, (c >> 8u) & 0xffu, (c >> 16u) & 0xffu, 1u);
  } else {
    var color = shade(colors[index], attributes_of(index), position.y);
    if (state == 2u) {
      color = highlighted(color);
    }
    run_sum += vec4<u32>(channels(color), 1u);
  }
}

// LEAN (compute_raster_batch.wgsl): the accumulation's lean loop, for 10-bit batches in the RGB
// mode without filters, as the depth passes' (see lean_batch in compute_raster_write.wgsl): no
// precision, filter or shading branches, no range test for words wholly inside the batch, no
// clipping tests in batches inside the view. A word's four points are projected, then their
// depth limits read together, then their colours (a point that does not pass reads point 0's,
// which stays in cache, so that no read waits behind a branch), then they join the thread's
// runs. The fallback's colour pass 1.79x faster with it on the H200; HQS's sums 1.17x slower at
// the overview (bench/RESULTS.md, run AA), so HQS keeps the general loop.
fn lean_sums_batch(bits: u32) -> bool {
  return LEAN && bits == 10u && !ablated(ABLATE_LOAD) && !ablated(ABLATE_SUMS) &&
         shading.mode == 1u && filters.flags == 0u;
}

// A lean point (tile entry `entry`: drawing_entry) that passes (`passes`) with colour `c`: into
// the thread's run.
fn lean_sum(p: LeanProjected, entry: u32, passes: bool, c: u32) {
  if (!passes) {
    return;
  }
  let sum = vec4<u32>(c & 0xffu, (c >> 8u) & 0xffu, (c >> 16u) & 0xffu, 1u);
  if (p.pixel == run_pixel) {
    run_sum += sum;
    return;
  }
  end_run();
  run_pixel = p.pixel;
  run_entry = entry;
  run_sum = sum;
}

// The four points of word `v` (points 4v..4v+3); unless `full` (a literal: the word lies wholly
// inside the batch) only those in [lo, end).
fn lean_sums_word(c: vec4<u32>, v: u32, lo: u32, end: u32, inside: bool, full: bool) {
  let first = v * 4u;
  let p0 = lean_project(c.x, inside);
  let p1 = lean_project(c.y, inside);
  let p2 = lean_project(c.z, inside);
  let p3 = lean_project(c.w, inside);
  let e0 = drawing_entry(p0.xy);
  let e1 = drawing_entry(p1.xy);
  let e2 = drawing_entry(p2.xy);
  let e3 = drawing_entry(p3.xy);
  let l0 = entry_limit(e0, p0.pixel);
  let l1 = entry_limit(e1, p1.pixel);
  let l2 = entry_limit(e2, p2.pixel);
  let l3 = entry_limit(e3, p3.pixel);
  var a0 = p0.valid && p0.depth <= l0 && selected(c.x);
  var a1 = p1.valid && p1.depth <= l1 && selected(c.y);
  var a2 = p2.valid && p2.depth <= l2 && selected(c.z);
  var a3 = p3.valid && p3.depth <= l3 && selected(c.w);
  if (!full) {
    a0 = a0 && first >= lo && first < end;
    a1 = a1 && first + 1u >= lo && first + 1u < end;
    a2 = a2 && first + 2u >= lo && first + 2u < end;
    a3 = a3 && first + 3u < end;
  }
  let c0 = colors[select(0u, first, a0)];
  let c1 = colors[select(0u, first + 1u, a1)];
  let c2 = colors[select(0u, first + 2u, a2)];
  let c3 = colors[select(0u, first + 3u, a3)];
  lean_sum(p0, e0, a0, c0);
  lean_sum(p1, e1, a1, c1);
  lean_sum(p2, e2, a2, c2);
  lean_sum(p3, e3, a3, c3);
}

// The lean loop over batch `b`: the words wholly inside it, then the partial first and last
// ones (threads 0 and 1).
fn draw_sums_lean(b: GpuBatch, lid: u32) {
  lean_size = vec2<f32>(f32(params.width), f32(params.height));
  let lo = b.first;
  let end = b.first + b.count;
  let full_end = end / 4u;
  if (batch_inside) {
    for (var v = (lo + 3u) / 4u + lid; v < full_end; v += WORKGROUP) {
      lean_sums_word(coarse[v], v, lo, end, true, true);
    }
  } else {
    for (var v = (lo + 3u) / 4u + lid; v < full_end; v += WORKGROUP) {
      lean_sums_word(coarse[v], v, lo, end, false, true);
    }
  }
  let part = lean_partial_word(lo, end, lid);
  if (part != 0xffffffffu) {
    lean_sums_word(coarse[part], part, lo, end, false, false);
  }
  end_run();
}

// The pass's loop over batch `b` at precision `bits`.
fn draw_sums(b: GpuBatch, bits: u32, lid: u32) {
  if (lean_sums_batch(bits)) {
    draw_sums_lean(b, lid);
  } else {
    draw_batch_points(b, bits, lid);
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
  let b = batches[batch];
  if (TILE && tile_begin(b, lid)) {
    tile_phase = 1u;
    draw_sums(b, bits, lid);
    workgroupBarrier();
    for (var i = lid; i < tile_size.x * tile_size.y; i += WORKGROUP) {
      let sum = vec4<u32>(atomicLoad(&tile_sums[i][0]), atomicLoad(&tile_sums[i][1]),
                          atomicLoad(&tile_sums[i][2]), atomicLoad(&tile_sums[i][3]));
      if (sum.w > 0u) {
        add_sums(tile_pixel(i), sum);
      }
    }
    return;
  }
  draw_sums(b, bits, lid);
}
