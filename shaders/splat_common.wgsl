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
// splat first (positive floats order as their bits). All 32 bits (splats.cpp's kDepthKeyBits):
// splats of equal keys keep the projection's order, which its atomic slots make vary from frame
// to frame, so a coarser key (24 bits, one radix round fewer, was tried) let nearly coplanar
// splats swap their blending order between frames of a still view. The draw reads the depth
// back from it.
fn depth_key(z: f32) -> u32 {
  return 0xffffffffu - bitcast<u32>(z);
}

fn key_depth(key: u32) -> f32 {
  return bitcast<f32>(0xffffffffu - key);
}

// Half the width and height, in pixels, of the box a splat's pixels can be drawn in: the square
// of its radius (3 sigma of the larger axis, as the reference) cut to the bounding box of the
// ellipse outside which its alpha falls under 1/255 and every pixel is dropped (opacity *
// exp(-m^2 / 2) < 1/255 beyond m^2 = 2 ln(255 opacity)). The same pixels are drawn, from fewer
// tiles and smaller quads.
fn splat_half_extent(p: Projected) -> vec2<f32> {
  let opacity = unpack2x16float(p.color_b_opacity).y;
  let m2 = 2.0 * log(max(255.0 * opacity, 1.0)) * 1.001;
  // The 2D covariance's diagonal from the conic (its inverse): a = C / det, c = A / det.
  let conic_det = p.conic_xy.x * p.conic_z - p.conic_xy.y * p.conic_xy.y;
  let var_xy = vec2<f32>(p.conic_z, p.conic_xy.x) / max(conic_det, 1e-30);
  return min(sqrt(m2 * var_xy), vec2<f32>(p.radius));
}
