#pragma once
// WGS84 geodesy in double precision: geodetic <-> ECEF and local east-north-up frames.
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

namespace stipple::geo {

inline constexpr double kWgs84A = 6378137.0;
inline constexpr double kWgs84F = 1.0 / 298.257223563;

// lon, lat in degrees, height in metres above the ellipsoid.
glm::dvec3 geodetic_to_ecef(const glm::dvec3& lon_lat_h);
glm::dvec3 ecef_to_geodetic(const glm::dvec3& ecef);
// Columns: east, north, up unit vectors in ECEF at that longitude/latitude (degrees).
glm::dmat3 enu_basis(double lon_deg, double lat_deg);

// Maps geodetic coordinates to a local metric ENU frame anchored at an origin.
struct LocalEnu {
  glm::dvec3 origin_ecef;
  glm::dmat3 basis;  // ENU -> ECEF
  explicit LocalEnu(const glm::dvec3& origin_lon_lat_h);
  glm::dvec3 from_geodetic(const glm::dvec3& lon_lat_h) const;
  glm::dvec3 to_geodetic(const glm::dvec3& enu) const;  // the inverse of from_geodetic
};

}  // namespace stipple::geo
