#include "stipple/app/point_options.hpp"

#include <cmath>
#include <stdexcept>

#include "stipple/core/error.hpp"

namespace stipple::app {

namespace {
// A flag whose value is a comma-separated list, parsed straight into the settings; errors come
// out as CLI validation errors (exit code and message like every other bad flag).
template <typename Apply>
void add_list_option(CLI::App* cmd, const char* name, size_t count, const char* help,
                     std::string default_text, Apply apply) {
  cmd->add_option_function<std::string>(
         name,
         [name, count, apply](const std::string& text) {
           try {
             apply(parse_numbers(text, count, name));
           } catch (const Error& e) {
             throw CLI::ValidationError(e.what());
           }
         },
         help)
      ->default_str(std::move(default_text));
}
}  // namespace

void add_point_render_options(CLI::App* cmd, pc::PointRenderSettings& s) {
  cmd->add_option_function<std::string>(
         "--color", [&s](const std::string& v) { s.color = pc::parse_color_mode(v); },
         "Colour by: auto (rgb when present, else elevation), rgb, intensity, classification, "
         "elevation, return, constant")
      ->check(CLI::IsMember(
          {"auto", "rgb", "intensity", "classification", "elevation", "return", "constant"}))
      ->default_str("auto");
  add_list_option(cmd, "--constant-color", 3, "Colour of --color constant, 'r,g,b' in 0..1",
                  "1,1,1", [&s](const std::vector<double>& v) {
                    s.constant_color = glm::vec3(float(v[0]), float(v[1]), float(v[2]));
                  });
  add_list_option(cmd, "--elevation-range", 2,
                  "Elevation ramp 'min,max' in the data's Z units (default: the 2nd-98th "
                  "percentile of the data)",
                  "from data", [&s](const std::vector<double>& v) {
                    if (!(v[1] > v[0])) fail("--elevation-range: max must exceed min");
                    s.elevation_range = {v[0], v[1]};
                  });
  add_list_option(cmd, "--intensity-range", 2,
                  "Intensity grey ramp 'min,max' (default: the 2nd-98th percentile)", "from data",
                  [&s](const std::vector<double>& v) {
                    if (!(v[1] > v[0])) fail("--intensity-range: max must exceed min");
                    s.intensity_range = {v[0], v[1]};
                  });
  add_list_option(cmd, "--background", 3, "Background colour 'r,g,b' in 0..1", "0.07,0.08,0.1",
                  [&s](const std::vector<double>& v) {
                    s.background = glm::vec3(float(v[0]), float(v[1]), float(v[2]));
                  });
  cmd->add_flag_callback(
      "--sky", [&s] { s.sky.enabled = true; },
      "Draw a Nishita sky (single-scattered Rayleigh and Mie light) behind the points instead of "
      "the background colour; the sun from --sun or --sun-time (default azimuth 180, "
      "elevation 45)");
  add_list_option(cmd, "--sun", 2,
                  "The sky's sun as 'azimuth,elevation' in degrees (azimuth clockwise from north "
                  "in the data's frame, elevation above the horizon); implies --sky",
                  "180,45", [&s](const std::vector<double>& v) {
                    if (v[1] < -90 || v[1] > 90) fail("--sun: elevation must be in -90..90");
                    s.sky.enabled = true;
                    s.sky.sun_azimuth_deg = v[0];
                    s.sky.sun_elevation_deg = v[1];
                  });
  cmd->add_option("--sky-exposure", s.sky.exposure,
                  "The sky's exposure (tone mapping 1 - exp(-exposure * radiance))")
      ->check(CLI::Range(0.01f, 100.0f))
      ->capture_default_str();
  cmd->add_option("--point-size", s.point_size,
                  "Fixed point size in pixels (default: from the data's density)")
      ->check(CLI::Range(0.0f, 64.0f));
  cmd->add_option_function<std::string>(
         "--point-size-mode",
         [&s](const std::string& v) { s.size_mode = pc::parse_point_size_mode(v); },
         "fixed (pixels), attenuated (world size from the point spacing, shrinks with distance) "
         "or adaptive (attenuated, grown where CLOD thinned the points)")
      ->check(CLI::IsMember({"fixed", "attenuated", "adaptive"}))
      ->default_str("fixed");
  cmd->add_option("--size-scale", s.size_scale,
                  "Attenuated/adaptive: point diameter in multiples of the point spacing")
      ->check(CLI::Range(0.01f, 100.0f))
      ->capture_default_str();
  cmd->add_option("--clod-k", s.clod_k,
                  "Continuous LOD quality factor k (s_target = distance * k); smaller keeps "
                  "more points; 0 = off")
      ->check(CLI::Range(0.0f, 10.0f))
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         "--splat", [&s](const std::string& v) { s.splat = pc::parse_splat_mode(v); },
         "naive (nearest point wins) or blend (depth pre-pass, weighted accumulation, "
         "normalisation)")
      ->check(CLI::IsMember({"naive", "blend"}))
      ->default_str("blend");
  cmd->add_option("--blend-depth", s.blend_depth,
                  "Blend: fragments within this fraction of their depth behind the nearest blend")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str();
  cmd->add_flag_callback(
      "--no-edl", [&s] { s.edl = false; }, "Turn eye-dome lighting off");
  cmd->add_option("--edl-radius", s.edl_radius, "Eye-dome lighting: neighbour distance, pixels")
      ->check(CLI::Range(0.5f, 16.0f))
      ->capture_default_str();
  cmd->add_option("--edl-strength", s.edl_strength,
                  "Eye-dome lighting: k of s = exp(-mean response * k)")
      ->check(CLI::Range(0.0f, 10000.0f))
      ->capture_default_str();
}

}  // namespace stipple::app
