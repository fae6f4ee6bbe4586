// draw_point of the geometry passes: a point's depth into the pixel it projects to, or with
// SPLAT into every pixel of a disc of params.splat_radius around it (points larger than one
// pixel drawn in the geometry pass, the alternative to dilating the visibility buffer after
// it). The including shader defines write_pixel(pixel, depth bits, index) and, before this
// file, the depth_word it reads.
//
// PLAIN_EARLY: the early depth test reads the depth word with a plain load of an aliased,
// non-atomic view of the buffer, as seed 001's Listing 1 does, instead of an atomic load.
override PLAIN_EARLY: bool = true;
override SPLAT: bool = false;

fn draw_point(position: vec3<f32>, index: u32) {
  if (!SPLAT) {
    let pr = project(params, position);
    if (pr.valid) {
      write_pixel(pr.pixel, bitcast<u32>(pr.depth), index);  // positive floats order as bits
    }
    return;
  }
  let c = params.view_proj * vec4<f32>(position, 1.0);
  if (c.w <= 0.0 || c.z > c.w) {
    return;
  }
  let s = vec2<f32>(c.x / c.w * 0.5 + 0.5, 0.5 - c.y / c.w * 0.5) *
          vec2<f32>(f32(params.width), f32(params.height));
  let r = i32(ceil(params.splat_radius));
  let centre = vec2<i32>(floor(s));
  let depth = bitcast<u32>(c.w);
  for (var dy = -r; dy <= r; dy++) {
    for (var dx = -r; dx <= r; dx++) {
      let q = centre + vec2<i32>(dx, dy);
      if (f32(dx * dx + dy * dy) > params.splat_radius2 || q.x < 0 || q.y < 0 ||
          q.x >= i32(params.width) || q.y >= i32(params.height)) {
        continue;
      }
      write_pixel(u32(q.y) * params.width + u32(q.x), depth, index);
    }
  }
}
