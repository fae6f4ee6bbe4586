#include "stipple/io/ept.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <tuple>

#include <fmt/format.h>
#include <zstd.h>
#include <nlohmann/json.hpp>

#include "batch_content.hpp"
#include "json_fields.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/las.hpp"

namespace stipple::io {
namespace {

using json = nlohmann::json;

struct Key {
  int32_t d = 0, x = 0, y = 0, z = 0;
  std::string str() const { return fmt::format("{}-{}-{}-{}", d, x, y, z); }
  auto operator<=>(const Key&) const = default;
};

bool parse_key(const std::string& s, Key* k) {
  char tail = 0;
  return std::sscanf(s.c_str(), "%d-%d-%d-%d%c", &k->d, &k->x, &k->y, &k->z, &tail) == 4;
}

Tile node_tile(const EptCloud& c, const Key& k) {
  const double n = std::ldexp(1.0, k.d);
  const glm::dvec3 size = (c.cube_max - c.cube_min) / n;
  const glm::dvec3 centre = c.cube_min + size * (glm::dvec3(k.x, k.y, k.z) + 0.5);
  Tile t;
  t.volume.kind = BoundingVolume::Kind::Box;
  t.volume.box = {centre.x, centre.y,   centre.z, size.x / 2, 0, 0,
                  0,        size.y / 2, 0,        0,          0, size.z / 2};
  t.box = obb_of(t.volume, t.transform);
  t.geometric_error = c.spacing / n;
  t.refine = Refine::Add;
  return t;
}

std::string hierarchy_uri(const EptCloud& c, const Key& k) {
  return resolve_uri(c.uri, "ept-hierarchy/" + k.str() + ".json");
}

std::string data_uri(const EptCloud& c, const Key& k, int64_t points) {
  const char* ext = c.data_type == "laszip" ? "laz" : c.data_type == "binary" ? "bin" : "zst";
  return fmt::format("{}#points={}&key={}", resolve_uri(c.uri, "ept-data/" + k.str() + "." + ext),
                     points, k.str());
}

std::shared_ptr<PendingChildren> hierarchy_pending(std::shared_ptr<const EptCloud> c,
                                                   const Key& k) {
  auto p = std::make_shared<PendingChildren>();
  p->kind = PendingChildren::Kind::EptHierarchy;
  p->uris = {hierarchy_uri(*c, k)};
  p->refine = Refine::Add;
  p->level = uint32_t(k.d), p->x = uint32_t(k.x), p->y = uint32_t(k.y), p->z = uint32_t(k.z);
  p->ept = std::move(c);
  return p;
}

glm::dvec3 bounds_part(const json& j, const char* key, int part, const std::string& uri) {
  const json& a = j.contains(key) ? j[key] : json();
  if (!a.is_array() || a.size() != 6) fail("{}: {} is not six numbers", uri, key);
  glm::dvec3 v;
  for (int k = 0; k < 3; ++k) {
    if (!a[size_t(part * 3 + k)].is_number()) fail("{}: {} holds a non-number", uri, key);
    v[k] = a[size_t(part * 3 + k)].get<double>();
    if (!std::isfinite(v[k])) fail("{}: {} is not finite", uri, key);
  }
  return v;
}

double read_dimension(const uint8_t* p, const EptDimension& d) {
  auto get = [p](auto v) {
    std::memcpy(&v, p, sizeof(v));
    return double(v);
  };
  double v = 0;
  if (d.type == "float") {
    v = d.size == 4 ? get(float{}) : get(double{});
  } else if (d.type == "signed") {
    v = d.size == 1   ? get(int8_t{})
        : d.size == 2 ? get(int16_t{})
        : d.size == 4 ? get(int32_t{})
                      : get(int64_t{});
  } else {
    v = d.size == 1   ? get(uint8_t{})
        : d.size == 2 ? get(uint16_t{})
        : d.size == 4 ? get(uint32_t{})
                      : get(uint64_t{});
  }
  return d.scaled ? v * d.scale + d.offset : v;
}

// ept.json's fields in the 1.0 layout into `c` (after the version).
void parse_ept_layout(const json& j, EptCloud& c);

}  // namespace

bool is_ept_input(const std::string& uri) {
  const std::string p = uri_path(uri);
  const size_t slash = p.find_last_of('/');
  return p.substr(slash == std::string::npos ? 0 : slash + 1) == "ept.json";
}

std::shared_ptr<const EptCloud> parse_ept_metadata(std::span<const uint8_t> bytes,
                                                   const std::string& uri) {
  json j = json_fields::metadata_object(bytes, uri);
  auto cloud = std::make_shared<EptCloud>();
  EptCloud& c = *cloud;
  c.uri = uri;
  // Early Entwine builds wrote "0.0.0" over the 1.0 layout: read where the layout is 1.0's (the
  // loader warns once), a clear error where it is not.
  std::string version;
  try {
    version = j.value("version", "1.0.0");
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed ept.json: {}", uri, e.what());
  }
  const bool before_1 = version.rfind("0.", 0) == 0;
  if (!before_1 && version.rfind("1.", 0) != 0)
    fail("{}: EPT version '{}' is not 1.x (nor a 0.x in the 1.0 layout)", uri, version);
  c.version = version;
  try {
    parse_ept_layout(j, c);
  } catch (const Error& e) {
    if (!before_1) throw;
    std::string why = e.what();
    if (why.rfind(uri + ": ", 0) == 0) why = why.substr(uri.size() + 2);
    fail(
        "{}: EPT version '{}' is from before 1.0 and is read only in the 1.0 layout, which this "
        "is not: {}",
        uri, version, why);
  }
  return cloud;
}

namespace {

void parse_ept_layout(const json& j, EptCloud& c) {
  const std::string& uri = c.uri;
  try {
    c.data_type = j.value("dataType", "");
    if (c.data_type != "laszip" && c.data_type != "binary" && c.data_type != "zstandard")
      fail("{}: dataType '{}' is not laszip, binary or zstandard", uri, c.data_type);
    if (j.value("hierarchyType", "json") != "json")
      fail("{}: hierarchyType '{}' is not json", uri, j.value("hierarchyType", ""));
    if (!j.contains("points") || !j["points"].is_number_unsigned())
      fail("{}: points is missing or not a count", uri);
    c.points = j["points"].get<uint64_t>();
    c.cube_min = bounds_part(j, "bounds", 0, uri);
    c.cube_max = bounds_part(j, "bounds", 1, uri);
    if (!(c.cube_max.x > c.cube_min.x && c.cube_max.y > c.cube_min.y &&
          c.cube_max.z > c.cube_min.z))
      fail("{}: bounds are empty", uri);
    c.data_min = c.cube_min, c.data_max = c.cube_max;
    if (j.contains("boundsConforming")) {
      c.data_min = bounds_part(j, "boundsConforming", 0, uri);
      c.data_max = bounds_part(j, "boundsConforming", 1, uri);
    }
    c.span = int(json_fields::integer(j, "span", json_fields::integer(j, "ticks", 0, uri), uri));
    if (c.span < 1 || c.span > (1 << 20)) fail("{}: span {} is not a grid size", uri, c.span);
    c.spacing = (c.cube_max.x - c.cube_min.x) / c.span;
    if (j.contains("srs") && j["srs"].is_object()) c.wkt = j["srs"].value("wkt", "");
    const json& schema = j.value("schema", json::array());
    if (!schema.is_array() || schema.empty()) fail("{}: schema is missing", uri);
    bool xyz[3] = {false, false, false};
    for (const auto& d : schema) {
      EptDimension dim;
      dim.name = d.value("name", "");
      dim.type = d.value("type", "");
      dim.size = int(json_fields::integer(d, "size", 0, uri));
      const bool ok = (dim.type == "float" && (dim.size == 4 || dim.size == 8)) ||
                      ((dim.type == "signed" || dim.type == "unsigned") &&
                       (dim.size == 1 || dim.size == 2 || dim.size == 4 || dim.size == 8));
      if (!ok) fail("{}: dimension '{}' is {} of {} bytes", uri, dim.name, dim.type, dim.size);
      if (d.contains("scale")) {
        dim.scale = d.value("scale", 1.0);
        dim.offset = d.value("offset", 0.0);
        dim.scaled = true;
        if (!(std::isfinite(dim.scale) && dim.scale != 0 && std::isfinite(dim.offset)))
          fail("{}: dimension '{}' has scale {} offset {}", uri, dim.name, dim.scale, dim.offset);
      }
      dim.at = c.record_size;
      c.record_size += size_t(dim.size);
      for (int k = 0; k < 3; ++k) xyz[k] = xyz[k] || dim.name == std::string(1, char('X' + k));
      c.schema.push_back(std::move(dim));
    }
    if (!xyz[0] || !xyz[1] || !xyz[2]) fail("{}: the schema lacks X, Y or Z", uri);
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed ept.json: {}", uri, e.what());
  }
}

}  // namespace

Expansion read_ept_hierarchy(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                             const Fetcher& fetcher, const TilesetOptions& options) {
  Expansion e;
  e.tile = tile;
  const Key root{int32_t(pending.level), int32_t(pending.x), int32_t(pending.y),
                 int32_t(pending.z)};
  const std::string name = pending.uris.empty() ? "?" : pending.uris[0];
  try {
    if (!pending.ept || pending.uris.size() != 1) fail("a hierarchy file without its dataset");
    const EptCloud& c = *pending.ept;
    const std::vector<uint8_t> bytes = fetcher(pending.uris[0]);
    if (bytes.size() > options.max_json_bytes) fail("{}: hierarchy file too large", name);
    json j = json::parse(bytes.begin(), bytes.end(), nullptr, false);
    if (!j.is_object()) fail("{}: a hierarchy file must be a JSON object", name);
    std::vector<std::pair<Key, int64_t>> entries;
    for (const auto& [text, count] : j.items()) {
      Key k;
      if (!parse_key(text, &k)) fail("{}: '{}' is not a D-X-Y-Z key", name, text);
      if (k.d < 0 || k.d > kMaxEptDepth)
        fail("{}: key {} is deeper than {}", name, text, kMaxEptDepth);
      const int64_t cells = int64_t(1) << k.d;
      if (k.x < 0 || k.y < 0 || k.z < 0 || k.x >= cells || k.y >= cells || k.z >= cells)
        fail("{}: key {} is outside its level's {} cells an axis", name, text, cells);
      if (!count.is_number_integer() || count.get<int64_t>() < -1)
        fail("{}: node {} has count {}", name, text, count.dump());
      entries.emplace_back(k, count.get<int64_t>());
    }
    std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
      return std::tie(a.first.d, a.first.x, a.first.y, a.first.z) <
             std::tie(b.first.d, b.first.x, b.first.y, b.first.z);
    });
    std::map<Key, int32_t> index;
    bool own = false;
    for (const auto& [k, count] : entries) {
      if (k == root) {
        if (count == -1) fail("{}: node {} points to its own file (a cycle)", name, k.str());
        if (count > 0) {
          e.contents.push_back(data_uri(c, k, count));
          e.content_points = uint64_t(count);
        }
        own = true;
        continue;
      }
      const int shift = k.d - root.d;
      if (shift <= 0 || (k.x >> shift) != root.x || (k.y >> shift) != root.y ||
          (k.z >> shift) != root.z)
        fail("{}: node {} is not below the file's node {}", name, k.str(), root.str());
      int32_t parent = -1;
      if (shift > 1) {
        auto it = index.find({k.d - 1, k.x >> 1, k.y >> 1, k.z >> 1});
        if (it == index.end()) fail("{}: node {} has no parent in the hierarchy", name, k.str());
        parent = it->second;
      }
      if (tiles_now + e.tiles.size() + 1 > options.max_tiles) {
        e.over_limit = true;
        fail("the tile limit of {} is reached (TilesetOptions::max_tiles)", options.max_tiles);
      }
      Tile t = node_tile(c, k);
      t.parent = parent;
      t.depth = uint32_t(shift - 1);
      if (count > 0) {
        t.contents.push_back(data_uri(c, k, count));
        t.content_points = uint64_t(count);
      }
      if (count == -1) t.pending = hierarchy_pending(pending.ept, k);
      const int32_t local = int32_t(e.tiles.size());
      if (parent >= 0) e.tiles[size_t(parent)].children.push_back(uint32_t(local));
      index[k] = local;
      e.tiles.push_back(std::move(t));
    }
    if (!own) fail("{}: the file does not list its own node {}", name, root.str());
    e.subtrees = 1;
  } catch (const std::exception& err) {
    e.tiles.clear();
    e.contents.clear();
    e.content_points = 0;
    e.errors.emplace_back(-1, err.what());
  }
  return e;
}

Tileset load_ept_tileset(const std::string& uri, const Fetcher& fetcher,
                         const TilesetOptions& options) {
  const std::vector<uint8_t> bytes = fetcher(uri);
  if (looks_like_html(bytes.data(), bytes.size()))
    fail("{}: this is an HTML page, not ept.json", uri);
  std::shared_ptr<const EptCloud> cloud = parse_ept_metadata(bytes, uri);
  Tileset ts;
  ts.uri = uri;
  ts.version = "EPT " + cloud->version;
  ts.geometric_error = 2.0 * cloud->spacing;
  ts.ept = cloud;
  if (cloud->version.rfind("0.", 0) == 0)
    ts.warnings.push_back(
        fmt::format("{}: EPT version '{}' is from before 1.0: read as 1.0, whose layout it has",
                    uri, cloud->version));
  ts.tiles.push_back(node_tile(*cloud, {}));
  auto pending = hierarchy_pending(cloud, {});
  // The root hierarchy file is read now: a dataset whose hierarchy cannot start is an error.
  Expansion e = read_ept_hierarchy(0, *pending, 1, fetcher, options);
  if (e.tiles.empty() && e.contents.empty())
    fail("{}", e.errors.empty() ? uri + ": the hierarchy is empty" : e.errors[0].second);
  ts.tiles[0].pending = pending;
  ts.pending = 1;
  attach_children(ts, std::move(e), options);
  return ts;
}

PointContent decode_ept_node(const EptCloud& c, std::span<const uint8_t> bytes,
                             const std::string& uri, const DecodeLimits& limits) {
  const std::string count = fragment_field(uri, "points");
  char* end = nullptr;
  const unsigned long long points = std::strtoull(count.c_str(), &end, 10);
  if (count.empty() || *end != '\0') fail("{}: not an EPT node (no point count)", uri);
  if (points > limits.max_points)
    fail("{}: {} points in one node is over the limit of {}", uri, points, limits.max_points);
  if (c.data_type == "laszip") {
    LasReader reader(bytes, uri);
    PointBatch b;
    b.reserve(points);
    while (b.size() < points)
      if (reader.read(b, size_t(points - b.size())) == 0) break;
    if (b.size() != points || reader.header().point_count != points)
      fail("{}: the node holds {} points, the hierarchy says {}", uri, reader.header().point_count,
           points);
    PointContent out = content_from_batch(b, reader.header().rgb_bits);
    out.format = "ept";
    return out;
  }
  std::vector<uint8_t> raw;
  std::span<const uint8_t> data = bytes;
  if (c.data_type == "zstandard") {
    const unsigned long long size = ZSTD_getFrameContentSize(bytes.data(), bytes.size());
    if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN)
      fail("{}: not a zstd frame with its size", uri);
    if (size != points * c.record_size)
      fail("{}: {} bytes once decompressed for {} points of {} bytes", uri, size, points,
           c.record_size);
    raw.resize(size_t(size));
    const size_t got = ZSTD_decompress(raw.data(), raw.size(), bytes.data(), bytes.size());
    if (ZSTD_isError(got) || got != raw.size())
      fail("{}: zstd data cannot be decoded ({})", uri,
           ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short");
    data = raw;
  }
  if (data.size() != points * c.record_size)
    fail("{}: {} bytes for {} points of {} bytes", uri, data.size(), points, c.record_size);
  const size_t n = size_t(points);
  PointContent out;
  out.format = "ept";
  out.point_count = n;
  std::vector<glm::dvec3> pos(n);
  const EptDimension* xyz[3] = {nullptr, nullptr, nullptr};
  const EptDimension* rgb[3] = {nullptr, nullptr, nullptr};
  for (const auto& d : c.schema) {
    for (int k = 0; k < 3; ++k) {
      if (d.name == std::string(1, char('X' + k))) xyz[k] = &d;
      if (d.name == (k == 0 ? "Red" : k == 1 ? "Green" : "Blue")) rgb[k] = &d;
    }
  }
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* r = data.data() + i * c.record_size;
    for (int k = 0; k < 3; ++k) pos[i][k] = read_dimension(r + xyz[k]->at, *xyz[k]);
    lo = glm::min(lo, pos[i]), hi = glm::max(hi, pos[i]);
  }
  out.center = n ? (lo + hi) * 0.5 : glm::dvec3(0.0);
  for (const auto& p : pos) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      fail("{}: a position is not finite", uri);
    out.positions.push_back(glm::vec3(p - out.center));
  }
  if (rgb[0] && rgb[1] && rgb[2]) {
    // 16-bit colour scaled down unless every value of the node fits 8 bits (as LAS readers do).
    double top = 0;
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k)
        top = std::max(top, read_dimension(data.data() + i * c.record_size + rgb[k]->at, *rgb[k]));
    const double div = top > 255 ? 256 : 1;
    out.rgba.resize(n);
    for (size_t i = 0; i < n; ++i) {
      uint32_t v = 0xff000000u;
      for (int k = 0; k < 3; ++k) {
        const double x = read_dimension(data.data() + i * c.record_size + rgb[k]->at, *rgb[k]);
        v |= uint32_t(std::clamp(x / div, 0.0, 255.0)) << (8 * k);
      }
      out.rgba[i] = v;
    }
  }
  static const std::map<std::string, std::string> keys = {
      {"Intensity", "intensity"},        {"Classification", "classification"},
      {"ReturnNumber", "return_number"}, {"NumberOfReturns", "number_of_returns"},
      {"GpsTime", "gps_time"},           {"PointSourceId", "point_source_id"},
      {"UserData", "user_data"},         {"ScanAngleRank", "scan_angle"}};
  for (const auto& d : c.schema) {
    if (d.name == "X" || d.name == "Y" || d.name == "Z" || d.name == "Red" || d.name == "Green" ||
        d.name == "Blue")
      continue;
    PointAttribute a;
    a.component_type = d.type + std::to_string(d.size * 8);
    a.values.resize(n);
    for (size_t i = 0; i < n; ++i)
      a.values[i] = read_dimension(data.data() + i * c.record_size + d.at, d);
    auto key = keys.find(d.name);
    out.attributes[key == keys.end() ? d.name : key->second] = std::move(a);
  }
  return out;
}

PointContent content_from_batch(PointBatch& b, int rgb_bits) {
  PointContent c;
  c.point_count = b.size();
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const auto& p : b.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  c.center = b.size() ? (lo + hi) * 0.5 : glm::dvec3(0.0);
  for (const auto& p : b.positions) c.positions.push_back(glm::vec3(p - c.center));
  if (!b.rgb.empty()) {
    const int shift = rgb_bits == 8 ? 0 : 8;
    for (const auto& v : b.rgb) {
      auto ch = [&](uint16_t x) { return uint32_t(std::min<uint32_t>(x >> shift, 255u)); };
      c.rgba.push_back(ch(v.x) | ch(v.y) << 8 | ch(v.z) << 16 | 0xff000000u);
    }
  }
  auto scalar = [&](const char* key, const char* type, auto const& values) {
    if (values.empty()) return;
    PointAttribute a;
    a.component_type = type;
    a.values.assign(values.begin(), values.end());
    c.attributes.emplace(key, std::move(a));
  };
  scalar("intensity", "UNSIGNED_SHORT", b.intensity);
  scalar("classification", "UNSIGNED_BYTE", b.classification);
  scalar("return_number", "UNSIGNED_BYTE", b.return_number);
  scalar("number_of_returns", "UNSIGNED_BYTE", b.number_of_returns);
  scalar("gps_time", "DOUBLE", b.gps_time);
  return c;
}

}  // namespace stipple::io
