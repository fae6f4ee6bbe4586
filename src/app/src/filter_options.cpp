#include "stipple/app/filter_options.hpp"

#include <cmath>

#include "stipple/core/error.hpp"
#include "stipple/io/geojson.hpp"

namespace stipple::app {
namespace {

// A flag parsed by `apply` as it is read: stipple::Error becomes a CLI validation error (the
// message names the flag and the problem; the exit code is non-zero).
template <typename Apply>
CLI::Option* add_parsed(CLI::App* cmd, const std::string& names, const std::string& help,
                        Apply apply) {
  return cmd->add_option_function<std::string>(
      names,
      [apply](const std::string& text) {
        try {
          apply(text);
        } catch (const Error& e) {
          throw CLI::ValidationError(e.what());
        }
      },
      help);
}

// The same for a flag that may be repeated: `apply` sees each value.
template <typename Apply>
CLI::Option* add_parsed_list(CLI::App* cmd, const std::string& names, const std::string& help,
                             Apply apply) {
  return cmd->add_option_function<std::vector<std::string>>(
      names,
      [apply](const std::vector<std::string>& texts) {
        try {
          for (const std::string& t : texts) apply(t);
        } catch (const Error& e) {
          throw CLI::ValidationError(e.what());
        }
      },
      help);
}

}  // namespace

void add_filter_options(CLI::App* cmd, FilterArgs& a, FilterFlags flags) {
  const bool render = flags == FilterFlags::Render;
  add_parsed(cmd, "--classes", "Keep only these ASPRS classes: '2,6' or ranges '2-5,9' (0-255)",
             [&a](const std::string& t) { a.filter.classes = pc::parse_classes(t, "--classes"); });
  add_parsed(cmd, "--returns",
             "Keep only these returns: first, last, single, intermediate (comma-separated: any of "
             "them)",
             [&a](const std::string& t) { a.filter.returns = pc::parse_returns(t, "--returns"); });
  const std::string intensity =
      render ? "--intensity-filter" : "--intensity-range,--intensity-filter";
  add_parsed(
      cmd, intensity, "Keep only intensities in 'min,max' (inclusive)",
      [&a](const std::string& t) { a.filter.intensity = pc::parse_range(t, "intensity filter"); });
  add_parsed(
      cmd, "--gps-time-range", "Keep only GPS times in 'min,max' (inclusive, seconds)",
      [&a](const std::string& t) { a.filter.gps_time = pc::parse_range(t, "--gps-time-range"); });
  add_parsed(cmd, "--point-source-range", "Keep only point source IDs in 'min,max' (inclusive)",
             [&a](const std::string& t) {
               const glm::dvec2 r = pc::parse_range(t, "--point-source-range");
               if (r.x < 0 || r.y > 65535)
                 fail("--point-source-range '{}': point source IDs are 0-65535", t);
               a.filter.point_source = r;
             });
  const std::string prefix = render ? "--clip-" : "--";
  add_parsed_list(
      cmd, prefix + "box",
      "Box 'minx,miny,minz,maxx,maxy,maxz[,yaw_degrees]' in the source CRS's units (Z up; "
      "yaw turns it about its centre, counter-clockwise); repeat for several",
      [&a, prefix](const std::string& t) {
        a.boxes.push_back(pc::parse_box(t, (prefix + "box").c_str()));
      });
  cmd->add_option(prefix + "polygon", a.polygon_files,
                  "GeoJSON file of Polygon/MultiPolygon geometries in the source CRS, extruded "
                  "vertically (a feature's min_z/max_z properties bound it)");
  add_parsed_list(cmd, prefix + "plane",
                  "Half-space 'a,b,c,d': keep a*x + b*y + c*z + d >= 0; repeat for several",
                  [&a, prefix](const std::string& t) {
                    a.planes.push_back(pc::parse_plane(t, (prefix + "plane").c_str()));
                  });
  if (render)
    add_parsed(cmd, "--clip-mode",
               "inside (show the region's points), outside (the others) or highlight (all, the "
               "region's tinted)",
               [&a](const std::string& t) { a.mode = pc::parse_clip_mode(t); })
        ->check(CLI::IsMember({"inside", "outside", "highlight"}));
}

}  // namespace stipple::app
