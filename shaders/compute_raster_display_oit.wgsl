// The display of a frame with translucent points (raster-translucent,
// compute_raster_translucent.wgsl): their alpha-weighted average colour over the opaque colour
// by the coverage 1 - revealage, revealage = exp(-sum of -ln(1 - alpha)).
#include "compute_raster_common.wgsl"

@group(0) @binding(4) var<storage, read> translucent: array<u32>;

fn over_translucent(pixel: u32, color: vec3<f32>) -> vec3<f32> {
  let o = pixel * 4u;
  let weight = translucent[o + 3u];
  if (weight == 0u) {
    return color;
  }
  let mean = vec3<f32>(f32(translucent[o]), f32(translucent[o + 1u]), f32(translucent[o + 2u])) /
             (f32(weight) * 255.0);
  let cover = translucent[params.width * params.height * 4u + pixel];
  let revealage = exp(-f32(cover) / REVEAL_SCALE);
  return mix(mean, color, revealage);
}
