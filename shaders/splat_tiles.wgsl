// The tile-based splat rasterizer (the reference's 16x16 tiles), an alternative to the sorted
// quads of splat_draw.wgsl, after the same projection and depth sort:
//
//   cs_block_sums   per block of 2048 ranks (rank i: the splat i-th in depth order, farthest
//                   first): the tiles each splat's footprint touches (tile_rect), their count
//                   into scan[i] and the rectangle after the block sums (rect_at), and their
//                   sum, into scan[capacity + block]
//   cs_scan_blocks  one workgroup: exclusive prefix of the block sums (2048 a step); the pairs
//                   kept (the total, at most pair_capacity) into tile_data[0] (the tile sort's
//                   count), the total into the word after the ranges (read back: the host grows
//                   the buffers when it exceeds the capacity)
//   cs_block_apply  per block: the exclusive prefix of its ranks plus its block's offset
//   cs_emit         per splat: one (tile, rank) pair per touched tile of its rectangle (read
//                   in rank order, not gathered from the projection again) at its offset, so the
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
  blocks: u32,         // of 2048 splats
  has_depth: u32,
  pad0: u32,
  pad1: u32,
}

const TILE: u32 = 16u;
const WG: u32 = 256u;
const BLOCK: u32 = 2048u;  // ranks a block of the scan (splats.cpp's kScanBlock)
const PER: u32 = 8u;       // ranks an invocation

@group(0) @binding(0) var<uniform> frame: SplatFrame;
@group(0) @binding(1) var<uniform> params: TileParams;
@group(0) @binding(2) var<storage, read> projected: array<Projected>;
@group(0) @binding(3) var<storage, read> sorted_keys: array<u32>;
@group(0) @binding(4) var<storage, read> sorted_values: array<u32>;
// The projection's indirect draw arguments: [1] is the visible count.
@group(0) @binding(5) var<storage, read> args: array<u32>;
// [0, capacity): per rank, tiles touched, then their exclusive prefix; then the block sums; then
// per rank its rectangle of tiles (rect_at).
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
  // Clamped again as integers: a NaN footprint (an overflowed covariance) converts to any
  // integer, and the rectangle's 16-bit packing must stay what its count says.
  let last = vec2<i32>(size) - 1;
  let plo = clamp(vec2<i32>(clamp(lo, vec2<f32>(0.0), size - 1.0)), vec2<i32>(0), last);
  let phi = clamp(vec2<i32>(clamp(hi, vec2<f32>(0.0), size - 1.0)), vec2<i32>(0), last);
  if (hi.x < 0.0 || hi.y < 0.0 || lo.x > size.x - 1.0 || lo.y > size.y - 1.0 || hi.x < lo.x ||
      hi.y < lo.y) {
    return vec4<i32>(0, 0, -1, -1);
  }
  return vec4<i32>(plo / i32(TILE), phi / i32(TILE));
}

// Where rank i's rectangle of tiles is kept in `scan`: two words, (x0 | y0 << 16, x1 | y1 << 16).
fn rect_at(i: u32) -> u32 {
  return params.capacity + params.blocks + 1u + 2u * i;
}

fn rect_tiles(r: vec4<i32>) -> u32 {
  if (r.z < r.x || r.w < r.y) {
    return 0u;
  }
  return u32((r.z - r.x + 1) * (r.w - r.y + 1));
}

var<workgroup> block_total: atomic<u32>;
var<workgroup> block_counts: array<u32, 2048>;

@compute @workgroup_size(256)
fn cs_block_sums(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                 @builtin(local_invocation_index) lid: u32) {
  let block = wid.x + wid.y * groups.x;
  if (block >= params.blocks) {
    return;
  }
  if (lid == 0u) {
    atomicStore(&block_total, 0u);
  }
  workgroupBarrier();
  let n = visible_count();
  var sum = 0u;
  for (var e = 0u; e < PER; e = e + 1u) {
    let i = block * BLOCK + e * WG + lid;
    if (i < n) {
      let r = tile_rect(projected[sorted_values[i]]);
      let c = rect_tiles(r);
      scan[i] = c;
      // An empty rectangle as x0 = 1 > x1 = 0: cs_emit's loops then write nothing.
      var packed = vec2<u32>(1u, 0u);
      if (c > 0u) {
        packed = vec2<u32>(u32(r.x) | (u32(r.y) << 16u), u32(r.z) | (u32(r.w) << 16u));
      }
      scan[rect_at(i)] = packed.x;
      scan[rect_at(i) + 1u] = packed.y;
      sum = sum + c;
    }
  }
  atomicAdd(&block_total, sum);
  workgroupBarrier();
  if (lid == 0u) {
    scan[params.capacity + block] = atomicLoad(&block_total);
  }
}

@compute @workgroup_size(256)
fn cs_scan_blocks(@builtin(local_invocation_index) lid: u32) {
  var carry = 0u;
  for (var chunk = 0u; chunk < params.blocks; chunk = chunk + BLOCK) {
    // Each invocation eight consecutive block sums.
    let first = chunk + PER * lid;
    var v: array<u32, 8>;
    var sum = 0u;
    for (var e = 0u; e < PER; e = e + 1u) {
      v[e] = 0u;
      if (first + e < params.blocks) {
        v[e] = scan[params.capacity + first + e];
      }
      sum = sum + v[e];
    }
    let inclusive = inclusive_scan(lid, vec2<u32>(sum, 0u)).x;
    let total = scan_total().x;
    var running = carry + inclusive - sum;
    for (var e = 0u; e < PER; e = e + 1u) {
      if (first + e < params.blocks) {
        scan[params.capacity + first + e] = running;
      }
      running = running + v[e];
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
  let base = block * BLOCK;
  // Coalesced through workgroup memory: each invocation then scans eight consecutive ranks.
  for (var e = 0u; e < PER; e = e + 1u) {
    let j = e * WG + lid;
    var c = 0u;
    if (base + j < n) {
      c = scan[base + j];
    }
    block_counts[j] = c;
  }
  workgroupBarrier();
  var v: array<u32, 8>;
  var sum = 0u;
  for (var e = 0u; e < PER; e = e + 1u) {
    v[e] = block_counts[PER * lid + e];
    sum = sum + v[e];
  }
  let inclusive = inclusive_scan(lid, vec2<u32>(sum, 0u)).x;
  var running = scan[params.capacity + block] + inclusive - sum;
  for (var e = 0u; e < PER; e = e + 1u) {
    block_counts[PER * lid + e] = running;
    running = running + v[e];
  }
  workgroupBarrier();
  for (var e = 0u; e < PER; e = e + 1u) {
    let j = e * WG + lid;
    if (base + j < n) {
      scan[base + j] = block_counts[j];
    }
  }
}

@compute @workgroup_size(256)
fn cs_emit(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
  let i = linear_index(wid, groups, lid);
  if (i >= visible_count()) {
    return;
  }
  let lo = scan[rect_at(i)];
  let hi = scan[rect_at(i) + 1u];
  let r = vec4<u32>(lo & 0xffffu, lo >> 16u, hi & 0xffffu, hi >> 16u);
  // Pairs past the capacity: the first `skip` (the farthest splats') are left out.
  let skip = tile_data[pair_total_index()] - tile_data[0];
  var slot = scan[i];
  for (var ty = r.y; ty <= r.w; ty = ty + 1u) {
    for (var tx = r.x; tx <= r.z; tx = tx + 1u) {
      if (slot >= skip) {
        pair_keys[slot - skip] = ty * params.tiles_x + tx;
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
