// Potree 1.x clouds (cloud.js with its hierarchy in 1.0-1.4, .hrc hierarchy files from 1.5,
// .bin/.las/.laz nodes) as a streamed octree; the formats are described in potree.hpp.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "batch_content.hpp"
#include "json_fields.hpp"
#include "potree_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/fetch.hpp"
#include "stipple/io/las.hpp"

namespace stipple::io {
namespace {

using json = nlohmann::json;
using namespace potree_detail;

constexpr size_t kHrcRecord = 5;  // child mask u8, points u32

// The attributes of formats up to 1.7, named in cloud.js by these strings alone (as Potree's
// viewer defines them; positions are read as uint32 from format 1.4 on).
struct NamedAttribute {
  const char* name;
  const char* type;
  int elements;
};
constexpr NamedAttribute kNamed[] = {{"POSITION_CARTESIAN", "uint32", 3},
                                     {"COLOR_PACKED", "uint8", 4},
                                     {"RGBA_PACKED", "uint8", 4},
                                     {"RGB_PACKED", "uint8", 3},
                                     {"NORMAL_FLOATS", "float", 3},
                                     {"FILLER_1B", "uint8", 1},
                                     {"INTENSITY", "uint16", 1},
                                     {"CLASSIFICATION", "uint8", 1},
                                     {"NORMAL_SPHEREMAPPED", "uint8", 2},
                                     {"NORMAL_OCT16", "uint8", 2},
                                     {"NORMAL", "float", 3},
                                     {"RETURN_NUMBER", "uint8", 1},
                                     {"NUMBER_OF_RETURNS", "uint8", 1},
                                     {"SOURCE_ID", "uint16", 1},
                                     {"INDICES", "uint32", 1},
                                     {"SPACING", "float", 1},
                                     {"GPS_TIME", "double", 1}};

// How a node's bytes of an attribute are read, by its name in either spelling (1.7 strings,
// 1.8 objects as PotreeConverter 1.7 writes them).
enum class Role { Position, Colour, NormalFloats, NormalSphere, NormalOct, Skip, Value };

Role role_of(const PotreeAttribute& a) {
  const std::string& n = a.name;
  if (n == "POSITION_CARTESIAN") return Role::Position;
  if (n == "COLOR_PACKED" || n == "RGBA_PACKED" || n == "RGB_PACKED" || n == "RGBA" || n == "rgba")
    return Role::Colour;
  if (n == "NORMAL" || n == "NORMAL_FLOATS") return Role::NormalFloats;
  if (n == "NORMAL_SPHEREMAPPED") return Role::NormalSphere;
  if (n == "NORMAL_OCT16") return Role::NormalOct;
  if (n == "FILLER_1B" || type_size(a.type) == 0) return Role::Skip;
  return Role::Value;
}

// Potree's names to the keys the colour modes read.
std::string value_key(const std::string& name) {
  static const std::map<std::string, std::string> keys = {
      {"INTENSITY", "intensity"},
      {"intensity", "intensity"},
      {"CLASSIFICATION", "classification"},
      {"classification", "classification"},
      {"RETURN_NUMBER", "return_number"},
      {"return number", "return_number"},
      {"NUMBER_OF_RETURNS", "number_of_returns"},
      {"number of returns", "number_of_returns"},
      {"SOURCE_ID", "point_source_id"},
      {"source id", "point_source_id"},
      {"GPS_TIME", "gps_time"},
      {"gps-time", "gps_time"}};
  auto k = keys.find(name);
  return k == keys.end() ? name : k->second;
}

double number(const json& j, const char* key, const std::string& uri) {
  if (!j.contains(key) || !j[key].is_number()) fail("{}: {} is missing or not a number", uri, key);
  const double v = j[key].get<double>();
  if (!std::isfinite(v)) fail("{}: {} is not finite", uri, key);
  return v;
}

void box(const json& j, const char* key, const std::string& uri, glm::dvec3* lo, glm::dvec3* hi) {
  const json& b = j.contains(key) ? j[key] : json();
  if (!b.is_object()) fail("{}: {} is missing", uri, key);
  *lo = {number(b, "lx", uri), number(b, "ly", uri), number(b, "lz", uri)};
  *hi = {number(b, "ux", uri), number(b, "uy", uri), number(b, "uz", uri)};
}

// The folder of node `name` below octreeDir: r, then one folder per whole group of `step` digits
// (1.5 on); octreeDir itself before 1.5.
std::string node_folder(const PotreeCloud& c, const std::string& name) {
  if (c.minor < 5) return c.octree_dir;
  std::string path = c.octree_dir + "/r";
  const std::string digits = name.substr(1);
  for (size_t i = 0; i + size_t(c.step_size) <= digits.size(); i += size_t(c.step_size))
    path += "/" + digits.substr(i, size_t(c.step_size));
  return path;
}

// Binary nodes are .bin from format 1.4; before, a node's file is its name alone.
std::string data_extension(const PotreeCloud& c) {
  return c.encoding == "LAS" ? ".las" : c.encoding == "LAZ" ? ".laz" : c.minor < 4 ? "" : ".bin";
}

std::shared_ptr<PendingChildren> hrc_pending(std::shared_ptr<const PotreeCloud> cloud,
                                             const Key& k) {
  auto p = std::make_shared<PendingChildren>();
  const std::string name = node_name(k);
  p->kind = PendingChildren::Kind::PotreeChunk;
  p->uris = {node_folder(*cloud, name) + "/" + name + ".hrc"};
  p->refine = Refine::Add;
  p->level = k.level, p->x = k.x, p->y = k.y, p->z = k.z;
  p->potree = std::move(cloud);
  return p;
}

std::string content_uri(const PotreeCloud& c, const Key& k, uint32_t points) {
  const std::string name = node_name(k);
  return fmt::format("{}/{}{}#points={}&key={}", node_folder(c, name), name, data_extension(c),
                     points, name);
}

glm::vec3 normal_sphere(uint8_t bx, uint8_t by) {
  // As Potree's viewer decodes it (a sphere map: aras-p.info/texts/CompactNormalStorage.html).
  double nx = bx / 255.0 * 2 - 1, ny = by / 255.0 * 2 - 1;
  const double l = std::max(0.0, 1 - nx * nx - ny * ny);
  nx *= std::sqrt(l) * 2, ny *= std::sqrt(l) * 2;
  return glm::vec3(float(nx), float(ny), float(l * 2 - 1));
}

glm::vec3 normal_oct16(uint8_t bx, uint8_t by) {
  // Octahedral normal vectors, 8 bits an axis, as Potree's viewer decodes them.
  const double u = bx / 255.0 * 2 - 1, v = by / 255.0 * 2 - 1;
  const double z = 1 - std::abs(u) - std::abs(v);
  auto sign = [](double s) { return s < 0 ? -1.0 : 1.0; };
  const double x = z >= 0 ? u : (1 - std::abs(v)) * sign(u);
  const double y = z >= 0 ? v : (1 - std::abs(u)) * sign(v);
  const double len = std::sqrt(x * x + y * y + z * z);
  return len > 0 ? glm::vec3(float(x / len), float(y / len), float(z / len)) : glm::vec3(0, 0, 1);
}

}  // namespace

std::shared_ptr<const PotreeCloud> parse_potree1_cloud(std::span<const uint8_t> bytes,
                                                       const std::string& uri) {
  json j = json_fields::metadata_object(bytes, uri);
  auto cloud = std::make_shared<PotreeCloud>();
  PotreeCloud& c = *cloud;
  c.uri = uri;
  c.major = 1;
  try {
    const json& v = j.contains("version") ? j["version"] : json();
    c.version = v.is_string() ? v.get<std::string>() : v.is_number() ? v.dump() : "";
    int major = 0, minor = 0;
    char tail = 0;
    if (std::sscanf(c.version.c_str(), "%d.%d%c", &major, &minor, &tail) != 2 || major != 1)
      fail("{}: version '{}' is not a Potree 1.x format", uri, c.version);
    if (minor < 0) fail("{}: version '{}' is not a Potree 1.x format", uri, c.version);
    if (minor > 8) fail("{}: format {} is newer than 1.8, the last of Potree 1", uri, c.version);
    c.minor = minor;
    c.projection = j.value("projection", "");
    if (!j.contains("octreeDir") || !j["octreeDir"].is_string() ||
        j["octreeDir"].get<std::string>().empty())
      fail("{}: octreeDir is missing", uri);
    const std::string dir = j["octreeDir"].get<std::string>();
    c.octree_dir = dir.rfind("http", 0) == 0 ? dir : resolve_uri(uri, dir);
    while (c.octree_dir.size() > 1 && c.octree_dir.back() == '/') c.octree_dir.pop_back();
    if (j.contains("points")) {
      if (!j["points"].is_number_unsigned()) fail("{}: points is not a count", uri);
      c.points = j["points"].get<uint64_t>();
    }
    box(j, "boundingBox", uri, &c.cube_min, &c.cube_max);
    if (!(c.cube_max.x > c.cube_min.x && c.cube_max.y > c.cube_min.y &&
          c.cube_max.z > c.cube_min.z))
      fail("{}: boundingBox is empty", uri);
    c.data_min = c.cube_min, c.data_max = c.cube_max;
    if (j.contains("tightBoundingBox")) box(j, "tightBoundingBox", uri, &c.data_min, &c.data_max);
    c.offset = c.cube_min;
    // Binary positions are integers with a scale from format 1.4; floats before (scale unused).
    const json& scale = j.contains("scale") ? j["scale"] : json();
    if (scale.is_number())
      c.scale = glm::dvec3(scale.get<double>());
    else if (minor >= 4)
      fail("{}: scale is missing or not a number", uri);
    if (!(std::isfinite(c.scale.x) && c.scale.x > 0)) fail("{}: scale must be positive", uri);
    c.spacing = number(j, "spacing", uri);
    if (!(c.spacing > 0)) fail("{}: spacing must be positive", uri);
    if (minor >= 5) {
      if (!j.contains("hierarchyStepSize") || !j["hierarchyStepSize"].is_number_integer())
        fail("{}: hierarchyStepSize is missing", uri);
      c.step_size = j["hierarchyStepSize"].get<int>();
      if (c.step_size < 1 || c.step_size > kMaxPotreeDepth)
        fail("{}: hierarchyStepSize {} is outside 1-{}", uri, c.step_size, kMaxPotreeDepth);
    } else {
      // The whole octree, [name, points] a node. Entries are checked as the tiles are made
      // (load_potree1): one bad node is an error of its own, not of the cloud.
      const json& h = j.contains("hierarchy") ? j["hierarchy"] : json();
      if (!h.is_array() || h.empty())
        fail("{}: format {} keeps its octree in \"hierarchy\", which is missing or empty", uri,
             c.version);
      c.hierarchy.reserve(h.size());
      for (size_t i = 0; i < h.size(); ++i) {
        const json& e = h[i];
        if (e.is_array() && e.size() == 2 && e[0].is_string() && e[1].is_number_unsigned())
          c.hierarchy.emplace_back(e[0].get<std::string>(), e[1].get<uint64_t>());
        else  // kept as written, so that its error shows it (it is no node name)
          c.hierarchy.emplace_back(e.dump(), 0);
      }
    }
    const json& attrs = j.contains("pointAttributes") ? j["pointAttributes"] : json();
    if (attrs.is_string()) {
      c.encoding = attrs.get<std::string>();
      if (c.encoding != "LAS" && c.encoding != "LAZ")
        fail("{}: pointAttributes '{}' is neither LAS, LAZ nor a list", uri, c.encoding);
    } else if (attrs.is_array() && !attrs.empty()) {
      c.encoding = "BINARY";
      bool position = false;
      for (const auto& a : attrs) {
        PotreeAttribute pa;
        if (a.is_string()) {
          pa.name = a.get<std::string>();
          auto known = std::find_if(std::begin(kNamed), std::end(kNamed),
                                    [&](const NamedAttribute& k) { return pa.name == k.name; });
          if (known == std::end(kNamed)) fail("{}: unknown point attribute '{}'", uri, pa.name);
          pa.type = known->type;
          pa.elements = known->elements;
          pa.element_size = type_size(pa.type);
          pa.size = pa.elements * pa.element_size;
        } else if (a.is_object()) {
          pa.name = a.value("name", "");
          pa.type = a.value("type", "");
          pa.elements = int(json_fields::integer(a, "elements", 1, uri));
          pa.element_size = int(json_fields::integer(a, "elementSize", 0, uri));
          pa.size = int(json_fields::integer(a, "size", 0, uri));
          if (pa.elements < 1 || pa.elements > 16 || pa.size < 1 || pa.size > 1024)
            fail("{}: attribute '{}' has {} elements of size {}", uri, pa.name, pa.elements,
                 pa.size);
          if (type_size(pa.type) != 0 &&
              (type_size(pa.type) != pa.element_size || pa.elements * pa.element_size != pa.size))
            fail("{}: attribute '{}': {} x {} {} does not make {} bytes", uri, pa.name, pa.elements,
                 pa.element_size, pa.type, pa.size);
        } else {
          fail("{}: a point attribute is neither a name nor an object", uri);
        }
        const Role r = role_of(pa);
        if (r == Role::Position && pa.size != 12)
          fail("{}: POSITION_CARTESIAN must be 12 bytes, not {}", uri, pa.size);
        if (r == Role::Colour && pa.size < 3)
          fail("{}: colour '{}' of {} bytes is not 3 or 4 bytes", uri, pa.name, pa.size);
        if (r == Role::NormalFloats && pa.size != 12)
          fail("{}: {} must be 3 floats, not {} bytes", uri, pa.name, pa.size);
        if ((r == Role::NormalSphere || r == Role::NormalOct) && pa.size != 2)
          fail("{}: {} must be 2 bytes, not {}", uri, pa.name, pa.size);
        position = position || r == Role::Position;
        pa.offset = c.record_size;
        c.record_size += size_t(pa.size);
        c.attributes.push_back(std::move(pa));
      }
      if (!position) fail("{}: no POSITION_CARTESIAN attribute", uri);
    } else {
      fail("{}: pointAttributes are missing", uri);
    }
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed cloud.js: {}", uri, e.what());
  }
  return cloud;
}

namespace potree_detail {

Expansion read_hrc(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                   const Fetcher& fetcher, const TilesetOptions& options) {
  Expansion e;
  e.tile = tile;
  const Key root{pending.level, pending.x, pending.y, pending.z};
  const std::string name = pending.uris.empty() ? "?" : pending.uris[0];
  try {
    if (!pending.potree || pending.uris.size() != 1) fail("a hierarchy file without its cloud");
    const PotreeCloud& c = *pending.potree;
    const std::vector<uint8_t> bytes = fetcher(pending.uris[0]);
    if (bytes.empty() || bytes.size() % kHrcRecord != 0)
      fail("{}: {} bytes are not a whole number of 5-byte records", name, bytes.size());
    const size_t records = bytes.size() / kHrcRecord;
    // Breadth first: record 0 is the file's node (the expanded tile), then every listed node's
    // children in child order, down to `step` levels below it. A deepest node with children
    // has its own file, which lists it again with its count.
    std::vector<QueuedNode> queue{{-1, root}};
    size_t next = 0;
    for (size_t r = 0; r < records; ++r) {
      if (next >= queue.size()) fail("{}: record {} is listed by no node's child mask", name, r);
      const QueuedNode item = queue[next++];
      const uint8_t* p = bytes.data() + r * kHrcRecord;
      const uint8_t mask = p[0];
      const uint32_t points = load<uint32_t>(p + 1);
      Tile* t = item.tile >= 0 ? &e.tiles[size_t(item.tile)] : nullptr;
      const bool deepest = item.key.level - root.level == uint32_t(c.step_size);
      if (deepest && mask != 0) {
        t->pending = hrc_pending(pending.potree, item.key);
        continue;  // its count and children are in its file
      }
      if (points > 0) {
        std::string uri = content_uri(c, item.key, points);
        if (t) {
          t->contents.push_back(std::move(uri));
          t->content_points = points;
        } else {
          e.contents.push_back(std::move(uri));
          e.content_points = points;
        }
      }
      if (deepest) continue;
      add_mask_children(c, root, item, mask, tiles_now, options, name, e, queue);
    }
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

namespace {

// Formats 1.0-1.4: the tiles of the octree cloud.js lists, all at once. An entry that is not a
// node name and a count, names a node twice, or whose parent is not listed (or was refused) is
// an error of its own, naming it; its subtree is left out and the rest is drawn. Without the
// root the cloud has nothing to start from: an error of the cloud.
void octree_from_list(Tileset& ts, const PotreeCloud& c, const TilesetOptions& options) {
  const std::string& uri = c.uri;
  // Parents before children whatever the file's order: by depth, then as listed.
  std::vector<size_t> order(c.hierarchy.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return c.hierarchy[a].first.size() < c.hierarchy[b].first.size();
  });
  std::map<std::string, uint32_t> tile_of;
  for (size_t i : order) {
    const auto& [name, points] = c.hierarchy[i];
    const std::string entry = fmt::format("{}: hierarchy entry {} ({})", uri, i, name);
    Key key;
    if (!parse_node_name(name, &key)) {
      ts.errors.push_back(entry + " is not [a node name r0123..., a point count]");
      continue;
    }
    if (tile_of.count(name)) {
      ts.errors.push_back(entry + " lists the node a second time");
      continue;
    }
    int32_t parent = -1;
    if (key.level > 0) {
      auto p = tile_of.find(name.substr(0, name.size() - 1));
      if (p == tile_of.end()) {
        ts.errors.push_back(fmt::format("{}: its parent {} is not listed (or was refused)", entry,
                                        name.substr(0, name.size() - 1)));
        continue;
      }
      parent = int32_t(p->second);
    } else if (!ts.tiles.empty()) {
      ts.errors.push_back(entry + " lists the node a second time");
      continue;
    }
    if (ts.tiles.size() >= options.max_tiles) {
      ts.errors.push_back(
          fmt::format("{}: more than {} nodes: the rest are left out", uri, options.max_tiles));
      break;
    }
    Tile t = node_tile(c, key);
    t.parent = parent;
    t.depth = key.level;
    if (points > UINT32_MAX) {
      ts.errors.push_back(
          fmt::format("{} declares {} points, more than a node can hold", entry, points));
      continue;
    }
    if (points > 0) {
      t.contents.push_back(content_uri(c, key, uint32_t(points)));
      t.content_points = points;
    }
    tile_of[name] = uint32_t(ts.tiles.size());
    if (parent >= 0) ts.tiles[size_t(parent)].children.push_back(uint32_t(ts.tiles.size()));
    ts.tiles.push_back(std::move(t));
  }
  if (!tile_of.count("r"))
    fail("{}: the hierarchy lists no root node r, which every other node hangs from", uri);
}

}  // namespace

Tileset load_potree1(const std::string& uri, const Fetcher& fetcher,
                     const TilesetOptions& options) {
  const std::vector<uint8_t> bytes = fetcher(uri);
  if (looks_like_html(bytes.data(), bytes.size()))
    fail("{}: this is an HTML page, not a Potree cloud.js", uri);
  std::shared_ptr<const PotreeCloud> cloud = parse_potree1_cloud(bytes, uri);
  Tileset ts;
  ts.uri = uri;
  ts.version = "Potree " + cloud->version;
  ts.geometric_error = 2.0 * cloud->spacing;
  ts.potree = cloud;
  if (cloud->minor < 5) {
    octree_from_list(ts, *cloud, options);
    return ts;
  }
  ts.tiles.push_back(node_tile(*cloud, {}));
  auto pending = hrc_pending(cloud, {});
  // The root's file is read now: a cloud whose hierarchy cannot even start is an error.
  Expansion e = read_hrc(0, *pending, 1, fetcher, options);
  if (e.tiles.empty() && e.contents.empty())
    fail("{}", e.errors.empty() ? uri + ": the hierarchy is empty" : e.errors[0].second);
  ts.tiles[0].pending = pending;
  ts.pending = 1;
  attach_children(ts, std::move(e), options);
  return ts;
}

PointContent decode_node1(const PotreeCloud& c, std::span<const uint8_t> bytes,
                          const std::string& uri, const DecodeLimits& limits) {
  const uint64_t points = node_points(uri, limits);
  Key key;
  if (!parse_node_name(fragment_field(uri, "key"), &key))
    fail("{}: not a Potree node (no node name)", uri);
  if (c.encoding == "LAS" || c.encoding == "LAZ") {
    LasReader reader(bytes, uri);
    if (reader.header().point_count != points)
      fail("{}: the node holds {} points, the hierarchy says {}", uri, reader.header().point_count,
           points);
    PointBatch b;
    b.reserve(size_t(points));
    while (b.size() < points)
      if (reader.read(b, size_t(points - b.size())) == 0) break;
    if (b.size() != points) fail("{}: {} of {} points could be read", uri, b.size(), points);
    PointContent out = content_from_batch(b, reader.header().rgb_bits);
    out.format = "potree";
    return out;
  }
  if (c.record_size == 0 || bytes.size() != points * c.record_size)
    fail("{}: {} bytes for {} points of {} bytes", uri, bytes.size(), points, c.record_size);
  const size_t n = size_t(points);
  PointContent out;
  out.format = "potree";
  out.point_count = n;
  const glm::dvec3 corner = node_min(c, key);
  auto at = [&](size_t i, const PotreeAttribute& a) {
    return bytes.data() + i * c.record_size + a.offset;
  };
  for (const PotreeAttribute& a : c.attributes) {
    switch (role_of(a)) {
      case Role::Position: {
        std::vector<glm::dvec3> pos(n);
        for (size_t i = 0; i < n; ++i) {
          const uint8_t* p = at(i, a);
          // Formats 1.0-1.3: float32 in the cloud's coordinates; then uint32 steps of the scale
          // from the node's corner.
          if (c.minor < 4) {
            pos[i] = glm::dvec3(load<float>(p), load<float>(p + 4), load<float>(p + 8));
            if (!std::isfinite(pos[i].x) || !std::isfinite(pos[i].y) || !std::isfinite(pos[i].z))
              fail("{}: point {}'s position is not a finite number", uri, i);
          } else {
            pos[i] = corner +
                     glm::dvec3(load<uint32_t>(p), load<uint32_t>(p + 4), load<uint32_t>(p + 8)) *
                         c.scale;
          }
        }
        set_positions(out, pos);
        break;
      }
      case Role::Colour:
        out.rgba.resize(n);
        for (size_t i = 0; i < n; ++i) {
          const uint8_t* p = at(i, a);
          out.rgba[i] = p[0] | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | 0xff000000u;
        }
        break;
      case Role::NormalFloats:
        out.normals.resize(n);
        for (size_t i = 0; i < n; ++i) {
          const uint8_t* p = at(i, a);
          out.normals[i] = glm::vec3(load<float>(p), load<float>(p + 4), load<float>(p + 8));
        }
        break;
      case Role::NormalSphere:
      case Role::NormalOct:
        out.normals.resize(n);
        for (size_t i = 0; i < n; ++i) {
          const uint8_t* p = at(i, a);
          out.normals[i] = role_of(a) == Role::NormalSphere ? normal_sphere(p[0], p[1])
                                                            : normal_oct16(p[0], p[1]);
        }
        break;
      case Role::Skip:
        break;
      case Role::Value: {
        const int size = type_size(a.type);
        PointAttribute pa;
        pa.component_type = a.type;
        pa.components = a.elements;
        pa.values.resize(n * size_t(a.elements));
        for (size_t i = 0; i < n; ++i)
          for (int k = 0; k < a.elements; ++k)
            pa.values[i * size_t(a.elements) + size_t(k)] =
                read_value(at(i, a) + size_t(k * size), a.type);
        out.attributes[value_key(a.name)] = std::move(pa);
        break;
      }
    }
  }
  return out;
}

}  // namespace potree_detail
}  // namespace stipple::io
