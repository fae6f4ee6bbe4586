#pragma once
// GeoJSON (RFC 7946) features in and out, for clip polygons and saved measurements. Coordinates
// are taken as they are written: stipple reads and writes them in the point cloud's own CRS (a
// projected CRS's units), as GIS tools do with a "crs" member, not reprojected to WGS84.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace stipple::io {

using GeoValue = std::variant<double, std::string, std::vector<double>>;

struct GeoFeature {
  // "Point", "MultiPoint", "LineString", "MultiLineString", "Polygon" or "MultiPolygon".
  std::string type;
  // Point: one part of one position; MultiPoint and LineString: one part; MultiLineString: a
  // part per line; Polygon: a part per ring (exterior first); MultiPolygon: every polygon's
  // rings, polygon_of_part saying which polygon each belongs to. Missing Z is NaN.
  std::vector<std::vector<glm::dvec3>> parts;
  std::vector<uint32_t> polygon_of_part;
  // Properties whose values are numbers, strings or arrays of numbers (others are skipped).
  std::map<std::string, GeoValue> properties;

  double number(const std::string& key, double fallback) const;
  std::string text(const std::string& key, const std::string& fallback = {}) const;
};

struct GeoDocument {
  std::vector<GeoFeature> features;
  std::string crs_name;  // the "crs" member's name (e.g. "urn:ogc:def:crs:EPSG::2992"), if any
};

// Parses a FeatureCollection, a Feature or a bare geometry (GeometryCollections are flattened).
// Throws stipple::Error "<name>: ..." naming what is wrong (not JSON, not GeoJSON, a bad
// position or ring) and where.
GeoDocument parse_geojson(std::string_view text, const std::string& name);
GeoDocument read_geojson(const std::filesystem::path& path);

// An extruded polygon for clipping: rings in X/Y (exterior first, then holes; a point is inside
// by the even-odd rule over all rings) and a Z range (infinite unless the feature's properties
// give "min_z"/"max_z").
struct GeoPolygon {
  std::vector<std::vector<glm::dvec2>> rings;
  double min_z = -1e300, max_z = 1e300;
};

// The Polygon and MultiPolygon geometries of a GeoJSON file; a file without any is an error.
std::vector<GeoPolygon> read_geojson_polygons(const std::filesystem::path& path);
std::vector<GeoPolygon> geojson_polygons(const GeoDocument& document, const std::string& name);

// Writes a FeatureCollection atomically; `epsg` > 0 adds a "crs" member naming it.
void write_geojson(const std::filesystem::path& path, const std::vector<GeoFeature>& features,
                   int epsg);
std::string geojson_text(const std::vector<GeoFeature>& features, int epsg);

}  // namespace stipple::io
