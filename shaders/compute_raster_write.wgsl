// draw_point of the depth passes: a point's key (its depth, and for the 64-bit visibility buffer
// its index) into the pixel it projects to. The including shader defines `alias Key`,
// point_key(depth bits, index) and write_key(pixel, key), which makes the early depth test (a
// load of the pixel's depth; most hidden points never reach the atomic) and then the atomicMin.
// Points hidden by the filters or the clip region (compute_raster_filter.wgsl) are dropped
// before the test.
#include "compute_raster_filter.wgsl"

// A point's depth test (the early test, then the atomic) happens at once: the depth passes keep
// no runs, so the batch loop's end_run() has nothing to write.
fn end_run() {}

fn draw_point(cells: vec3<f32>, index: u32) {
  let pr = project_point(cells);
  if (!pr.valid || raster_filter(index, point_position(cells)) == 0u) {
    return;
  }
  // Positive floats order as their bits.
  write_key(pr.pixel, point_key(bitcast<u32>(pr.depth), index));
}

// The lean loop's point: the key draw_point would write (translucent points are skipped where the
// frame blends them: SPLIT).
fn lean_point(v: u32, index: u32, inside: bool) {
  if (!selected(v)) {
    return;
  }
  let p = lean_project(v, inside);
  if (p.valid) {
    write_key(p.pixel, point_key(bitcast<u32>(p.depth), index));
  }
}

// A depth pass's batch at precision `bits` (not 0).
fn draw_batch(b: GpuBatch, bits: u32, lid: u32) {
  if (lean_batch(bits)) {
    draw_batch_lean(b, lid);
  } else {
    draw_batch_points(b, bits, lid);
  }
}

// The lean loop for the common case, a 10-bit batch with no filter, written for the fewest
// instructions a point: no precision or filter branches inside the loop, a range test per
// 16-byte word (none for words wholly inside the batch), the viewport's size converted once, and
// in a batch that lies inside the view (batch_inside: box_inside, a pixel to spare and in front
// of the near plane) no clipping tests and no z. The passes are bound by the instructions they
// issue a point (bench/RESULTS.md, runs U-Y: 1.67x faster than the general loop); the pixels and
// depths, and so the keys and the image, are the ones project_point gives.
fn lean_batch(bits: u32) -> bool {
  return LEAN && bits == 10u && !ablated(ABLATE_LOAD) && filters.flags == 0u;
}

// The four points of word `v` (points 4v..4v+3) that lie in [lo, end).
fn lean_word(c: vec4<u32>, v: u32, lo: u32, end: u32, inside: bool) {
  let first = v * 4u;
  if (first >= lo && first + 4u <= end) {
    lean_point(c.x, first, inside);
    lean_point(c.y, first + 1u, inside);
    lean_point(c.z, first + 2u, inside);
    lean_point(c.w, first + 3u, inside);
    return;
  }
  for (var k = 0u; k < 4u; k++) {
    if (first + k >= lo && first + k < end) {
      lean_point(c[k], first + k, inside);
    }
  }
}

// The words wholly inside the batch take no range test; the partial first and last ones (at
// most two a batch) are drawn by threads 0 and 1 after them.
fn draw_batch_lean(b: GpuBatch, lid: u32) {
  lean_size = vec2<f32>(f32(params.width), f32(params.height));
  let lo = b.first;
  let end = b.first + b.count;
  let full_end = end / 4u;
  if (batch_inside) {
    for (var v = (lo + 3u) / 4u + lid; v < full_end; v += WORKGROUP) {
      lean_word(coarse[v], v, lo, end, true);
    }
  } else {
    for (var v = (lo + 3u) / 4u + lid; v < full_end; v += WORKGROUP) {
      lean_word(coarse[v], v, lo, end, false);
    }
  }
  let part = lean_partial_word(lo, end, lid);
  if (part != 0xffffffffu) {
    if (batch_inside) {
      lean_word(coarse[part], part, lo, end, true);
    } else {
      lean_word(coarse[part], part, lo, end, false);
    }
  }
}

// Every depth pass's entry point: one workgroup a batch.
@compute @workgroup_size(WORKGROUP)
fn main(@builtin(workgroup_id) group: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
        @builtin(local_invocation_index) lid: u32) {
  let batch = batch_index(group, groups);
  let bits = batch_prologue(batch, lid);
  if (bits == 0u) {
    return;
  }
  draw_batch(batches[batch], bits, lid);
}
