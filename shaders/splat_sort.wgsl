// A stable least-significant-digit radix sort of (u32 key, u32 value) pairs, 8 bits a round,
// in plain WGSL: no subgroups, 256 invocations and under 5 KB of workgroup memory a workgroup,
// so it runs on every WebGPU implementation and in browsers. One round is four dispatches:
//
//   cs_histogram     per block of 512 pairs, how many keys have each digit: hist[digit][block]
//   cs_scan_digits   one workgroup per digit: exclusive prefix over the blocks (in place; each
//                    invocation a run of blocks), and the digit's total into digit_offsets
//   cs_scan_totals   one workgroup: exclusive prefix of the 256 totals (digit_offsets)
//   cs_scatter       per block: a stable local sort of its pairs by the digit (four 2-bit
//                    split rounds, each one workgroup prefix sum of packed counters), then each
//                    pair goes to digit_offsets[d] + hist[d][block] + its rank among the block's
//                    pairs of digit d
//
// Stability: a block's pairs keep their order within a digit (each invocation owns two
// consecutive pairs, and the splits are stable), and blocks are laid out in order.
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

const WG: u32 = 256u;
const BLOCK: u32 = 512u;  // pairs a workgroup: two per invocation

var<workgroup> digit_counts: array<atomic<u32>, 256>;
var<workgroup> scan: array<u32, 256>;
var<workgroup> sk: array<u32, 512>;
var<workgroup> sv: array<u32, 512>;
var<workgroup> starts: array<u32, 256>;

fn block_index(wid: vec3<u32>) -> u32 {
  return wid.x + wid.y * params.groups_x;
}

fn pair_count() -> u32 {
  return min(count[params.count_index], params.capacity);
}

// Inclusive prefix sum of `v` over the workgroup (Hillis-Steele); scan[255] is the total
// afterwards. Every invocation must call it.
fn inclusive_scan(lid: u32, v: u32) -> u32 {
  scan[lid] = v;
  workgroupBarrier();
  for (var offset = 1u; offset < WG; offset = offset << 1u) {
    var t = scan[lid];
    if (lid >= offset) {
      t = t + scan[lid - offset];
    }
    workgroupBarrier();
    scan[lid] = t;
    workgroupBarrier();
  }
  return scan[lid];
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
  for (var j = 0u; j < 2u; j = j + 1u) {
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
  // each writes its run's prefixes: one scan a digit instead of one every 256 blocks (6M keys:
  // 46, each eight barrier steps).
  let row = wid.x * params.blocks;
  let per = (params.blocks + WG - 1u) / WG;
  let first = min(lid * per, params.blocks);
  let last = min(first + per, params.blocks);
  var sum = 0u;
  for (var b = first; b < last; b = b + 1u) {
    sum = sum + hist[row + b];
  }
  let inclusive = inclusive_scan(lid, sum);
  let total = scan[WG - 1u];
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
  let inclusive = inclusive_scan(lid, v);
  digit_offsets[lid] = inclusive - v;
}

// Packed counter of a 2-bit digit: 10 bits for each of digits 0-2 (a block has 512 pairs, so no
// field overflows); digit 3's count is what the other three leave.
fn packed_one(d: u32) -> u32 {
  return select(0u, 1u << (10u * d), d < 3u);
}

fn unpack_counts(c: u32, all: u32) -> vec4<u32> {
  let a = c & 1023u;
  let b = (c >> 10u) & 1023u;
  let d = (c >> 20u) & 1023u;
  return vec4<u32>(a, b, d, all - a - b - d);
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
  // Coalesced loads; missing pairs are the largest key, so they sort after every real one.
  for (var j = 0u; j < 2u; j = j + 1u) {
    let i = base + j * WG + lid;
    var k = 0xffffffffu;
    var v = 0u;
    if (i < n) {
      k = keys_in[i];
      v = values_in[i];
    }
    sk[j * WG + lid] = k;
    sv[j * WG + lid] = v;
  }
  workgroupBarrier();
  var k0 = sk[2u * lid];
  var k1 = sk[2u * lid + 1u];
  var v0 = sv[2u * lid];
  var v1 = sv[2u * lid + 1u];
  workgroupBarrier();

  // Four stable 2-bit splits sort the block by the round's 8-bit digit.
  for (var r = 0u; r < 4u; r = r + 1u) {
    let s = params.shift + 2u * r;
    let d0 = (k0 >> s) & 3u;
    let d1 = (k1 >> s) & 3u;
    let c = packed_one(d0) + packed_one(d1);
    let inclusive = inclusive_scan(lid, c);
    let total = scan[WG - 1u];
    let before = unpack_counts(inclusive - c, 2u * lid);
    let totals = unpack_counts(total, BLOCK);
    let run_start = vec4<u32>(0u, totals.x, totals.x + totals.y, totals.x + totals.y + totals.z);
    let p0 = run_start[d0] + before[d0];
    let p1 = run_start[d1] + before[d1] + select(0u, 1u, d0 == d1);
    sk[p0] = k0;
    sv[p0] = v0;
    sk[p1] = k1;
    sv[p1] = v1;
    workgroupBarrier();
    k0 = sk[2u * lid];
    k1 = sk[2u * lid + 1u];
    v0 = sv[2u * lid];
    v1 = sv[2u * lid + 1u];
    workgroupBarrier();
  }

  // Where each digit's run starts in the sorted block.
  let i0 = 2u * lid;
  let e0 = (k0 >> params.shift) & 255u;
  let e1 = (k1 >> params.shift) & 255u;
  if (i0 == 0u || ((sk[i0 - 1u] >> params.shift) & 255u) != e0) {
    starts[e0] = i0;
  }
  if (e1 != e0) {
    starts[e1] = i0 + 1u;
  }
  workgroupBarrier();
  // The block's real pairs are its first min(512, n - base) sorted ones (the padding sorts last
  // and, as the last of equal keys, after any real key 0xffffffff).
  let valid = min(BLOCK, n - base);
  if (i0 < valid) {
    let dst = digit_offsets[e0] + hist[e0 * params.blocks + block] + (i0 - starts[e0]);
    keys_out[dst] = k0;
    values_out[dst] = v0;
  }
  if (i0 + 1u < valid) {
    let dst = digit_offsets[e1] + hist[e1 * params.blocks + block] + (i0 + 1u - starts[e1]);
    keys_out[dst] = k1;
    values_out[dst] = v1;
  }
}
