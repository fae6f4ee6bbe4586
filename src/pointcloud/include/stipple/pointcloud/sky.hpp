#pragma once
// The Nishita sky behind the points (shaders/sky.wgsl): settings and the uniforms both render
// paths append to theirs (the billboards' Frame, the compute rasterizer's Params). Where no
// point was drawn, the resolve and display passes show the single-scattered sky for the sun's
// direction instead of the background colour; with the sky off (the default) nothing changes.
// The sun is given as azimuth and elevation in the data's local frame (Z-up east-north-up, as
// world +X, +Y, -Z); stipple/math/sun.hpp's solar_position turns a date, time and place into them.
#include <cstdint>

#include "stipple/math/camera.hpp"

namespace stipple::pc {

struct SkySettings {
  bool enabled = false;
  double sun_azimuth_deg = 180.0;   // clockwise from north
  double sun_elevation_deg = 45.0;  // above the horizon
  // Tone mapping 1 - exp(-exposure * radiance), written as the display value; with
  // sun_intensity 20 (the usual choice of implementations of the model) and exposure 2 noon
  // gives a mid blue overhead (about 80, 110, 157 of 255) and a pale blue-white horizon.
  float exposure = 2.0f;
  float sun_intensity = 20.0f;
  float observer_height_m = 100.0f;  // above the ground, for the atmosphere's density
};

// Mirrors `Sky` in sky.wgsl (112 bytes).
struct SkyUniforms {
  float inv_view_proj[16];
  float sun[4];
  float up[4];
  float view[4];
};
static_assert(sizeof(SkyUniforms) == 112);

// The uniforms for a frame: `view_proj` is the rotation-only view-projection the passes use
// (camera-relative), inverted here in double; `sun.w` is 0 when the sky is off.
SkyUniforms sky_uniforms(const SkySettings& sky, const glm::dmat4& view_proj, uint32_t width,
                         uint32_t height);

}  // namespace stipple::pc
