// A stable least-significant-digit radix sort of (u32 key, u32 value) pairs, 8 bits a round,
// in plain WGSL: no subgroups, 256 invocations and 12 KB of workgroup memory a workgroup, so it
// runs on every WebGPU implementation and in browsers. One round is four dispatches:
//
//   cs_histogram     per block of 2048 pairs, how many keys have each digit: hist[digit][block]
//   cs_scan_digits   one workgroup per digit: exclusive prefix over the blocks (in place; each
//                    invocation a run of blocks), and the digit's total into digit_offsets
//   cs_scan_totals   one workgroup: exclusive prefix of the 256 totals (digit_offsets)
//   cs_scatter       per block: a stable local sort of the block's (digit, index) words by the
//                    digit (four 2-bit split rounds, each one workgroup prefix sum of packed
//                    counters), then each pair goes to digit_offsets[d] + hist[d][block] + its
//                    rank among the block's pairs of digit d
//
// Each invocation owns eight consecutive words of the block, so a split round costs one
// workgroup scan per 2048 pairs, and a digit's run in the output averages eight pairs. The local
// sort moves 32-bit words (digit << 16 | index in the block); the pairs themselves are read once
// from global memory (the block's 16 KB stays in cache) and written once to their places.
//
// Stability: a block's pairs keep their order within a digit (each invocation's words are
// consecutive, and the splits are stable), and blocks are laid out in order.
// The pair count is read from a storage buffer (count[count_index]) written on the GPU: blocks
// past it do nothing, so a dispatch sized for the capacity sorts only what was produced.

struct SortParams {
  shift: u32,        // bit of the round's digit: 0, 8, 16, 24
  blocks: u32,       // blocks of the capacity
  groups_x: u32,     // workgroups along x of a 2D dispatch (the x size is limited to 65,535)
  count_index: u32,  // where the pair count is in `count`
  capacity: u32,
}

@group(0) @binding(0) var<uniform> params: SortParams;
@group(0) @binding(1) var<storage, read> count: array<u32>;
@group(0) @binding(2) var<storage, read> keys_in: array<u32>;
@group(0) @binding(3) var<storage, read> values_in: array<u32>;
@group(0) @binding(4) var<storage, read_write> keys_out: array<u32>;
@group(0) @binding(5) var<storage, read_write> values_out: array<u32>;
@group(0) @binding(6) var<storage, read_write> hist: array<u32>;  // [256 * blocks], digit-major
@group(0) @binding(7) var<storage, read_write> digit_offsets: array<u32>;  // [256]

#include "workgroup_scan.wgsl"

const WG: u32 = 256u;
const PER: u32 = 8u;       // words an invocation
const BLOCK: u32 = 2048u;  // pairs a workgroup (radix_sort.cpp's kBlock)

var<workgroup> digit_counts: array<atomic<u32>, 256>;
var<workgroup> words: array<u32, 2048>;
var<workgroup> starts: array<u32, 256>;

fn block_index(wid: vec3<u32>) -> u32 {
  return wid.x + wid.y * params.groups_x;
}

fn pair_count() -> u32 {
  return min(count[params.count_index], params.capacity);
}

@compute @workgroup_size(256)
fn cs_histogram(@builtin(workgroup_id) wid: vec3<u32>,
                @builtin(local_invocation_index) lid: u32) {
  let block = block_index(wid);
  if (block >= params.blocks) {
    return;
  }
  let n = pair_count();
  atomicStore(&digit_counts[lid], 0u);
  workgroupBarrier();
  let base = block * BLOCK;
  for (var j = 0u; j < PER; j = j + 1u) {
    let i = base + j * WG + lid;
    if (i < n) {
      atomicAdd(&digit_counts[(keys_in[i] >> params.shift) & 255u], 1u);
    }
  }
  workgroupBarrier();
  hist[lid * params.blocks + block] = atomicLoad(&digit_counts[lid]);
}

@compute @workgroup_size(256)
fn cs_scan_digits(@builtin(workgroup_id) wid: vec3<u32>,
                  @builtin(local_invocation_index) lid: u32) {
  // Each invocation sums a run of consecutive blocks, one workgroup scan offsets the runs, and
  // each writes its run's prefixes: one scan a digit.
  let row = wid.x * params.blocks;
  let per = (params.blocks + WG - 1u) / WG;
  let first = min(lid * per, params.blocks);
  let last = min(first + per, params.blocks);
  var sum = 0u;
  for (var b = first; b < last; b = b + 1u) {
    sum = sum + hist[row + b];
  }
  let inclusive = inclusive_scan(lid, vec2<u32>(sum, 0u)).x;
  let total = scan_total().x;
  var running = inclusive - sum;
  for (var b = first; b < last; b = b + 1u) {
    let v = hist[row + b];
    hist[row + b] = running;
    running = running + v;
  }
  if (lid == 0u) {
    digit_offsets[wid.x] = total;
  }
}

@compute @workgroup_size(256)
fn cs_scan_totals(@builtin(local_invocation_index) lid: u32) {
  let v = digit_offsets[lid];
  let inclusive = inclusive_scan(lid, vec2<u32>(v, 0u)).x;
  digit_offsets[lid] = inclusive - v;
}

// One of a 2-bit digit in four 16-bit counters (a block has 2048 pairs: no field overflows).
fn packed_one(d: u32) -> vec2<u32> {
  let one = 1u << (16u * (d & 1u));
  return select(vec2<u32>(one, 0u), vec2<u32>(0u, one), d >= 2u);
}

fn unpack_counts(c: vec2<u32>) -> vec4<u32> {
  return vec4<u32>(c.x & 0xffffu, c.x >> 16u, c.y & 0xffffu, c.y >> 16u);
}

@compute @workgroup_size(256)
fn cs_scatter(@builtin(workgroup_id) wid: vec3<u32>,
              @builtin(local_invocation_index) lid: u32) {
  let block = block_index(wid);
  if (block >= params.blocks) {
    return;
  }
  let n = pair_count();
  let base = block * BLOCK;
  if (base >= n) {
    return;
  }
  let valid = min(BLOCK, n - base);
  // Coalesced loads of the digits; missing pairs get digit 255 and the highest indices, so they
  // sort after every real pair.
  for (var j = 0u; j < PER; j = j + 1u) {
    let local = j * WG + lid;
    var d = 255u;
    if (local < valid) {
      d = (keys_in[base + local] >> params.shift) & 255u;
    }
    words[local] = (d << 16u) | local;
  }
  workgroupBarrier();
  var w: array<u32, 8>;
  for (var e = 0u; e < PER; e = e + 1u) {
    w[e] = words[PER * lid + e];
  }
  workgroupBarrier();

  // Four stable 2-bit splits sort the block by the round's 8-bit digit.
  for (var r = 0u; r < 4u; r = r + 1u) {
    let s = 16u + 2u * r;
    var c = vec2<u32>(0u, 0u);
    for (var e = 0u; e < PER; e = e + 1u) {
      c = c + packed_one((w[e] >> s) & 3u);
    }
    let inclusive = inclusive_scan(lid, c);
    let totals = unpack_counts(scan_total());
    var at = unpack_counts(inclusive - c) +
             vec4<u32>(0u, totals.x, totals.x + totals.y, totals.x + totals.y + totals.z);
    for (var e = 0u; e < PER; e = e + 1u) {
      let d = (w[e] >> s) & 3u;
      words[at[d]] = w[e];
      at[d] = at[d] + 1u;
    }
    workgroupBarrier();
    for (var e = 0u; e < PER; e = e + 1u) {
      w[e] = words[PER * lid + e];
    }
    workgroupBarrier();
  }

  // Where each digit's run starts in the sorted block.
  for (var e = 0u; e < PER; e = e + 1u) {
    let j = PER * lid + e;
    let d = w[e] >> 16u;
    var prev = 0xffffffffu;
    if (e > 0u) {
      prev = w[e - 1u] >> 16u;
    } else if (j > 0u) {
      prev = words[j - 1u] >> 16u;
    }
    if (prev != d) {
      starts[d] = j;
    }
  }
  workgroupBarrier();
  // Each digit's output place less its run's start in the block, once a digit (wrapping u32
  // arithmetic; digits the block lacks are never read) rather than two global reads a pair.
  starts[lid] = digit_offsets[lid] + hist[lid * params.blocks + block] - starts[lid];
  workgroupBarrier();
  // Neighbouring invocations write neighbouring places of a digit's run; the block's real pairs
  // are its first `valid` sorted ones (the padding sorts last).
  for (var e = 0u; e < PER; e = e + 1u) {
    let j = e * WG + lid;
    let word = words[j];
    let local = word & 0xffffu;
    if (local < valid) {
      let d = word >> 16u;
      let dst = starts[d] + j;
      keys_out[dst] = keys_in[base + local];
      values_out[dst] = values_in[base + local];
    }
  }
}
