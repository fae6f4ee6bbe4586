// The tile-based splat rasterizer (the reference's 16x16 tiles), an alternative to the sorted
// quads of splat_draw.wgsl, after the same projection and depth sort:
//
//   cs_count        per splat in depth order (rank i, farthest first): the tiles of its box
//                   (tile_rect) that its ellipse reaches (tile_reached), into scan[i]
//   cs_block_sums   per block of 512 ranks: the sum, into scan[capacity + block]
//   cs_scan_blocks  one workgroup: exclusive prefix of the block sums; the pairs kept (the
//                   total, at most pair_capacity) into tile_data[0] (the tile sort's count),
//                   the total into the word after the ranges (read back: the host grows the
//                   buffers when it exceeds the capacity)
//   cs_block_apply  per block: the exclusive prefix of its ranks plus its block's offset
//   cs_emit         per splat: one (tile, rank) pair per reached tile at its offset, so the
//                   pairs are in rank order; a stable sort by tile then leaves each tile's
//                   splats in depth order. Over the capacity the first (farthest) pairs are the
//                   ones left out: the nearest splats are drawn. A slot the count gave that the
//                   emit does not fill (were the two passes' arithmetic to differ) holds
//                   NO_TILE, which sorts last and belongs to no tile's range
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

// The key of a pair slot that holds no pair (16 bits, as the tile sort's keys; more tiles than
// that are refused by the host).
const NO_TILE: u32 = 0xffffu;

// The least of q(d) = a dx^2 + 2 b dx dy + c dy^2 over the rectangle [lo, hi] of offsets from a
// splat's centre: 0 where the centre is inside, else on an edge, where q is a parabola in the
// free coordinate whose vertex is clamped to the edge.
fn rect_min_q(conic: vec3<f32>, lo: vec2<f32>, hi: vec2<f32>) -> f32 {
  if (lo.x <= 0.0 && hi.x >= 0.0 && lo.y <= 0.0 && hi.y >= 0.0) {
    return 0.0;
  }
  let a = max(conic.x, 1e-30);
  let b = conic.y;
  let c = max(conic.z, 1e-30);
  var m = 3.4e38;
  for (var k = 0; k < 2; k = k + 1) {
    let x = select(hi.x, lo.x, k == 0);
    let y = clamp(-b * x / c, lo.y, hi.y);
    m = min(m, a * x * x + 2.0 * b * x * y + c * y * y);
    let y2 = select(hi.y, lo.y, k == 0);
    let x2 = clamp(-b * y2 / a, lo.x, hi.x);
    m = min(m, a * x2 * x2 + 2.0 * b * x2 * y2 + c * y2 * y2);
  }
  return m;
}

// Whether tile (tx, ty) of the splat's box has a pixel centre where the splat's alpha can reach
// 1/255 (the raster's test: power = -q / 2 >= ln(1 / (255 opacity))): the box of an elongated or
// tilted ellipse holds many tiles it does not reach, and each pair costs the tile's raster pass a
// splat. Conservative: q's least value over the tile's pixel-centre rectangle, against the
// threshold splat_half_extent uses (with its margin).
fn tile_reached(p: Projected, m2: f32, tx: i32, ty: i32) -> bool {
  let first = vec2<f32>(f32(tx), f32(ty)) * f32(TILE) + 0.5;
  let lo = first - p.centre;
  let hi = lo + f32(TILE - 1u);
  return rect_min_q(vec3<f32>(p.conic_xy, p.conic_z), lo, hi) <= m2;
}

// The q threshold of a splat's alpha >= 1/255 (as splat_half_extent).
fn reach_m2(p: Projected) -> f32 {
  let opacity = unpack2x16float(p.color_b_opacity).y;
  return 2.0 * log(max(255.0 * opacity, 1.0)) * 1.001;
}

// The tiles of r that the splat reaches.
fn reached_tiles(p: Projected, r: vec4<i32>) -> u32 {
  let m2 = reach_m2(p);
  var n = 0u;
  for (var ty = r.y; ty <= r.w; ty = ty + 1) {
    for (var tx = r.x; tx <= r.z; tx = tx + 1) {
      n = n + u32(tile_reached(p, m2, tx, ty));
    }
  }
  return n;
}

@compute @workgroup_size(256)
fn cs_count(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
            @builtin(local_invocation_index) lid: u32) {
  let i = linear_index(wid, groups, lid);
  if (i >= visible_count()) {
    return;
  }
  let p = projected[sorted_values[i]];
  scan[i] = reached_tiles(p, tile_rect(p));
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
  let p = projected[sorted_values[i]];
  let r = tile_rect(p);
  let m2 = reach_m2(p);
  // Pairs past the capacity: the first `skip` (the farthest splats') are left out.
  let total = tile_data[pair_total_index()];
  let skip = total - tile_data[0];
  var slot = scan[i];
  let end = select(total, scan[i + 1u], i + 1u < visible_count());
  for (var ty = r.y; ty <= r.w; ty = ty + 1) {
    for (var tx = r.x; tx <= r.z; tx = tx + 1) {
      if (slot < end && tile_reached(p, m2, tx, ty)) {
        if (slot >= skip) {
          pair_keys[slot - skip] = u32(ty) * params.tiles_x + u32(tx);
          pair_values[slot - skip] = i;
        }
        slot = slot + 1u;
      }
    }
  }
  for (; slot < end; slot = slot + 1u) {
    if (slot >= skip) {
      pair_keys[slot - skip] = NO_TILE;
      pair_values[slot - skip] = i;
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
  if (t >= params.tiles_x * params.tiles_y) {
    return;  // NO_TILE
  }
  if (j == 0u || pair_keys[j - 1u] != t) {
    tile_data[1u + 2u * t] = j;
  }
  if (j + 1u == n || pair_keys[j + 1u] != t) {
    tile_data[2u + 2u * t] = j + 1u;
  }
}
