// The parts of the CRS code that need no PROJ (the web build has the CRS module without it).
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "stipple/io/las.hpp"

namespace stipple::io {

std::string Crs::describe() const {
  if (empty()) return blank_wkt ? "none (the WKT VLR holds no text)" : "none";
  std::string s = epsg ? fmt::format("EPSG:{}", epsg) : std::string("custom CRS");
  if (!name.empty()) s += fmt::format(" ({})", name);
  if (vertical_epsg) s += fmt::format(" + vertical EPSG:{}", vertical_epsg);
  if (geographic) {
    s += ", geographic degrees";
  } else if (!linear_unit.empty()) {
    s += fmt::format(", unit {}", linear_unit);
  }
  if (source == Source::GeoTiff && !wkt.empty()) s += " (from the GeoTIFF keys)";
  return s;
}

std::string geographic_bounds_problem(const LasHeader& h) {
  if (!h.crs.geographic) return {};
  const double lat = std::max(std::abs(h.min.y), std::abs(h.max.y));
  const double lon = std::max(std::abs(h.min.x), std::abs(h.max.x));
  // A hair past the limits is rounding of a scaled integer; anything more is not degrees.
  if (lat <= 90.0 + 1e-6 && lon <= 360.0 + 1e-6) return {};
  return fmt::format(
      "{}: the CRS ({}) is geographic, but the coordinates reach {} {:.7g}, beyond +-{}: they "
      "are not longitude/latitude (is the CRS wrong?)",
      h.path, h.crs.epsg ? fmt::format("EPSG:{}", h.crs.epsg) : h.crs.name,
      lat > 90.0 + 1e-6 ? "latitude" : "longitude", lat > 90.0 + 1e-6 ? lat : lon,
      lat > 90.0 + 1e-6 ? 90 : 360);
}

}  // namespace stipple::io
