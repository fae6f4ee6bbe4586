// GeoJSON reading and writing over nlohmann::json. Every position is checked (two or three finite
// numbers) and every ring (closed, at least four positions) before it is used.
#include "stipple/io/geojson.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"

namespace stipple::io {

using nlohmann::json;

double GeoFeature::number(const std::string& key, double fallback) const {
  auto it = properties.find(key);
  if (it == properties.end()) return fallback;
  if (const double* d = std::get_if<double>(&it->second)) return *d;
  return fallback;
}

std::string GeoFeature::text(const std::string& key, const std::string& fallback) const {
  auto it = properties.find(key);
  if (it == properties.end()) return fallback;
  if (const std::string* s = std::get_if<std::string>(&it->second)) return *s;
  return fallback;
}

namespace {

constexpr uint64_t kMaxFileBytes = 256ull << 20;

struct Reader {
  const std::string& name;

  glm::dvec3 position(const json& p, const std::string& where) const {
    if (!p.is_array() || p.size() < 2 || p.size() > 4)
      fail("{}: {}: a position must be an array of 2 or 3 numbers", name, where);
    glm::dvec3 out(0.0, 0.0, std::numeric_limits<double>::quiet_NaN());
    for (size_t i = 0; i < std::min<size_t>(p.size(), 3); ++i) {
      if (!p[i].is_number()) fail("{}: {}: coordinate {} is not a number", name, where, i);
      out[int(i)] = p[i].get<double>();
      if (!std::isfinite(out[int(i)])) fail("{}: {}: coordinate {} is not finite", name, where, i);
    }
    return out;
  }

  std::vector<glm::dvec3> positions(const json& list, const std::string& where) const {
    if (!list.is_array()) fail("{}: {}: expected an array of positions", name, where);
    std::vector<glm::dvec3> out;
    out.reserve(list.size());
    for (size_t i = 0; i < list.size(); ++i)
      out.push_back(position(list[i], fmt::format("{} position {}", where, i)));
    return out;
  }

  std::vector<glm::dvec3> ring(const json& list, const std::string& where) const {
    std::vector<glm::dvec3> r = positions(list, where);
    if (r.size() < 4)
      fail("{}: {}: a ring needs at least 4 positions, has {}", name, where, r.size());
    if (r.front().x != r.back().x || r.front().y != r.back().y)
      fail("{}: {}: the ring is not closed (first and last positions differ)", name, where);
    return r;
  }

  void geometry(const json& g, GeoFeature& f, const std::string& where,
                std::vector<GeoFeature>& out, int depth) const {
    if (!g.is_object()) fail("{}: {}: a geometry must be an object", name, where);
    auto type_it = g.find("type");
    if (type_it == g.end() || !type_it->is_string())
      fail("{}: {}: the geometry has no \"type\"", name, where);
    const std::string type = type_it->get<std::string>();
    if (type == "GeometryCollection") {
      if (depth > 8) fail("{}: {}: geometry collections nested too deeply", name, where);
      auto members = g.find("geometries");
      if (members == g.end() || !members->is_array())
        fail("{}: {}: a GeometryCollection needs a \"geometries\" array", name, where);
      for (size_t i = 0; i < members->size(); ++i) {
        GeoFeature part;
        part.properties = f.properties;
        geometry((*members)[i], part, fmt::format("{} geometry {}", where, i), out, depth + 1);
      }
      return;
    }
    auto coords_it = g.find("coordinates");
    if (coords_it == g.end()) fail("{}: {}: the {} has no \"coordinates\"", name, where, type);
    const json& c = *coords_it;
    f.type = type;
    if (type == "Point") {
      f.parts.push_back({position(c, where)});
    } else if (type == "MultiPoint" || type == "LineString") {
      f.parts.push_back(positions(c, where));
      if (type == "LineString" && f.parts.back().size() < 2)
        fail("{}: {}: a LineString needs at least 2 positions", name, where);
    } else if (type == "MultiLineString") {
      if (!c.is_array()) fail("{}: {}: expected an array of lines", name, where);
      for (size_t i = 0; i < c.size(); ++i)
        f.parts.push_back(positions(c[i], fmt::format("{} line {}", where, i)));
    } else if (type == "Polygon") {
      if (!c.is_array() || c.empty())
        fail("{}: {}: a Polygon needs at least one ring", name, where);
      for (size_t i = 0; i < c.size(); ++i) {
        f.parts.push_back(ring(c[i], fmt::format("{} ring {}", where, i)));
        f.polygon_of_part.push_back(0);
      }
    } else if (type == "MultiPolygon") {
      if (!c.is_array()) fail("{}: {}: expected an array of polygons", name, where);
      for (size_t p = 0; p < c.size(); ++p) {
        if (!c[p].is_array() || c[p].empty())
          fail("{}: {} polygon {}: a polygon needs at least one ring", name, where, p);
        for (size_t i = 0; i < c[p].size(); ++i) {
          f.parts.push_back(ring(c[p][i], fmt::format("{} polygon {} ring {}", where, p, i)));
          f.polygon_of_part.push_back(uint32_t(p));
        }
      }
    } else {
      fail("{}: {}: unknown geometry type \"{}\"", name, where, type);
    }
    out.push_back(std::move(f));
  }

  void properties(const json& p, GeoFeature& f) const {
    if (!p.is_object()) return;
    for (auto it = p.begin(); it != p.end(); ++it) {
      const json& v = it.value();
      if (v.is_number()) {
        f.properties[it.key()] = v.get<double>();
      } else if (v.is_string()) {
        f.properties[it.key()] = v.get<std::string>();
      } else if (v.is_array()) {
        std::vector<double> numbers;
        bool all = true;
        for (const json& x : v) {
          if (!x.is_number()) {
            all = false;
            break;
          }
          numbers.push_back(x.get<double>());
        }
        if (all) f.properties[it.key()] = std::move(numbers);
      }
    }
  }

  void feature(const json& j, const std::string& where, std::vector<GeoFeature>& out) const {
    if (!j.is_object()) fail("{}: {}: a feature must be an object", name, where);
    GeoFeature f;
    if (auto p = j.find("properties"); p != j.end()) properties(*p, f);
    auto g = j.find("geometry");
    if (g == j.end()) fail("{}: {}: the feature has no \"geometry\"", name, where);
    if (g->is_null()) return;  // allowed by RFC 7946: an unlocated feature
    geometry(*g, f, where, out, 0);
  }
};

std::string clean_json_message(const std::string& what) {
  // nlohmann's messages start with "[json.exception.parse_error.101] ".
  const size_t bracket = what.find("] ");
  return bracket == std::string::npos ? what : what.substr(bracket + 2);
}

}  // namespace

GeoDocument parse_geojson(std::string_view text, const std::string& name) {
  json j;
  try {
    j = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {
    fail("{}: not valid GeoJSON: {}", name, clean_json_message(e.what()));
  }
  if (!j.is_object()) fail("{}: not valid GeoJSON: the top level must be an object", name);
  auto type_it = j.find("type");
  if (type_it == j.end() || !type_it->is_string())
    fail("{}: not valid GeoJSON: the top-level object has no \"type\"", name);
  Reader reader{name};
  GeoDocument doc;
  if (auto crs = j.find("crs"); crs != j.end() && crs->is_object()) {
    if (auto props = crs->find("properties"); props != crs->end() && props->is_object())
      if (auto n = props->find("name"); n != props->end() && n->is_string())
        doc.crs_name = n->get<std::string>();
  }
  const std::string type = type_it->get<std::string>();
  if (type == "FeatureCollection") {
    auto features = j.find("features");
    if (features == j.end() || !features->is_array())
      fail("{}: not valid GeoJSON: a FeatureCollection needs a \"features\" array", name);
    for (size_t i = 0; i < features->size(); ++i)
      reader.feature((*features)[i], fmt::format("feature {}", i), doc.features);
  } else if (type == "Feature") {
    reader.feature(j, "feature", doc.features);
  } else {
    GeoFeature f;
    reader.geometry(j, f, "geometry", doc.features, 0);
  }
  return doc;
}

GeoDocument read_geojson(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) fail("{}: no such file", name);
  if (std::filesystem::is_directory(path, ec)) fail("{}: is a directory, not a GeoJSON file", name);
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) fail("{}: cannot read: {}", name, ec.message());
  if (size > kMaxFileBytes)
    fail("{}: {} bytes is more than a GeoJSON file of clip polygons or measurements should be",
         name, size);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open: {}", name, std::strerror(errno));
  std::string text(static_cast<size_t>(size), '\0');
  in.read(text.data(), std::streamsize(size));
  if (!in) fail("{}: cannot read", name);
  return parse_geojson(text, name);
}

std::vector<GeoPolygon> geojson_polygons(const GeoDocument& doc, const std::string& name) {
  std::vector<GeoPolygon> out;
  for (const GeoFeature& f : doc.features) {
    if (f.type != "Polygon" && f.type != "MultiPolygon") continue;
    const double min_z = f.number("min_z", -1e300), max_z = f.number("max_z", 1e300);
    if (!(min_z <= max_z))
      fail("{}: a polygon's min_z {} exceeds its max_z {}", name, min_z, max_z);
    uint32_t current = ~0u;
    for (size_t i = 0; i < f.parts.size(); ++i) {
      if (f.polygon_of_part[i] != current) {
        current = f.polygon_of_part[i];
        out.push_back({});
        out.back().min_z = min_z;
        out.back().max_z = max_z;
      }
      std::vector<glm::dvec2> ring;
      // The closing position repeats the first: dropped.
      for (size_t k = 0; k + 1 < f.parts[i].size(); ++k)
        ring.emplace_back(f.parts[i][k].x, f.parts[i][k].y);
      out.back().rings.push_back(std::move(ring));
    }
  }
  if (out.empty()) fail("{}: holds no Polygon or MultiPolygon geometry", name);
  return out;
}

std::vector<GeoPolygon> read_geojson_polygons(const std::filesystem::path& path) {
  return geojson_polygons(read_geojson(path), path.string());
}

namespace {

json position_json(const glm::dvec3& p) {
  // Full double precision (17 significant digits) so coordinates round trip exactly.
  json a = json::array({p.x, p.y});
  if (!std::isnan(p.z)) a.push_back(p.z);
  return a;
}

}  // namespace

std::string geojson_text(const std::vector<GeoFeature>& features, int epsg) {
  json doc = {{"type", "FeatureCollection"}, {"features", json::array()}};
  if (epsg > 0)
    doc["crs"] = {{"type", "name"},
                  {"properties", {{"name", fmt::format("urn:ogc:def:crs:EPSG::{}", epsg)}}}};
  for (const GeoFeature& f : features) {
    json props = json::object();
    for (const auto& [key, value] : f.properties)
      std::visit([&, &k = key](const auto& v) { props[k] = v; }, value);
    json coords;
    auto line = [&](const std::vector<glm::dvec3>& part) {
      json a = json::array();
      for (const glm::dvec3& p : part) a.push_back(position_json(p));
      return a;
    };
    if (f.type == "Point") {
      coords = position_json(f.parts.at(0).at(0));
    } else if (f.type == "LineString" || f.type == "MultiPoint") {
      coords = line(f.parts.at(0));
    } else if (f.type == "MultiLineString" || f.type == "Polygon") {
      coords = json::array();
      for (const auto& part : f.parts) coords.push_back(line(part));
    } else if (f.type == "MultiPolygon") {
      coords = json::array();
      for (size_t i = 0; i < f.parts.size(); ++i) {
        const uint32_t polygon = i < f.polygon_of_part.size() ? f.polygon_of_part[i] : 0;
        while (coords.size() <= polygon) coords.push_back(json::array());
        coords[polygon].push_back(line(f.parts[i]));
      }
    } else {
      fail("cannot write a GeoJSON geometry of type \"{}\"", f.type);
    }
    doc["features"].push_back({{"type", "Feature"},
                               {"properties", props},
                               {"geometry", {{"type", f.type}, {"coordinates", coords}}}});
  }
  return doc.dump(2) + "\n";
}

void write_geojson(const std::filesystem::path& path, const std::vector<GeoFeature>& features,
                   int epsg) {
  write_file_atomically(path, geojson_text(features, epsg));
}

}  // namespace stipple::io
