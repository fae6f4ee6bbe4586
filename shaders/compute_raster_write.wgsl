// draw_point of the geometry passes: a point's key (depth, and for the 64-bit visibility buffer
// its index) into the pixel it projects to. The including shader defines `alias Key`,
// point_key(depth bits, index), key_less(a, b), depth_word(pixel) and write_key(pixel, key),
// which does the early depth test and the atomic. Points hidden by the filters or the clip
// region (compute_raster_filter.wgsl) are dropped before they join a run.
//
// PLAIN_EARLY: the early depth test reads the depth word with a plain load of an aliased,
// non-atomic view of the buffer, as seed 001's Listing 1 does, instead of an atomic load.
// MERGE: a thread keeps the nearest key of the pixel its last points fell on and writes it once
// the pixel changes (or its points end): at overview distances hundreds of points share a
// pixel, and consecutive points of a sorted batch mostly do.
#include "compute_raster_filter.wgsl"

override PLAIN_EARLY: bool = true;
override MERGE: bool = true;
// SUBGROUP_REDUCE (without MERGE): the points of a subgroup that share a pixel write once, their
// nearest key found by subgroup operations (subgroup_write(): compute_raster_reduce_*.wgsl).
override SUBGROUP_REDUCE: bool = false;
// A measurement of where the time goes, never a default (write_key of the 64-bit pass).
override ABLATE: u32 = 0u;
// EARLY_TEST: a point reads its pixel's depth before the atomic and skips it when hidden.
// GROUP_EARLY (the lean loop): a full word's four early-test loads are issued together, before
// any of its tests, instead of each after the previous point's test and atomic. The driver's
// robust buffer access puts a range check before each load; with a test and an atomic between
// them a thread waited for four loads in turn.
override EARLY_TEST: bool = true;
override GROUP_EARLY: bool = false;

const NO_PIXEL: u32 = 0xffffffffu;
var<private> run_pixel: u32 = NO_PIXEL;
var<private> run_key: Key;

fn end_run() {
  if (run_pixel != NO_PIXEL) {
    write_key(run_pixel, run_key);
    run_pixel = NO_PIXEL;
  }
}

fn draw_point(cells: vec3<f32>, index: u32) {
  let pr = project_point(cells);
  let shown = pr.valid && raster_filter(index, point_position(cells)) != 0u;
  let key = point_key(bitcast<u32>(pr.depth), index);  // positive floats order as their bits
  if (SUBGROUP_REDUCE && !MERGE) {
    subgroup_write(shown, pr.pixel, key);
    return;
  }
  if (!shown) {
    return;
  }
  if (!MERGE) {
    write_key(pr.pixel, key);
    return;
  }
  if (pr.pixel == run_pixel) {
    if (key_less(key, run_key)) {
      run_key = key;
    }
    return;
  }
  end_run();
  run_pixel = pr.pixel;
  run_key = key;
}

// The lean loop's point: the key draw_point would write.
fn lean_point(v: u32, index: u32, inside: bool) {
  let p = lean_project(v, inside);
  if (p.valid) {
    write_key(p.pixel, point_key(bitcast<u32>(p.depth), index));
  }
}

// A depth pass's batch at precision `bits` (not 0), without the workgroup tile.
fn draw_batch(b: GpuBatch, bits: u32, lid: u32) {
  if (lean_batch(bits)) {
    draw_batch_lean(b, lid);
  } else {
    draw_batch_points(b, bits, lid);
  }
}

// BATCHES_PER_GROUP > 1 (with PARALLEL_PROLOGUE, without TILE): the workgroup's batches, a grid
// stride apart.
fn draw_batch_group(group: vec3<u32>, groups: vec3<u32>, lid: u32) {
  let stride = groups.x * groups.y;
  for (var j = 0u; j < BATCHES_PER_GROUP; j++) {
    let batch = batch_index(group, groups) + j * stride;
    let bits = batch_prologue(batch, lid);
    if (bits != 0u) {
      draw_batch(batches[batch], bits, lid);
    }
  }
}

// LEAN: the depth passes' loop for the common case, a 10-bit batch with no filter, merging or
// subgroup reduction (lean_batch), written for the fewest instructions a point: no precision or
// filter branches inside the loop, a range test per 16-byte word (none for words wholly inside
// the batch), the viewport's size converted once, and in a batch that lies inside the view
// (batch_inside: box_inside, a pixel to spare and in front of the near plane) no clipping tests
// and no z. The passes are bound by the instructions they issue a point (bench/RESULTS.md, runs
// U-Y); the pixels and depths, and so the keys and the image, are the ones project_point gives.
// (The LEAN constant: compute_raster_batch.wgsl.)
fn lean_batch(bits: u32) -> bool {
  return LEAN && bits == 10u && PREFETCH && !CONTIGUOUS && !ABLATE_LOAD && filters.flags == 0u &&
         !MERGE && !SUBGROUP_REDUCE;
}

// A projected point whose pixel's early-test value (`early`: early_value of the including
// shader; pixel 0's for an invalid point) has been read: its key, tested against it.
fn lean_write(p: LeanProjected, index: u32, early: Early) {
  if (p.valid) {
    write_key_tested(p.pixel, point_key(bitcast<u32>(p.depth), index), early);
  }
}

// The four points of word `v` (points 4v..4v+3) that lie in [lo, end).
fn lean_word(c: vec4<u32>, v: u32, lo: u32, end: u32, inside: bool) {
  let first = v * 4u;
  if (GROUP_EARLY && EARLY_TEST && ABLATE == 0u && first >= lo && first + 4u <= end) {
    // An invalid point's pixel is 0 (LeanProjected starts zeroed): a load in range.
    let p0 = lean_project(c.x, inside);
    let p1 = lean_project(c.y, inside);
    let p2 = lean_project(c.z, inside);
    let p3 = lean_project(c.w, inside);
    let w0 = early_value(p0.pixel);
    let w1 = early_value(p1.pixel);
    let w2 = early_value(p2.pixel);
    let w3 = early_value(p3.pixel);
    lean_write(p0, first, w0);
    lean_write(p1, first + 1u, w1);
    lean_write(p2, first + 2u, w2);
    lean_write(p3, first + 3u, w3);
    return;
  }
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
  if (PREFETCH_WORDS > 1u) {
    // Two words a thread in flight before either is drawn.
    for (var v = (lo + 3u) / 4u + lid; v < full_end; v += 2u * WORKGROUP) {
      let v2 = v + WORKGROUP;
      let c = coarse[v];
      var c2 = vec4<u32>(0u);
      if (v2 < full_end) {
        c2 = coarse[v2];
      }
      if (batch_inside) {
        lean_word(c, v, lo, end, true);
        if (v2 < full_end) {
          lean_word(c2, v2, lo, end, true);
        }
      } else {
        lean_word(c, v, lo, end, false);
        if (v2 < full_end) {
          lean_word(c2, v2, lo, end, false);
        }
      }
    }
  } else if (batch_inside) {
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
  end_run();
}
