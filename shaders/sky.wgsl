// The Nishita sky (Nishita et al. 1993, seed 000's future work) as a background: where no point
// was drawn, the single-scattered Rayleigh and Mie light of a spherical atmosphere along the
// pixel's view ray, for the sun's direction, instead of the plain background colour. The
// primary ray is marched in SKY_STEPS samples (denser near the observer) to the top of the
// atmosphere, each sample's light ray to the sun in SKY_LIGHT_STEPS (samples whose light ray
// meets the earth are in its shadow). Evaluated per background pixel and frame (no look-up
// table): 16 x 8 samples.
// Constants are the commonly used ones: earth radius 6360 km, atmosphere 6420 km, Rayleigh scale
// height 8 km and coefficients (5.8, 13.5, 33.1) x 1e-6 / m, Mie scale height 1.2 km,
// scattering 21e-6 / m (extinction 1.1 times that) and g = 0.76. Directions below the horizon
// take the horizon's light, darkened with depth (no ground is modelled). The radiance is tone
// mapped, 1 - exp(-exposure x), and written as the display value.

struct Sky {
  inv_view_proj: mat4x4<f32>,  // clip space -> rotation-only view (world directions)
  sun: vec4<f32>,              // xyz: unit vector towards the sun (world); w: 1 when drawn
  up: vec4<f32>,               // xyz: the data's local up (world); w: observer height, metres
  view: vec4<f32>,             // xy: viewport, pixels; z: exposure; w: sun intensity
}

const SKY_EARTH_R: f32 = 6360e3;
const SKY_ATMOSPHERE_R: f32 = 6420e3;
const SKY_H_R: f32 = 8000.0;
const SKY_H_M: f32 = 1200.0;
const SKY_BETA_R: vec3<f32> = vec3<f32>(5.8e-6, 13.5e-6, 33.1e-6);
const SKY_BETA_M: f32 = 21e-6;
const SKY_G: f32 = 0.76;
const SKY_STEPS: u32 = 16u;
const SKY_LIGHT_STEPS: u32 = 8u;
const SKY_PI: f32 = 3.14159265;
const SKY_SUN_COS: f32 = 0.99996;  // the sun's disc: about 0.5 degrees across

// Distance from `o` (inside the sphere of radius r about the origin) along unit `d` to its
// surface; negative when the ray meets no sphere of that radius ahead.
fn sky_exit(o: vec3<f32>, d: vec3<f32>, r: f32) -> f32 {
  let b = dot(o, d);
  let c = dot(o, o) - r * r;
  let disc = b * b - c;
  if (disc < 0.0) {
    return -1.0;
  }
  return -b + sqrt(disc);
}

// Single-scattered radiance towards the observer along unit `dir` (world), sun along `sun`.
fn sky_radiance(dir_in: vec3<f32>, sun: vec3<f32>, up: vec3<f32>, height: f32) -> vec3<f32> {
  // Below the horizon: the horizon's light (the view ray turned up to it).
  let mu_view = dot(dir_in, up);
  var dir = dir_in;
  if (mu_view < 0.002) {
    dir = normalize(dir_in - up * mu_view + up * 0.002);
  }
  // Earth-centred frame: the observer stands `height` above the ground, "up" away from the centre.
  let origin = up * (SKY_EARTH_R + max(height, 1.0));
  let t_max = sky_exit(origin, dir, SKY_ATMOSPHERE_R);
  let mu = dot(dir, sun);
  let phase_r = 3.0 / (16.0 * SKY_PI) * (1.0 + mu * mu);
  let g2 = SKY_G * SKY_G;
  let phase_m = 3.0 / (8.0 * SKY_PI) * ((1.0 - g2) * (1.0 + mu * mu)) /
                ((2.0 + g2) * pow(1.0 + g2 - 2.0 * SKY_G * mu, 1.5));
  var depth_r = 0.0;
  var depth_m = 0.0;
  var sum_r = vec3<f32>(0.0);
  var sum_m = vec3<f32>(0.0);
  for (var i = 0u; i < SKY_STEPS; i++) {
    // Samples crowd near the observer (segment ends at (i / n)^2 of the ray), where the air is
    // densest: 16 even steps of a ~1000 km horizontal ray would make each near-ground segment
    // opaque to blue and the noon horizon yellow.
    let a0 = f32(i) / f32(SKY_STEPS);
    let a1 = f32(i + 1u) / f32(SKY_STEPS);
    let segment = (a1 * a1 - a0 * a0) * t_max;
    let p = origin + dir * (0.5 * (a0 * a0 + a1 * a1) * t_max);
    let h = length(p) - SKY_EARTH_R;
    let hr = exp(-h / SKY_H_R) * segment;
    let hm = exp(-h / SKY_H_M) * segment;
    // The optical depth to the sample's middle: half of its own segment.
    depth_r += 0.5 * hr;
    depth_m += 0.5 * hm;
    // The light ray to the sun; in the earth's shadow it brings nothing.
    let light_len = sky_exit(p, sun, SKY_ATMOSPHERE_R);
    let light_step = light_len / f32(SKY_LIGHT_STEPS);
    var light_r = 0.0;
    var light_m = 0.0;
    var lit = true;
    for (var j = 0u; j < SKY_LIGHT_STEPS; j++) {
      let q = p + sun * ((f32(j) + 0.5) * light_step);
      let hl = length(q) - SKY_EARTH_R;
      if (hl < 0.0) {
        lit = false;
        break;
      }
      light_r += exp(-hl / SKY_H_R) * light_step;
      light_m += exp(-hl / SKY_H_M) * light_step;
    }
    if (lit) {
      let tau = SKY_BETA_R * (depth_r + light_r) + SKY_BETA_M * 1.1 * (depth_m + light_m);
      let attenuation = exp(-tau);
      sum_r += attenuation * hr;
      sum_m += attenuation * hm;
    }
    depth_r += 0.5 * hr;
    depth_m += 0.5 * hm;
  }
  var color = sum_r * SKY_BETA_R * phase_r + sum_m * SKY_BETA_M * phase_m;
  // The sun's disc, dimmed by the air in front of it.
  if (mu > SKY_SUN_COS && mu_view >= 0.0) {
    color += exp(-(SKY_BETA_R * depth_r + SKY_BETA_M * 1.1 * depth_m)) * 50.0;
  }
  if (mu_view < 0.0) {
    color *= mix(1.0, 0.35, smoothstep(0.0, 0.3, -mu_view));
  }
  return color;
}

// The displayed sky colour at a pixel (framebuffer coordinates, origin top left).
fn sky_color(sky: Sky, pixel: vec2<f32>) -> vec3<f32> {
  let ndc = vec2<f32>(pixel.x / sky.view.x * 2.0 - 1.0, 1.0 - pixel.y / sky.view.y * 2.0);
  let p = sky.inv_view_proj * vec4<f32>(ndc, 1.0, 1.0);  // on the near plane
  let dir = normalize(p.xyz / p.w);
  let radiance = sky_radiance(dir, sky.sun.xyz, sky.up.xyz, sky.up.w) * sky.view.w;
  // Written as the display value (no further gamma), which keeps the blue saturated.
  return vec3<f32>(1.0) - exp(-radiance * sky.view.z);
}

// The background at a pixel: the sky when it is on, else the plain colour.
fn background_at(sky: Sky, plain: vec3<f32>, pixel: vec2<f32>) -> vec3<f32> {
  if (sky.sun.w == 0.0) {
    return plain;
  }
  return sky_color(sky, pixel);
}
