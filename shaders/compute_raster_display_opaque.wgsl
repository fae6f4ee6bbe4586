// The display of a frame without translucent points: the opaque colour as it is.
fn over_translucent(pixel: u32, color: vec3<f32>) -> vec3<f32> {
  return color;
}
