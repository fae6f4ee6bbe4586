// Colour of the compute rasterizer's points, the billboard path's point_color over the same
// packed words: the batches keep each point's source RGB and its attribute word (intensity
// 0-15, class 16-23, return 24-27, returns 28-31), and the resolve (visible points only) or the
// accumulation pass shades them in the frame's colour mode. Mode and ramps are uniforms, so a
// change costs nothing and the intensity ramp can follow what is loaded.
#include "compute_raster_attributes.wgsl"
#include "point_colors.wgsl"

struct Shading {
  mode: u32,                  // ColorMode: 1 rgb, 2 intensity, 3 classification, 4 elevation,
                              // 5 return, 6 constant
  needs_attributes: u32,      // the mode reads the attribute word
  pad0: u32,
  pad1: u32,
  // x: camera Y - elevation minimum (double on the CPU), y: 1 / elevation span,
  // z: intensity minimum, w: 1 / intensity span
  ranges: vec4<f32>,
  constant_color: vec4<f32>,
  palette: array<vec4<f32>, 32>,  // ASPRS classes
}

@group(0) @binding(10) var<uniform> shading: Shading;

// `rel_y`: the point's camera-relative Y (world Y is the source elevation).
fn shade(rgba: u32, attr: u32, rel_y: f32) -> vec3<f32> {
  switch (shading.mode) {
    case 1u: {
      return unpack4x8unorm(rgba).rgb;
    }
    case 2u: {
      return vec3<f32>(clamp((f32(attr & 0xffffu) - shading.ranges.z) * shading.ranges.w, 0.0, 1.0));
    }
    case 3u: {
      return shading.palette[min((attr >> 16u) & 0xffu, 31u)].rgb;
    }
    case 5u: {
      return return_color((attr >> 24u) & 0xfu, attr >> 28u);
    }
    case 6u: {
      return shading.constant_color.rgb;
    }
    default: {
      return ramp((rel_y + shading.ranges.x) * shading.ranges.y);
    }
  }
}

// The attribute word of point `index` when the mode reads it.
fn attributes_of(index: u32) -> u32 {
  if (shading.needs_attributes != 0u) {
    return attributes[index];
  }
  return 0u;
}

// 8-bit channel values of a colour, as the accumulation buffer sums them.
fn channels(c: vec3<f32>) -> vec3<u32> {
  return vec3<u32>(round(clamp(c, vec3<f32>(0.0), vec3<f32>(1.0)) * 255.0));
}
