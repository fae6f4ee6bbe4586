#include "stipple/math/geo.hpp"

#include <cmath>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

namespace stipple::geo {
namespace {
constexpr double kE2 = kWgs84F * (2.0 - kWgs84F);  // first eccentricity squared
}

glm::dvec3 geodetic_to_ecef(const glm::dvec3& llh) {
  double lon = glm::radians(llh.x), lat = glm::radians(llh.y);
  double s = std::sin(lat), c = std::cos(lat);
  double n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);
  return {(n + llh.z) * c * std::cos(lon), (n + llh.z) * c * std::sin(lon),
          (n * (1.0 - kE2) + llh.z) * s};
}

glm::dvec3 ecef_to_geodetic(const glm::dvec3& p) {
  // Bowring's iteration converges to sub-millimetre in a few steps for terrestrial points.
  double lon = std::atan2(p.y, p.x);
  double r = std::hypot(p.x, p.y);
  double lat = std::atan2(p.z, r * (1.0 - kE2));
  double h = 0.0;
  for (int i = 0; i < 6; ++i) {
    double s = std::sin(lat);
    double n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);
    h = r / std::cos(lat) - n;
    lat = std::atan2(p.z, r * (1.0 - kE2 * n / (n + h)));
  }
  return {glm::degrees(lon), glm::degrees(lat), h};
}

glm::dmat3 enu_basis(double lon_deg, double lat_deg) {
  double lon = glm::radians(lon_deg), lat = glm::radians(lat_deg);
  glm::dvec3 east(-std::sin(lon), std::cos(lon), 0.0);
  glm::dvec3 north(-std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat));
  glm::dvec3 up(std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat));
  return glm::dmat3(east, north, up);
}

LocalEnu::LocalEnu(const glm::dvec3& origin)
    : origin_ecef(geodetic_to_ecef(origin)), basis(enu_basis(origin.x, origin.y)) {}

glm::dvec3 LocalEnu::from_geodetic(const glm::dvec3& llh) const {
  // basis is orthonormal, so its transpose maps ECEF offsets into ENU.
  return glm::transpose(basis) * (geodetic_to_ecef(llh) - origin_ecef);
}

glm::dvec3 LocalEnu::to_geodetic(const glm::dvec3& enu) const {
  return ecef_to_geodetic(origin_ecef + basis * enu);
}

}  // namespace stipple::geo
