#include "stipple/io/potree.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>

#include <brotli/decode.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "json_fields.hpp"
#include "potree_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"

namespace stipple::io {
namespace {

using json = nlohmann::json;
using namespace potree_detail;

constexpr size_t kRecord = 22;  // hierarchy.bin record

glm::dvec3 vec3(const json& j, const char* key, const std::string& uri) {
  const json& a = j.contains(key) ? j[key] : json();
  if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() || !a[2].is_number())
    fail("{}: {} is not three numbers", uri, key);
  glm::dvec3 v(a[0].get<double>(), a[1].get<double>(), a[2].get<double>());
  if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
    fail("{}: {} is not finite", uri, key);
  return v;
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
                     node_name(k));
}

}  // namespace

namespace potree_detail {

uint64_t node_points(const std::string& uri, const DecodeLimits& limits) {
  const std::string count = fragment_field(uri, "points");
  char* end = nullptr;
  const unsigned long long points = std::strtoull(count.c_str(), &end, 10);
  if (count.empty() || *end != '\0') fail("{}: not a Potree node (no point count)", uri);
  if (points > limits.max_points)
    fail("{}: {} points in one node is over the limit of {}", uri, points, limits.max_points);
  return points;
}

void set_positions(PointContent& out, const std::vector<glm::dvec3>& absolute) {
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const auto& p : absolute) lo = glm::min(lo, p), hi = glm::max(hi, p);
  out.center = absolute.empty() ? glm::dvec3(0.0) : (lo + hi) * 0.5;
  out.positions.reserve(absolute.size());
  for (const auto& p : absolute) out.positions.push_back(glm::vec3(p - out.center));
}

}  // namespace potree_detail

bool is_potree_input(const std::string& uri) {
  const std::string p = uri_path(uri);
  const size_t slash = p.find_last_of('/');
  const std::string file = p.substr(slash == std::string::npos ? 0 : slash + 1);
  return file == "metadata.json" || file == "cloud.js";
}

std::shared_ptr<const PotreeCloud> parse_potree_metadata(std::span<const uint8_t> bytes,
                                                         const std::string& uri) {
  json j = json_fields::metadata_object(bytes, uri);
  auto cloud = std::make_shared<PotreeCloud>();
  PotreeCloud& c = *cloud;
  c.uri = uri;
  try {
    const std::string version = j.value("version", "");
    if (version.rfind("2.", 0) != 0) fail("{}: version '{}' is not Potree 2.x", uri, version);
    c.name = j.value("name", "");
    c.projection = j.value("projection", "");
    c.version = version;
    c.encoding = j.value("encoding", "DEFAULT");
    if (c.encoding != "DEFAULT" && c.encoding != "BROTLI")
      fail("{}: unknown encoding '{}' (DEFAULT and BROTLI are Potree's)", uri, c.encoding);
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
    c.first_chunk_size = uint64_t(
        json_fields::integer(h, "firstChunkSize", 0, uri, 0, std::numeric_limits<int64_t>::max()));
    c.step_size = int(json_fields::integer(h, "stepSize", 0, uri));
    c.depth = int(json_fields::integer(h, "depth", 0, uri));
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
      pa.elements = int(json_fields::integer(a, "numElements", 1, uri));
      pa.element_size = int(json_fields::integer(a, "elementSize", 0, uri));
      pa.size = int(json_fields::integer(a, "size", 0, uri));
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
      // BROTLI stores rgb as a Morton code of three 16-bit values.
      if (c.encoding == "BROTLI" && pa.name == "rgb" && (pa.type != "uint16" || pa.elements != 3))
        fail("{}: BROTLI rgb must be 3 x uint16, not {} x {}", uri, pa.elements, pa.type);
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
  if (pending.potree && pending.potree->major == 1)
    return potree_detail::read_hrc(tile, pending, tiles_now, fetcher, options);
  Expansion e;
  e.tile = tile;
  const Key root{pending.level, pending.x, pending.y, pending.z};
  const std::string name = fmt::format("{} (hierarchy chunk of node {})",
                                       pending.potree ? pending.potree->uri : "?", node_name(root));
  try {
    if (!pending.potree || pending.uris.size() != 1) fail("a hierarchy chunk without its cloud");
    const PotreeCloud& c = *pending.potree;
    const std::vector<uint8_t> bytes = fetcher(pending.uris[0]);
    if (bytes.empty() || bytes.size() % kRecord != 0)
      fail("{}: {} bytes are not a whole number of 22-byte records", name, bytes.size());
    const size_t records = bytes.size() / kRecord;
    // Breadth first: record 0 is the chunk's root (the expanded tile), then every listed node's
    // children in child order. A proxy ends its branch here: its chunk lists it again.
    std::vector<QueuedNode> queue{{-1, root}};
    size_t next = 0;
    for (size_t r = 0; r < records; ++r) {
      if (next >= queue.size()) fail("{}: record {} is listed by no node's child mask", name, r);
      const QueuedNode item = queue[next++];
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
        // DEFAULT nodes are records; a BROTLI node's compressed size says nothing of its count.
        if (c.encoding == "DEFAULT" && size != uint64_t(points) * c.record_size)
          fail("{}: node {}: {} bytes for {} points of {} bytes", name, node_name(item.key), size,
               points, c.record_size);
        std::string uri = content_uri(c, item.key, offset, size, points);
        if (t) {
          t->contents.push_back(std::move(uri));
          t->content_points = points;
        } else {
          e.contents.push_back(std::move(uri));
          e.content_points = points;
        }
      }
      add_mask_children(c, root, item, mask, tiles_now, options, name, e, queue);
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
  const std::string path = uri_path(uri);
  if (path.ends_with("cloud.js")) return potree_detail::load_potree1(uri, fetcher, options);
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

namespace {

// Every third bit of `x` from bit 0, packed: one axis of a Morton code, 16 bits of it.
[[maybe_unused]] uint32_t morton_axis(uint64_t x) {  // unused without Brotli
  x &= 0x1249249249249249ull;
  x = (x ^ (x >> 2)) & 0x10c30c30c30c30c3ull;
  x = (x ^ (x >> 4)) & 0x100f00f00f00f00full;
  x = (x ^ (x >> 8)) & 0x1f0000ff0000ffull;
  x = (x ^ (x >> 16)) & 0x1f00000000ffffull;
  x = (x ^ (x >> 32)) & 0x1fffffull;
  return uint32_t(x & 0xffff);
}

bool is_position(const PotreeAttribute& a) {
  return a.name == "position" || a.name == "POSITION_CARTESIAN";
}

// A BROTLI node turned into DEFAULT records: decompressed (to exactly the size its count makes),
// the attributes one after the other put back into records, Morton codes undone.
std::vector<uint8_t> brotli_records(const PotreeCloud& c, std::span<const uint8_t> bytes, size_t n,
                                    const std::string& uri) {
  size_t packed = 0;
  for (const auto& a : c.attributes)
    packed += is_position(a) ? 16 : a.name == "rgb" ? 8 : size_t(a.size);
  if (n == 0) return {};
  if (packed * n > (size_t(2) << 30))
    fail("{}: {} points of {} bytes is over 2 GiB once decompressed", uri, n, packed);
  std::vector<uint8_t> raw(packed * n);
  size_t got = raw.size();
  if (BrotliDecoderDecompress(bytes.size(), bytes.data(), &got, raw.data()) !=
          BROTLI_DECODER_RESULT_SUCCESS ||
      got != raw.size())
    fail("{}: not a Brotli stream of {} points of {} bytes", uri, n, packed);
  std::vector<uint8_t> records(n * c.record_size);
  const uint8_t* at = raw.data();
  for (const auto& a : c.attributes) {
    uint8_t* dst = records.data() + a.offset;
    if (is_position(a)) {
      // 128 bits a point, the upper 64 first: bits 3k, 3k+1, 3k+2 are bit k of x, y, z.
      for (size_t i = 0; i < n; ++i, at += 16) {
        const uint64_t upper = load<uint64_t>(at), lower = load<uint64_t>(at + 8);
        for (int k = 0; k < 3; ++k) {
          const uint32_t v = morton_axis(lower >> k) | morton_axis(upper >> k) << 16;
          std::memcpy(dst + i * c.record_size + 4 * size_t(k), &v, 4);
        }
      }
    } else if (a.name == "rgb") {
      for (size_t i = 0; i < n; ++i, at += 8) {
        const uint64_t code = load<uint64_t>(at);
        for (int k = 0; k < 3; ++k) {
          const uint16_t v = uint16_t(morton_axis(code >> k));
          std::memcpy(dst + i * c.record_size + 2 * size_t(k), &v, 2);
        }
      }
    } else {
      for (size_t i = 0; i < n; ++i, at += a.size)
        std::memcpy(dst + i * c.record_size, at, size_t(a.size));
    }
  }
  return records;
}

}  // namespace

PointContent decode_potree_node(const PotreeCloud& c, std::span<const uint8_t> bytes,
                                const std::string& uri, const DecodeLimits& limits) {
  if (c.major == 1) return potree_detail::decode_node1(c, bytes, uri, limits);
  const uint64_t points = node_points(uri, limits);
  std::vector<uint8_t> unpacked;
  if (c.encoding == "BROTLI") {
    unpacked = brotli_records(c, bytes, size_t(points), uri);
    bytes = unpacked;
  }
  if (c.record_size == 0 || bytes.size() != points * c.record_size)
    fail("{}: {} bytes for {} points of {} bytes", uri, bytes.size(), points, c.record_size);
  const size_t n = size_t(points);
  PointContent out;
  out.format = "potree";
  out.point_count = n;
  std::vector<glm::dvec3> pos(n);
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* p = bytes.data() + i * c.record_size;
    pos[i] = glm::dvec3(load<int32_t>(p), load<int32_t>(p + 4), load<int32_t>(p + 8)) * c.scale +
             c.offset;
  }
  set_positions(out, pos);
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
