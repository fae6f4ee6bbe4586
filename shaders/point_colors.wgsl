// The colour ramps of the colour modes, shared by the billboard passes (point_common.wgsl) and
// the compute rasterizer (compute_raster_shading.wgsl), so that both paths colour alike; the
// CPU mirror is the profile image's (shade_sample in src/pointcloud/src/profile.cpp).

fn ramp(t_in: f32) -> vec3<f32> {
  // Dark blue, cyan, green, yellow, red.
  let t = clamp(t_in, 0.0, 1.0) * 4.0;
  let i = min(u32(t), 3u);
  let f = t - f32(i);
  var a = vec3<f32>(0.15, 0.15, 0.6);
  var b = vec3<f32>(0.1, 0.6, 0.8);
  if (i == 1u) {
    a = vec3<f32>(0.1, 0.6, 0.8);
    b = vec3<f32>(0.3, 0.75, 0.3);
  } else if (i == 2u) {
    a = vec3<f32>(0.3, 0.75, 0.3);
    b = vec3<f32>(0.95, 0.85, 0.2);
  } else if (i == 3u) {
    a = vec3<f32>(0.95, 0.85, 0.2);
    b = vec3<f32>(0.85, 0.2, 0.1);
  }
  return mix(a, b, f);
}

fn return_color(number: u32, count: u32) -> vec3<f32> {
  if (count <= 1u) { return vec3<f32>(240.0, 200.0, 60.0) / 255.0; }  // single return
  if (number <= 1u) { return vec3<f32>(220.0, 60.0, 50.0) / 255.0; }  // first of many
  if (number >= count) { return vec3<f32>(40.0, 110.0, 230.0) / 255.0; }  // last of many
  return vec3<f32>(60.0, 190.0, 80.0) / 255.0;  // intermediate
}
