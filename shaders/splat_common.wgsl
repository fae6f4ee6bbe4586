// Shared by the splat passes (splat_project.wgsl, splat_draw.wgsl).

struct SplatFrame {
  // World to the reference rasterizer's view axes (x right, y down, z forward) times the set's
  // linear transform: local offsets to view offsets. Columns, w unused.
  local_to_view: mat4x4<f32>,
  // The set's inverse linear transform: world directions to the set's frame (the SH's frame).
  world_to_local: mat4x4<f32>,
  view_rotation: mat4x4<f32>,  // world to (x right, y down, z forward)
  // The set's centre minus the camera, in world space (from double on the CPU).
  offset: vec3<f32>,
  count: u32,
  focal: vec2<f32>,      // pixels
  tan_fov: vec2<f32>,    // tan of the half field of view, x and y
  viewport: vec2<f32>,   // pixels
  near: f32,
  sh_degree: u32,
  sh_stride: u32,        // u32 words of SH a splat
  pad0: u32,
  pad1: u32,
  pad2: u32,
}

// One splat as uploaded: 48 bytes.
struct Splat {
  position: vec3<f32>,  // relative to the set's centre, in the set's frame
  opacity: f32,
  scale: vec3<f32>,     // linear standard deviations
  rot_xy: u32,          // pack2x16float of the unit quaternion's x, y
  rot_zw: u32,
  dc_rg: u32,           // pack2x16float of the degree-0 SH coefficients
  dc_b: u32,
  pad: u32,
}

// A visible splat after projection: 32 bytes, indexed by its slot in the draw order.
struct Projected {
  centre: vec2<f32>,  // pixels, from the top-left corner
  conic_xy: vec2<f32>,  // the inverse 2D covariance (a, b, c): a and b
  conic_z: f32,
  radius: f32,        // half the quad's side, pixels: ceil(3 sigma) of the larger axis
  color_rg: u32,      // pack2x16float
  color_b_opacity: u32,
}

const MIN_ALPHA: f32 = 1.0 / 255.0;

// The sort key: the view depth's bits reversed, so that an ascending sort puts the farthest
// splat first (positive floats order as their bits). The draw reads the depth back from it.
fn depth_key(z: f32) -> u32 {
  return 0xffffffffu - bitcast<u32>(z);
}

fn key_depth(key: u32) -> f32 {
  return bitcast<f32>(0xffffffffu - key);
}
