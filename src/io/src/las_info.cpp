// The header of a LAS/LAZ/COPC file as JSON (`stipple info --json`, stipple.info in Python).
#include <string>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/io/las.hpp"

namespace stipple::io {
namespace {

// -0 (some writers store it for a zero offset) printed as 0.
glm::dvec3 no_negative_zero(glm::dvec3 v) {
  for (int i = 0; i < 3; ++i)
    if (v[i] == 0.0) v[i] = 0.0;
  return v;
}

}  // namespace

// An Extra Bytes descriptor's type (LAS 1.4 R15 table 25), e.g. "uint16", "float64[3]".
std::string extra_bytes_type_name(const ExtraBytesDescriptor& e) {
  static constexpr const char* kScalars[10] = {"uint8", "int8",   "uint16", "int16",   "uint32",
                                               "int32", "uint64", "int64",  "float32", "float64"};
  if (e.data_type == 0) return fmt::format("{} bytes", e.options);
  if (e.data_type > 30) return fmt::format("type {}", e.data_type);
  const int count = (e.data_type - 1) / 10 + 1;
  const char* scalar = kScalars[(e.data_type - 1) % 10];
  return count == 1 ? std::string(scalar) : fmt::format("{}[{}]", scalar, count);
}

std::string las_header_json(const LasHeader& h) {
  nlohmann::json j;
  j["file"] = h.path;
  j["version"] = fmt::format("{}.{}", h.version_major, h.version_minor);
  j["point_format"] = h.point_format;
  j["point_record_length"] = h.point_record_length;
  j["compressed"] = h.compressed;
  j["copc"] = h.copc;
  j["point_count"] = h.point_count;
  j["points_by_return"] = h.points_by_return;
  for (auto [key, v] : {std::pair{"scale", h.scale}, std::pair{"offset", h.offset},
                        std::pair{"min", h.min}, std::pair{"max", h.max}}) {
    v = no_negative_zero(v);
    j[key] = {v.x, v.y, v.z};
  }
  j["system_identifier"] = h.system_identifier;
  j["generating_software"] = h.generating_software;
  j["creation"] = {{"day", h.creation_day}, {"year", h.creation_year}};
  j["rgb_bits"] = h.has_rgb ? h.rgb_bits : 0;
  j["has_gps_time"] = h.has_gps_time;
  j["has_nir"] = h.has_nir;
  j["extra_bytes_per_point"] = h.extra_bytes_per_point;
  nlohmann::json crs;
  crs["epsg"] = h.crs.epsg;
  crs["vertical_epsg"] = h.crs.vertical_epsg;
  crs["name"] = h.crs.name;
  crs["geographic"] = h.crs.geographic;
  crs["wkt"] = h.crs.wkt;
  crs["geokeys"] = h.crs.geokeys.size();
  crs["source"] = h.crs.source == Crs::Source::Wkt       ? "wkt"
                  : h.crs.source == Crs::Source::GeoTiff ? "geotiff"
                                                         : "none";
  crs["linear_unit"] = h.crs.linear_unit;
  crs["description"] = h.crs.describe();
  if (!h.crs.conflict.empty()) crs["conflict"] = h.crs.conflict;
  if (const std::string problem = geographic_bounds_problem(h); !problem.empty())
    crs["problem"] = problem;
  j["crs"] = crs;
  nlohmann::json vlrs = nlohmann::json::array();
  for (const auto& v : h.vlrs)
    vlrs.push_back({{"user_id", v.user_id},
                    {"record_id", v.record_id},
                    {"description", v.description},
                    {"bytes", v.data.size()}});
  for (const auto& v : h.evlrs)
    vlrs.push_back({{"user_id", v.user_id},
                    {"record_id", v.record_id},
                    {"description", v.description},
                    {"bytes", v.data.size()},
                    {"extended", true}});
  j["vlrs"] = vlrs;
  nlohmann::json extra = nlohmann::json::array();
  for (const auto& e : h.extra_bytes)
    extra.push_back({{"name", e.name},
                     {"data_type", e.data_type},
                     {"type", extra_bytes_type_name(e)},
                     {"bytes", e.size}});
  j["extra_bytes"] = extra;
  return j.dump();
}

}  // namespace stipple::io
