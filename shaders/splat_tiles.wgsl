// The tile-based splat rasterizer (the reference's 16x16 tiles), an alternative to the sorted
// quads of splat_draw.wgsl, after the same projection and depth sort:
//
//   cs_count        per splat in depth order (rank i, farthest first): the tiles its footprint
//                   touches (tile_rect), into scan[i]
//   cs_block_sums   per block of 512 ranks: the sum, into scan[capacity + block]
//   cs_scan_blocks  one workgroup: exclusive prefix of the block sums; the pairs kept (the
//                   total, at most pair_capacity) into tile_data[0] (the tile sort's count),
//                   the total into the word after the ranges (read back: the host grows the
//                   buffers when it exceeds the capacity)
//   cs_block_apply  per block: the exclusive prefix of its ranks plus its block's offset
//   cs_emit         per splat: one (tile, rank) pair per touched tile at its offset, so the
//                   pairs are in rank order; a stable sort by tile then leaves each tile's
//                   splats in depth order. Over the capacity the first (farthest) pairs are the
//                   ones left out: the nearest splats are drawn
//   cs_clear_ranges / cs_ranges   each tile's range of the sorted pairs
//   cs_raster       one workgroup per tile, one invocation per pixel: the tile's splats front
//                   to back in batches of 256 through workgroup memory, blended until the
//                   transmittance falls under 1e-4 (every pixel of the tile done: the loop
//                   ends), depth-tested against the points' depth; (colour, 1 - T) per pixel
//   fs_composite    lays that over the frame (premultiplied: one, one minus source alpha)
#include "splat_common.wgsl"
#include "workgroup_scan.wgsl"

struct TileParams {
  tiles_x: u32,
  tiles_y: u32,
  capacity: u32,       // splats (the scan's length)
  pair_capacity: u32,  // (tile, rank) pairs the buffers hold; the farthest of more are dropped
  blocks: u32,         // of 512 splats
  has_depth: u32,
  pad0: u32,
  pad1: u32,
}

const TILE: u32 = 16u;
const WG: u32 = 256u;
const BLOCK: u32 = 512u;

@group(0) @binding(0) var<uniform> frame: SplatFrame;
@group(0) @binding(1) var<uniform> params: TileParams;
@group(0) @binding(2) var<storage, read> projected: array<Projected>;
@group(0) @binding(3) var<storage, read> sorted_keys: array<u32>;
@group(0) @binding(4) var<storage, read> sorted_values: array<u32>;
// The projection's indirect draw arguments: [1] is the visible count.
@group(0) @binding(5) var<storage, read> args: array<u32>;
// [0, capacity): per rank, tiles touched, then their exclusive prefix; then the block sums.
@group(0) @binding(6) var<storage, read_write> scan: array<u32>;
@group(0) @binding(7) var<storage, read_write> pair_keys: array<u32>;
@group(0) @binding(8) var<storage, read_write> pair_values: array<u32>;
// [0]: the pairs kept; then per tile its [start, end) in the sorted pairs; then the pairs the
// frame wanted (pair_total_index).
@group(0) @binding(9) var<storage, read_write> tile_data: array<u32>;

fn pair_total_index() -> u32 {
  return 1u + 2u * params.tiles_x * params.tiles_y;
}

fn visible_count() -> u32 {
  return min(args[1], params.capacity);
}

fn linear_index(wid: vec3<u32>, groups: vec3<u32>, lid: u32) -> u32 {
  return (wid.x + wid.y * groups.x) * WG + lid;
}

// The tiles whose pixels' centres can lie in the splat's box (splat_half_extent): (x0, y0, x1,
// y1), inclusive; empty when x1 < x0.
fn tile_rect(p: Projected) -> vec4<i32> {
  let half = splat_half_extent(p);
  let lo = ceil(p.centre - half - 0.5);
  let hi = floor(p.centre + half - 0.5);
  let size = vec2<f32>(frame.viewport);
  let plo = vec2<i32>(clamp(lo, vec2<f32>(0.0), size - 1.0));
  let phi = vec2<i32>(clamp(hi, vec2<f32>(0.0), size - 1.0));
  if (hi.x < 0.0 || hi.y < 0.0 || lo.x > size.x - 1.0 || lo.y > size.y - 1.0 || hi.x < lo.x ||
      hi.y < lo.y) {
    return vec4<i32>(0, 0, -1, -1);
  }
  return vec4<i32>(plo / i32(TILE), phi / i32(TILE));
}

fn rect_tiles(r: vec4<i32>) -> u32 {
  if (r.z < r.x || r.w < r.y) {
    return 0u;
  }
  return u32((r.z - r.x + 1) * (r.w - r.y + 1));
}

@compute @workgroup_size(256)
fn cs_count(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
            @builtin(local_invocation_index) lid: u32) {
  let i = linear_index(wid, groups, lid);
  if (i >= visible_count()) {
    return;
  }
  scan[i] = rect_tiles(tile_rect(projected[sorted_values[i]]));
}

@compute @workgroup_size(256)
fn cs_block_sums(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                 @builtin(local_invocation_index) lid: u32) {
  let block = wid.x + wid.y * groups.x;
  if (block >= params.blocks) {
    return;
  }
  let n = visible_count();
  let i = block * BLOCK + 2u * lid;
  var v = 0u;
  if (i < n) {
    v = scan[i];
  }
  if (i + 1u < n) {
    v = v + scan[i + 1u];
  }
  let inclusive = inclusive_scan(lid, vec2<u32>(v, 0u)).x;
  if (lid == WG - 1u) {
    scan[params.capacity + block] = inclusive;
  }
}

@compute @workgroup_size(256)
fn cs_scan_blocks(@builtin(local_invocation_index) lid: u32) {
  var carry = 0u;
  for (var chunk = 0u; chunk < params.blocks; chunk = chunk + WG) {
    let b = chunk + lid;
    var v = 0u;
    if (b < params.blocks) {
      v = scan[params.capacity + b];
    }
    let inclusive = inclusive_scan(lid, vec2<u32>(v, 0u)).x;
    let total = scan_total().x;
    if (b < params.blocks) {
      scan[params.capacity + b] = carry + inclusive - v;
    }
    carry = carry + total;
    workgroupBarrier();
  }
  if (lid == 0u) {
    tile_data[0] = min(carry, params.pair_capacity);
    tile_data[pair_total_index()] = carry;
  }
}

@compute @workgroup_size(256)
fn cs_block_apply(@builtin(workgroup_id) wid: vec3<u32>,
                  @builtin(num_workgroups) groups: vec3<u32>,
                  @builtin(local_invocation_index) lid: u32) {
  let block = wid.x + wid.y * groups.x;
  if (block >= params.blocks) {
    return;
  }
  let n = visible_count();
  let i = block * BLOCK + 2u * lid;
  var a = 0u;
  var b = 0u;
  if (i < n) {
    a = scan[i];
  }
  if (i + 1u < n) {
    b = scan[i + 1u];
  }
  let inclusive = inclusive_scan(lid, vec2<u32>(a + b, 0u)).x;
  let base = scan[params.capacity + block] + inclusive - a - b;
  if (i < n) {
    scan[i] = base;
  }
  if (i + 1u < n) {
    scan[i + 1u] = base + a;
  }
}

@compute @workgroup_size(256)
fn cs_emit(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
  let i = linear_index(wid, groups, lid);
  if (i >= visible_count()) {
    return;
  }
  let r = tile_rect(projected[sorted_values[i]]);
  // Pairs past the capacity: the first `skip` (the farthest splats') are left out.
  let skip = tile_data[pair_total_index()] - tile_data[0];
  var slot = scan[i];
  for (var ty = r.y; ty <= r.w; ty = ty + 1) {
    for (var tx = r.x; tx <= r.z; tx = tx + 1) {
      if (slot >= skip) {
        pair_keys[slot - skip] = u32(ty) * params.tiles_x + u32(tx);
        pair_values[slot - skip] = i;
      }
      slot = slot + 1u;
    }
  }
}

@compute @workgroup_size(256)
fn cs_clear_ranges(@builtin(workgroup_id) wid: vec3<u32>,
                   @builtin(num_workgroups) groups: vec3<u32>,
                   @builtin(local_invocation_index) lid: u32) {
  let t = linear_index(wid, groups, lid);
  if (t < params.tiles_x * params.tiles_y) {
    tile_data[1u + 2u * t] = 0u;
    tile_data[2u + 2u * t] = 0u;
  }
}

@compute @workgroup_size(256)
fn cs_ranges(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
             @builtin(local_invocation_index) lid: u32) {
  let j = linear_index(wid, groups, lid);
  let n = tile_data[0];
  if (j >= n) {
    return;
  }
  let t = pair_keys[j];
  if (j == 0u || pair_keys[j - 1u] != t) {
    tile_data[1u + 2u * t] = j;
  }
  if (j + 1u == n || pair_keys[j + 1u] != t) {
    tile_data[2u + 2u * t] = j + 1u;
  }
}
