// Splats, per frame: one invocation per splat culls, projects (EWA splatting, as the 3D Gaussian
// splatting reference rasterizer: covariance from scale and rotation, the perspective's
// Jacobian at the centre clamped to 1.3 x tan(fov / 2), 0.3 px added to the 2D covariance,
// radius 3 sigma of the larger axis), evaluates the colour's spherical harmonics (degree 0-3)
// for the view direction, and appends the visible ones: the projected splat, its depth key and
// its slot (the sort's value) at a slot counted in the indirect draw arguments' instance count.
#include "splat_common.wgsl"

@group(0) @binding(0) var<uniform> frame: SplatFrame;
@group(0) @binding(1) var<storage, read> splats: array<Splat>;
// f16 pairs, sh_stride words (a multiple of four) a splat
@group(0) @binding(2) var<storage, read> sh: array<vec4<u32>>;
@group(0) @binding(3) var<storage, read_write> projected: array<Projected>;
@group(0) @binding(4) var<storage, read_write> keys: array<u32>;
@group(0) @binding(5) var<storage, read_write> values: array<u32>;
// {vertex_count, instance_count, first_vertex, first_instance}
@group(0) @binding(6) var<storage, read_write> args: array<atomic<u32>, 4>;

var<workgroup> group_count: atomic<u32>;
var<workgroup> group_base: u32;

const SH_C0: f32 = 0.28209479177387814;
const SH_C1: f32 = 0.4886025119029199;

fn h2(word: u32) -> vec2<f32> {
  return unpack2x16float(word);
}

// The SH above degree 0 come as whole vec4<u32> loads (six a splat at degree 3, where 45 f16
// read a word at a time took twice as many load instructions): sh_stride is a multiple of four
// words (splats.cpp). Coefficient k (1-based) is halves 3(k - 1) to 3(k - 1) + 2, half h the
// h % 2 of word h / 2 (pN below is word N unpacked).
fn sh_color(index: u32, dc: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
  var c = SH_C0 * dc;
  let deg = frame.sh_degree;
  if (deg > 0u) {
    let base = index * (frame.sh_stride / 4u);
    let w0 = sh[base];
    let w1 = sh[base + 1u];
    let p0 = h2(w0.x);
    let p1 = h2(w0.y);
    let p2 = h2(w0.z);
    let p3 = h2(w0.w);
    let p4 = h2(w1.x);
    let x = dir.x;
    let y = dir.y;
    let z = dir.z;
    c = c - SH_C1 * y * vec3<f32>(p0.x, p0.y, p1.x) + SH_C1 * z * vec3<f32>(p1.y, p2.x, p2.y) -
        SH_C1 * x * vec3<f32>(p3.x, p3.y, p4.x);
    if (deg > 1u) {
      let w2 = sh[base + 2u];
      let p5 = h2(w1.y);
      let p6 = h2(w1.z);
      let p7 = h2(w1.w);
      let p8 = h2(w2.x);
      let p9 = h2(w2.y);
      let p10 = h2(w2.z);
      let p11 = h2(w2.w);
      let xx = x * x;
      let yy = y * y;
      let zz = z * z;
      let xy = x * y;
      let yz = y * z;
      let xz = x * z;
      c = c + 1.0925484305920792 * xy * vec3<f32>(p4.y, p5.x, p5.y) +
          (-1.0925484305920792) * yz * vec3<f32>(p6.x, p6.y, p7.x) +
          0.31539156525252005 * (2.0 * zz - xx - yy) * vec3<f32>(p7.y, p8.x, p8.y) +
          (-1.0925484305920792) * xz * vec3<f32>(p9.x, p9.y, p10.x) +
          0.5462742152960396 * (xx - yy) * vec3<f32>(p10.y, p11.x, p11.y);
      if (deg > 2u) {
        let w3 = sh[base + 3u];
        let w4 = sh[base + 4u];
        let w5 = sh[base + 5u];
        let p12 = h2(w3.x);
        let p13 = h2(w3.y);
        let p14 = h2(w3.z);
        let p15 = h2(w3.w);
        let p16 = h2(w4.x);
        let p17 = h2(w4.y);
        let p18 = h2(w4.z);
        let p19 = h2(w4.w);
        let p20 = h2(w5.x);
        let p21 = h2(w5.y);
        let p22 = h2(w5.z);
        c = c + (-0.5900435899266435) * y * (3.0 * xx - yy) * vec3<f32>(p12.x, p12.y, p13.x) +
            2.890611442640554 * xy * z * vec3<f32>(p13.y, p14.x, p14.y) +
            (-0.4570457994644658) * y * (4.0 * zz - xx - yy) * vec3<f32>(p15.x, p15.y, p16.x) +
            0.3731763325901154 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy) *
                vec3<f32>(p16.y, p17.x, p17.y) +
            (-0.4570457994644658) * x * (4.0 * zz - xx - yy) * vec3<f32>(p18.x, p18.y, p19.x) +
            1.445305721320277 * z * (xx - yy) * vec3<f32>(p19.y, p20.x, p20.y) +
            (-0.5900435899266435) * x * (xx - 3.0 * yy) * vec3<f32>(p21.x, p21.y, p22.x);
      }
    }
  }
  return max(c + vec3<f32>(0.5), vec3<f32>(0.0));
}

// Rotation matrix of a unit quaternion (x, y, z, w).
fn quat_matrix(q: vec4<f32>) -> mat3x3<f32> {
  let x = q.x;
  let y = q.y;
  let z = q.z;
  let w = q.w;
  // Columns.
  return mat3x3<f32>(
      vec3<f32>(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)),
      vec3<f32>(2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x)),
      vec3<f32>(2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)));
}

struct Projection {
  visible: bool,
  key: u32,
  p: Projected,
}

fn project(index: u32) -> Projection {
  var out: Projection;
  out.visible = false;
  let s = splats[index];
  if (s.opacity < MIN_ALPHA) {
    return out;
  }
  let l2v = mat3x3<f32>(frame.local_to_view[0].xyz, frame.local_to_view[1].xyz,
                        frame.local_to_view[2].xyz);
  let w2v = mat3x3<f32>(frame.view_rotation[0].xyz, frame.view_rotation[1].xyz,
                        frame.view_rotation[2].xyz);
  // View position: the set's offset (world) rotated, plus the local position transformed.
  let t = w2v * frame.offset + l2v * s.position;
  // Written so that a NaN fails each test (an overflowed transform or covariance): such a splat
  // is dropped, not drawn from undefined conversions.
  if (!(t.z > frame.near)) {
    return out;
  }
  // Covariance in the set's frame: R S S^T R^T.
  let q = normalize(vec4<f32>(unpack2x16float(s.rot_xy), unpack2x16float(s.rot_zw)));
  let r = quat_matrix(q);
  let m = mat3x3<f32>(r[0] * s.scale.x, r[1] * s.scale.y, r[2] * s.scale.z);
  let sigma = m * transpose(m);
  // The perspective's Jacobian at the centre, the centre's direction clamped to 1.3 x the
  // half field of view (splats far outside the view would otherwise blow up).
  let lim = 1.3 * frame.tan_fov;
  let txz = clamp(t.x / t.z, -lim.x, lim.x) * t.z;
  let tyz = clamp(t.y / t.z, -lim.y, lim.y) * t.z;
  let fx = frame.focal.x;
  let fy = frame.focal.y;
  // J as columns (3 columns of a 2x3 matrix, padded to 3x3 with a zero row).
  let j = mat3x3<f32>(vec3<f32>(fx / t.z, 0.0, 0.0), vec3<f32>(0.0, fy / t.z, 0.0),
                      vec3<f32>(-fx * txz / (t.z * t.z), -fy * tyz / (t.z * t.z), 0.0));
  let tm = j * l2v;
  let cov = tm * sigma * transpose(tm);
  let a = cov[0][0] + 0.3;
  let b = cov[0][1];
  let c = cov[1][1] + 0.3;
  let det = a * c - b * b;
  if (!(det > 0.0)) {
    return out;
  }
  let mid = 0.5 * (a + c);
  let lambda = mid + sqrt(max(0.1, mid * mid - det));
  let radius = ceil(3.0 * sqrt(lambda));
  let centre = vec2<f32>(fx * t.x / t.z, fy * t.y / t.z) + 0.5 * frame.viewport;
  // Off screen: the quad misses the viewport.
  if (!(centre.x + radius > 0.0 && centre.y + radius > 0.0 && centre.x - radius < frame.viewport.x &&
        centre.y - radius < frame.viewport.y)) {
    return out;
  }
  // The view direction in the set's frame, for the SH.
  let w2l = mat3x3<f32>(frame.world_to_local[0].xyz, frame.world_to_local[1].xyz,
                        frame.world_to_local[2].xyz);
  let dir = normalize(w2l * (transpose(w2v) * t));
  let dc = vec3<f32>(unpack2x16float(s.dc_rg), unpack2x16float(s.dc_b).x);
  let color = sh_color(index, dc, dir);
  out.visible = true;
  out.key = depth_key(t.z);
  out.p.centre = centre;
  out.p.conic_xy = vec2<f32>(c / det, -b / det);
  out.p.conic_z = a / det;
  out.p.radius = radius;
  out.p.color_rg = pack2x16float(color.rg);
  out.p.color_b_opacity = pack2x16float(vec2<f32>(color.b, s.opacity));
  return out;
}

@compute @workgroup_size(256)
fn cs_project(@builtin(workgroup_id) wid: vec3<u32>,
              @builtin(num_workgroups) groups: vec3<u32>,
              @builtin(local_invocation_index) lid: u32) {
  if (lid == 0u) {
    atomicStore(&group_count, 0u);
  }
  workgroupBarrier();
  let index = (wid.x + wid.y * groups.x) * 256u + lid;
  var result: Projection;
  result.visible = false;
  if (index < frame.count) {
    result = project(index);
  }
  var local = 0u;
  if (result.visible) {
    local = atomicAdd(&group_count, 1u);
  }
  workgroupBarrier();
  if (lid == 0u) {
    group_base = atomicAdd(&args[1], atomicLoad(&group_count));
  }
  let base = workgroupUniformLoad(&group_base);
  if (result.visible) {
    let slot = base + local;
    projected[slot] = result.p;
    keys[slot] = result.key;
    values[slot] = slot;
  }
}
