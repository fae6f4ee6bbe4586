#include "stipple/io/potree.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"

namespace stipple::io {
namespace {

using json = nlohmann::json;

constexpr size_t kRecord = 22;  // hierarchy.bin record

int type_size(const std::string& t) {
  if (t == "int8" || t == "uint8") return 1;
  if (t == "int16" || t == "uint16") return 2;
  if (t == "int32" || t == "uint32" || t == "float") return 4;
  if (t == "int64" || t == "uint64" || t == "double") return 8;
  return 0;
}

double read_value(const uint8_t* p, const std::string& t) {
  auto get = [p](auto v) {
    std::memcpy(&v, p, sizeof(v));
    return double(v);
  };
  if (t == "int8") return get(int8_t{});
  if (t == "uint8") return get(uint8_t{});
  if (t == "int16") return get(int16_t{});
  if (t == "uint16") return get(uint16_t{});
  if (t == "int32") return get(int32_t{});
  if (t == "uint32") return get(uint32_t{});
  if (t == "int64") return get(int64_t{});
  if (t == "uint64") return get(uint64_t{});
  if (t == "float") return get(float{});
  return get(double{});
}

template <typename T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

glm::dvec3 vec3(const json& j, const char* key, const std::string& uri) {
  const json& a = j.contains(key) ? j[key] : json();
  if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() || !a[2].is_number())
    fail("{}: {} is not three numbers", uri, key);
  glm::dvec3 v(a[0].get<double>(), a[1].get<double>(), a[2].get<double>());
  if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
    fail("{}: {} is not finite", uri, key);
  return v;
}

std::string node_name(uint32_t level, uint32_t x, uint32_t y, uint32_t z) {
  std::string name = "r";
  for (uint32_t l = level; l > 0; --l) {
    const uint32_t b = l - 1;
    name += char('0' + (((x >> b) & 1) << 2 | ((y >> b) & 1) << 1 | ((z >> b) & 1)));
  }
  return name;
}

struct Key {
  uint32_t level = 0, x = 0, y = 0, z = 0;
  Key child(int i) const {
    return {level + 1, 2 * x + ((i >> 2) & 1), 2 * y + ((i >> 1) & 1), 2 * z + (i & 1)};
  }
};

Tile node_tile(const PotreeCloud& c, const Key& k) {
  const double n = std::ldexp(1.0, int(k.level));
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

std::shared_ptr<PendingChildren> chunk_pending(std::shared_ptr<const PotreeCloud> cloud,
                                               const Key& k, uint64_t offset, uint64_t size) {
  auto p = std::make_shared<PendingChildren>();
  p->kind = PendingChildren::Kind::PotreeChunk;
  p->uris = {range_uri(cloud->hierarchy_uri, offset, size)};
  p->refine = Refine::Add;
  p->level = k.level, p->x = k.x, p->y = k.y, p->z = k.z;
  p->potree = std::move(cloud);
  return p;
}

std::string content_uri(const PotreeCloud& c, const Key& k, uint64_t offset, uint64_t size,
                        uint32_t points) {
  return fmt::format("{}&points={}&key={}", range_uri(c.octree_uri, offset, size), points,
                     node_name(k.level, k.x, k.y, k.z));
}

}  // namespace

bool is_potree_input(const std::string& uri) {
  const std::string p = uri_path(uri);
  const size_t slash = p.find_last_of('/');
  return p.substr(slash == std::string::npos ? 0 : slash + 1) == "metadata.json";
}

std::shared_ptr<const PotreeCloud> parse_potree_metadata(std::span<const uint8_t> bytes,
                                                         const std::string& uri) {
  if (bytes.size() > (64u << 20)) fail("{}: metadata of {} bytes is too large", uri, bytes.size());
  json j = json::parse(bytes.begin(), bytes.end(), nullptr, false);
  if (!j.is_object()) fail("{}: not a JSON object", uri);
  auto cloud = std::make_shared<PotreeCloud>();
  PotreeCloud& c = *cloud;
  c.uri = uri;
  try {
    const std::string version = j.value("version", "");
    if (version.rfind("2.", 0) != 0) fail("{}: version '{}' is not Potree 2.x", uri, version);
    c.name = j.value("name", "");
    c.projection = j.value("projection", "");
    c.encoding = j.value("encoding", "DEFAULT");
    if (c.encoding == "BROTLI")
      fail("{}: BROTLI encoding is not supported (DEFAULT is); convert with --encoding DEFAULT",
           uri);
    if (c.encoding != "DEFAULT") fail("{}: unknown encoding '{}'", uri, c.encoding);
    if (!j.contains("points") || !j["points"].is_number_unsigned())
      fail("{}: points is missing or not a count", uri);
    c.points = j["points"].get<uint64_t>();
    c.scale = vec3(j, "scale", uri);
    c.offset = vec3(j, "offset", uri);
    if (!(c.scale.x > 0 && c.scale.y > 0 && c.scale.z > 0)) fail("{}: scale must be positive", uri);
    const json& box = j.value("boundingBox", json::object());
    c.cube_min = vec3(box, "min", uri);
    c.cube_max = vec3(box, "max", uri);
    if (!(c.cube_max.x > c.cube_min.x && c.cube_max.y > c.cube_min.y &&
          c.cube_max.z > c.cube_min.z))
      fail("{}: boundingBox is empty", uri);
    c.data_min = c.cube_min, c.data_max = c.cube_max;
    c.spacing = j.value("spacing", 0.0);
    if (!(std::isfinite(c.spacing) && c.spacing > 0)) fail("{}: spacing must be positive", uri);
    const json& h = j.value("hierarchy", json::object());
    c.first_chunk_size = h.value("firstChunkSize", uint64_t(0));
    c.step_size = h.value("stepSize", 0);
    c.depth = h.value("depth", 0);
    if (c.first_chunk_size == 0 || c.first_chunk_size % kRecord != 0)
      fail("{}: hierarchy.firstChunkSize {} is not a positive multiple of 22", uri,
           c.first_chunk_size);
    if (c.depth < 0 || c.depth > kMaxPotreeDepth)
      fail("{}: hierarchy.depth {} is outside 0-{}", uri, c.depth, kMaxPotreeDepth);
    const json& attrs = j.value("attributes", json::array());
    if (!attrs.is_array() || attrs.empty()) fail("{}: attributes are missing", uri);
    size_t at = 0;
    bool position = false;
    for (const auto& a : attrs) {
      PotreeAttribute pa;
      pa.name = a.value("name", "");
      pa.type = a.value("type", "");
      pa.elements = a.value("numElements", 1);
      pa.element_size = a.value("elementSize", 0);
      pa.size = a.value("size", 0);
      if (pa.elements < 1 || pa.elements > 16 || pa.size < 1 || pa.size > 1024)
        fail("{}: attribute '{}' has {} elements of size {}", uri, pa.name, pa.elements, pa.size);
      if (type_size(pa.type) != 0 &&
          (type_size(pa.type) != pa.element_size || pa.elements * pa.element_size != pa.size))
        fail("{}: attribute '{}': {} x {} {} does not make {} bytes", uri, pa.name, pa.elements,
             pa.element_size, pa.type, pa.size);
      if (a.contains("min") && a["min"].is_array() && a["min"].size() >= 3 && a.contains("max") &&
          a["max"].is_array() && a["max"].size() >= 3) {
        pa.min = vec3(a, "min", uri);
        pa.max = vec3(a, "max", uri);
      }
      pa.offset = at;
      at += size_t(pa.size);
      if (pa.name == "position" || pa.name == "POSITION_CARTESIAN") {
        if (pa.type != "int32" || pa.elements != 3)
          fail("{}: position must be 3 x int32, not {} x {}", uri, pa.elements, pa.type);
        if (pa.offset != 0) fail("{}: position must be the first attribute", uri);
        position = true;
        if (pa.max.x >= pa.min.x && pa.max != pa.min) c.data_min = pa.min, c.data_max = pa.max;
      }
      c.attributes.push_back(std::move(pa));
    }
    if (!position) fail("{}: no position attribute", uri);
    c.record_size = at;
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed metadata: {}", uri, e.what());
  }
  c.hierarchy_uri = resolve_uri(uri, "hierarchy.bin");
  c.octree_uri = resolve_uri(uri, "octree.bin");
  return cloud;
}

Expansion read_potree_chunk(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                            const Fetcher& fetcher, const TilesetOptions& options) {
  Expansion e;
  e.tile = tile;
  const Key root{pending.level, pending.x, pending.y, pending.z};
  const std::string name =
      fmt::format("{} (hierarchy chunk of node {})", pending.potree ? pending.potree->uri : "?",
                  node_name(root.level, root.x, root.y, root.z));
  try {
    if (!pending.potree || pending.uris.size() != 1) fail("a hierarchy chunk without its cloud");
    const PotreeCloud& c = *pending.potree;
    const std::vector<uint8_t> bytes = fetcher(pending.uris[0]);
    if (bytes.empty() || bytes.size() % kRecord != 0)
      fail("{}: {} bytes are not a whole number of 22-byte records", name, bytes.size());
    const size_t records = bytes.size() / kRecord;
    // Breadth first: record 0 is the chunk's root (the expanded tile), then every listed node's
    // children in child order. A proxy ends its branch here: its chunk lists it again.
    struct Item {
      int32_t tile;  // -1: the expanded tile
      Key key;
    };
    std::vector<Item> queue{{-1, root}};
    size_t next = 0;
    for (size_t r = 0; r < records; ++r) {
      if (next >= queue.size()) fail("{}: record {} is listed by no node's child mask", name, r);
      const Item item = queue[next++];
      const uint8_t* p = bytes.data() + r * kRecord;
      const uint8_t type = p[0], mask = p[1];
      const uint32_t points = load<uint32_t>(p + 2);
      const uint64_t offset = load<uint64_t>(p + 6), size = load<uint64_t>(p + 14);
      if (type > 2) fail("{}: record {} has node type {}", name, r, type);
      if (r == 0 && type == 2) fail("{}: the chunk's root is a proxy of itself (a cycle)", name);
      if (offset > UINT64_MAX / 2 || size > UINT64_MAX / 2)
        fail("{}: record {} has offset {} and size {} past any file", name, r, offset, size);
      Tile* t = item.tile >= 0 ? &e.tiles[size_t(item.tile)] : nullptr;
      if (type == 2) {
        if (size == 0 || size % kRecord != 0)
          fail("{}: proxy record {}: chunk of {} bytes is not a positive multiple of 22", name, r,
               size);
        t->pending = chunk_pending(pending.potree, item.key, offset, size);
        continue;  // its children are in its chunk
      }
      if (points > 0) {
        if (size != uint64_t(points) * c.record_size)
          fail("{}: node {}: {} bytes for {} points of {} bytes", name,
               node_name(item.key.level, item.key.x, item.key.y, item.key.z), size, points,
               c.record_size);
        std::string uri = content_uri(c, item.key, offset, size, points);
        if (t) {
          t->contents.push_back(std::move(uri));
          t->content_points = points;
        } else {
          e.contents.push_back(std::move(uri));
          e.content_points = points;
        }
      }
      for (int i = 0; i < 8; ++i) {
        if (!(mask & (1 << i))) continue;
        const Key k = item.key.child(i);
        if (int(k.level) > kMaxPotreeDepth)
          fail("{}: node below depth {} (a corrupt child mask)", name, kMaxPotreeDepth);
        if (tiles_now + e.tiles.size() + 1 > options.max_tiles) {
          e.over_limit = true;
          fail("the tile limit of {} is reached (TilesetOptions::max_tiles)", options.max_tiles);
        }
        Tile child = node_tile(c, k);
        child.parent = item.tile;
        child.depth = k.level - root.level - 1;
        const int32_t local = int32_t(e.tiles.size());
        if (item.tile >= 0) e.tiles[size_t(item.tile)].children.push_back(uint32_t(local));
        e.tiles.push_back(std::move(child));
        queue.push_back({local, k});
      }
    }
    // Nodes listed by a mask but without a record: the chunk is cut short.
    if (next != queue.size())
      fail("{}: {} nodes of the child masks have no record", name, queue.size() - next);
    e.subtrees = 1;
  } catch (const std::exception& err) {
    e.tiles.clear();
    e.contents.clear();
    e.content_points = 0;
    e.errors.emplace_back(-1, err.what());
  }
  return e;
}

Tileset load_potree_tileset(const std::string& uri, const Fetcher& fetcher,
                            const TilesetOptions& options) {
  const std::vector<uint8_t> bytes = fetcher(uri);
  if (looks_like_html(bytes.data(), bytes.size()))
    fail("{}: this is an HTML page, not Potree metadata", uri);
  std::shared_ptr<const PotreeCloud> cloud = parse_potree_metadata(bytes, uri);
  Tileset ts;
  ts.uri = uri;
  ts.version = "Potree 2.0";
  ts.geometric_error = 2.0 * cloud->spacing;
  ts.potree = cloud;
  ts.tiles.push_back(node_tile(*cloud, {}));
  auto pending = chunk_pending(cloud, {}, 0, cloud->first_chunk_size);
  // The first chunk is read now: a cloud whose hierarchy cannot even start is an error.
  Expansion e = read_potree_chunk(0, *pending, 1, fetcher, options);
  if (e.tiles.empty() && e.contents.empty())
    fail("{}", e.errors.empty() ? uri + ": the hierarchy is empty" : e.errors[0].second);
  ts.tiles[0].pending = pending;
  ts.pending = 1;
  attach_children(ts, std::move(e), options);
  return ts;
}

PointContent decode_potree_node(const PotreeCloud& c, std::span<const uint8_t> bytes,
                                const std::string& uri, const DecodeLimits& limits) {
  const std::string count = fragment_field(uri, "points");
  char* end = nullptr;
  const unsigned long long points = std::strtoull(count.c_str(), &end, 10);
  if (count.empty() || *end != '\0') fail("{}: not a Potree node (no point count)", uri);
  if (points > limits.max_points)
    fail("{}: {} points in one node is over the limit of {}", uri, points, limits.max_points);
  if (c.record_size == 0 || bytes.size() != points * c.record_size)
    fail("{}: {} bytes for {} points of {} bytes", uri, bytes.size(), points, c.record_size);
  const size_t n = size_t(points);
  PointContent out;
  out.format = "potree";
  out.point_count = n;
  std::vector<glm::dvec3> pos(n);
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* p = bytes.data() + i * c.record_size;
    pos[i] = glm::dvec3(load<int32_t>(p), load<int32_t>(p + 4), load<int32_t>(p + 8)) * c.scale +
             c.offset;
    lo = glm::min(lo, pos[i]);
    hi = glm::max(hi, pos[i]);
  }
  out.center = n ? (lo + hi) * 0.5 : glm::dvec3(0.0);
  out.positions.reserve(n);
  for (const auto& p : pos) out.positions.push_back(glm::vec3(p - out.center));
  // Potree's own names to the keys the colour modes read (as LAS and 3D Tiles content give them).
  static const std::map<std::string, std::string> keys = {
      {"intensity", "intensity"},         {"classification", "classification"},
      {"return number", "return_number"}, {"number of returns", "number_of_returns"},
      {"gps-time", "gps_time"},           {"point source id", "point_source_id"},
      {"user data", "user_data"},         {"scan angle", "scan_angle"},
      {"scan angle rank", "scan_angle"}};
  for (const PotreeAttribute& a : c.attributes) {
    if (a.offset == 0) continue;  // position
    const int size = type_size(a.type);
    if (a.name == "rgb" && size == 2 && a.elements >= 3) {
      // As Potree reads it: 16-bit values above 255 are scaled down, 8-bit ones kept.
      out.rgba.resize(n);
      for (size_t i = 0; i < n; ++i) {
        const uint8_t* p = bytes.data() + i * c.record_size + a.offset;
        uint32_t v = 0xff000000u;
        for (int k = 0; k < 3; ++k) {
          const uint16_t x = load<uint16_t>(p + 2 * k);
          v |= uint32_t(x > 255 ? x / 256 : x) << (8 * k);
        }
        out.rgba[i] = v;
      }
      continue;
    }
    if (size == 0) continue;  // "undefined": raw bytes nobody can interpret
    PointAttribute pa;
    pa.component_type = a.type;
    pa.components = a.elements;
    pa.values.resize(n * size_t(a.elements));
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < a.elements; ++k)
        pa.values[i * size_t(a.elements) + size_t(k)] =
            read_value(bytes.data() + i * c.record_size + a.offset + size_t(k * size), a.type);
    auto key = keys.find(a.name);
    out.attributes[key == keys.end() ? a.name : key->second] = std::move(pa);
  }
  return out;
}

}  // namespace stipple::io
