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

