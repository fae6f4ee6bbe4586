// Level of detail of pointlets (seed 002, III-B), three entry points run in order:
//   weights: frustum culling of each pointlet's box, then its importance l_i (eq. 2) with
//            gamma_i (eq. 3), stored without the common factor (sum_j r_j)^2 of gamma (it cancels
//            in the normalisation): w_i = |v/2 p_center - v/2 p_max| / r_i^2, r_i the box's
//            half diagonal; per-workgroup partial sums
//   total:   one workgroup adds the partial sums
//   counts:  n_i = min(floor(w_i / sum w * B), size_i, loaded_i): the point bucket B shared by
//            importance, capped by what the pointlet has and what is resident
// pc::pointlet_lod_cpu computes the same in the same float arithmetic.

struct Params {
  view_proj: mat4x4<f32>,  // rotation-only view times projection (camera-relative)
  offset: vec3<f32>,       // boxes' origin minus the camera position (double on the CPU)
  count: u32,              // pointlets
  viewport: vec2<f32>,
  bucket: f32,             // B
  partials: u32,           // workgroups of the weights pass
}

struct Box {
  lo: vec4<f32>,  // xyz: min corner relative to the origin (world, Y up); w: half diagonal
  hi: vec4<f32>,  // xyz: max corner
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> boxes: array<Box>;
@group(0) @binding(2) var<storage, read> sizes: array<vec2<u32>>;  // points, loaded points
@group(0) @binding(3) var<storage, read_write> weights: array<f32>;
@group(0) @binding(4) var<storage, read_write> partial_sums: array<f32>;
@group(0) @binding(5) var<storage, read_write> counts: array<u32>;

const WORKGROUP: u32 = 256u;
var<workgroup> scratch: array<f32, WORKGROUP>;

fn weight_of(b: Box) -> f32 {
  let lo = b.lo.xyz + params.offset;
  let hi = b.hi.xyz + params.offset;
  var out_l = true;
  var out_r = true;
  var out_b = true;
  var out_t = true;
  var out_n = true;
  for (var i = 0u; i < 8u; i++) {
    let corner = select(lo, hi, vec3<bool>((i & 1u) != 0u, (i & 2u) != 0u, (i & 4u) != 0u));
    let c = params.view_proj * vec4<f32>(corner, 1.0);
    out_l = out_l && c.x < -c.w;
    out_r = out_r && c.x > c.w;
    out_b = out_b && c.y < -c.w;
    out_t = out_t && c.y > c.w;
    out_n = out_n && c.z > c.w;  // reverse Z: nearer than the near plane
  }
  if (out_l || out_r || out_b || out_t || out_n) {
    return 0.0;
  }
  let center = params.view_proj * vec4<f32>((lo + hi) * 0.5, 1.0);
  let corner = params.view_proj * vec4<f32>(hi, 1.0);
  var projected = length(params.viewport);  // a box around the camera fills the view
  if (center.w > 0.0 && corner.w > 0.0) {
    let half_view = params.viewport * 0.5;
    projected = length(half_view * (center.xy / center.w) - half_view * (corner.xy / corner.w));
  }
  let r = max(b.lo.w, 1e-6);
  return projected / (r * r);
}

// Sums scratch into scratch[0] (a tree over the workgroup); call from uniform control flow.
fn workgroup_sum(lid: u32) {
  workgroupBarrier();
  for (var stride = WORKGROUP / 2u; stride > 0u; stride >>= 1u) {
    if (lid < stride) {
      scratch[lid] += scratch[lid + stride];
    }
    workgroupBarrier();
  }
}

@compute @workgroup_size(256)
fn weights_main(@builtin(global_invocation_id) id: vec3<u32>,
                @builtin(local_invocation_index) lid: u32,
                @builtin(workgroup_id) group: vec3<u32>) {
  var w = 0.0;
  if (id.x < params.count) {
    w = weight_of(boxes[id.x]);
    weights[id.x] = w;
  }
  scratch[lid] = w;
  workgroup_sum(lid);
  if (lid == 0u) {
    partial_sums[group.x] = scratch[0];
  }
}

@compute @workgroup_size(256)
fn total_main(@builtin(local_invocation_index) lid: u32) {
  var s = 0.0;
  for (var i = lid; i < params.partials; i += WORKGROUP) {
    s += partial_sums[i];
  }
  scratch[lid] = s;
  workgroup_sum(lid);
  if (lid == 0u) {
    partial_sums[params.partials] = scratch[0];  // the total, after the partial sums
  }
}

@compute @workgroup_size(256)
fn counts_main(@builtin(global_invocation_id) id: vec3<u32>) {
  if (id.x >= params.count) {
    return;
  }
  let total = partial_sums[params.partials];
  var n = 0u;
  if (total > 0.0) {
    n = u32(min(floor(weights[id.x] / total * params.bucket), 4294967040.0));
  }
  let s = sizes[id.x];
  counts[id.x] = min(n, min(s.x, s.y));
}
