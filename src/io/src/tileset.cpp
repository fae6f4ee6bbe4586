#include "stipple/io/tileset.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <glm/trigonometric.hpp>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/io/copc.hpp"
#include "stipple/io/ept.hpp"
#include "stipple/io/potree.hpp"
#include "stipple/io/subtree.hpp"
#include "stipple/math/geo.hpp"

namespace stipple::io {

using json = nlohmann::json;

double Obb::radius() const {
  if (sphere_radius >= 0) return sphere_radius;
  return glm::length(half_axes[0] + half_axes[1] + half_axes[2]) > 0
             ? std::sqrt(glm::dot(half_axes[0], half_axes[0]) +
                         glm::dot(half_axes[1], half_axes[1]) +
                         glm::dot(half_axes[2], half_axes[2]))
             : 0.0;
}

double Obb::distance(const glm::dvec3& p) const {
  glm::dvec3 d = p - center;
  if (sphere_radius >= 0) return std::max(0.0, glm::length(d) - sphere_radius);
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    double half = glm::length(half_axes[i]);
    glm::dvec3 u;
    if (half > 1e-12) {
      u = half_axes[i] / half;
    } else {
      // A flat box: its normal is the cross product of the other two axes.
      u = glm::cross(half_axes[(i + 1) % 3], half_axes[(i + 2) % 3]);
      double l = glm::length(u);
      if (l <= 1e-24) continue;
      u /= l;
      half = 0;
    }
    double excess = std::max(std::abs(glm::dot(d, u)) - half, 0.0);
    sum += excess * excess;
  }
  return std::sqrt(sum);
}

namespace {

Obb region_obb(const std::array<double, 6>& r) {
  // Sample the region's surface in ECEF and fit a box in the east-north-up frame of its middle.
  double lon0 = (r[0] + r[2]) * 0.5, lat0 = (r[1] + r[3]) * 0.5;
  glm::dmat3 enu = geo::enu_basis(glm::degrees(lon0), glm::degrees(lat0));
  glm::dvec3 origin = geo::geodetic_to_ecef({glm::degrees(lon0), glm::degrees(lat0), r[4]});
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  constexpr int kSteps = 6;
  for (int i = 0; i <= kSteps; ++i)
    for (int k = 0; k <= kSteps; ++k)
      for (double h : {r[4], r[5]}) {
        double lon = r[0] + (r[2] - r[0]) * i / kSteps, lat = r[1] + (r[3] - r[1]) * k / kSteps;
        glm::dvec3 e = geo::geodetic_to_ecef({glm::degrees(lon), glm::degrees(lat), h});
        glm::dvec3 local = glm::transpose(enu) * (e - origin);
        lo = glm::min(lo, local);
        hi = glm::max(hi, local);
      }
  Obb o;
  o.center = origin + enu * ((lo + hi) * 0.5);
  glm::dvec3 half = (hi - lo) * 0.5;
  for (int i = 0; i < 3; ++i) o.half_axes[i] = enu[i] * half[i];
  return o;
}

}  // namespace

Obb obb_of(const BoundingVolume& v, const glm::dmat4& transform) {
  Obb o;
  glm::dmat3 linear(transform);
  switch (v.kind) {
    case BoundingVolume::Kind::Box: {
      const auto& b = v.box;
      o.center = glm::dvec3(transform * glm::dvec4(b[0], b[1], b[2], 1.0));
      for (int i = 0; i < 3; ++i)
        o.half_axes[i] = linear * glm::dvec3(b[3 + i * 3], b[4 + i * 3], b[5 + i * 3]);
      break;
    }
    case BoundingVolume::Kind::Sphere: {
      const auto& s = v.sphere;
      o.center = glm::dvec3(transform * glm::dvec4(s[0], s[1], s[2], 1.0));
      double scale =
          std::max({glm::length(linear[0]), glm::length(linear[1]), glm::length(linear[2])});
      o.sphere_radius = s[3] * scale;
      o.half_axes = glm::dmat3(o.sphere_radius);
      break;
    }
    case BoundingVolume::Kind::Region:
      o = region_obb(v.region);  // regions are geographic: transforms do not apply
      break;
  }
  return o;
}

bool is_tileset_uri(const std::string& uri) {
  std::string p = uri_path(uri);
  if (is_url(uri)) p = p.substr(0, p.find('?'));
  return p.size() >= 5 && p.compare(p.size() - 5, 5, ".json") == 0;
}

namespace {

std::vector<double> numbers(const json& j, size_t n, const std::string& what,
                            const std::string& where) {
  if (!j.is_array() || j.size() != n) fail("{}: {} must be an array of {} numbers", where, what, n);
  std::vector<double> v;
  for (const auto& x : j) {
    if (!x.is_number() || !std::isfinite(x.get<double>()))
      fail("{}: {} holds a value that is not a finite number", where, what);
    v.push_back(x.get<double>());
  }
  return v;
}

BoundingVolume parse_volume(const json& j, const std::string& where) {
  if (!j.is_object()) fail("{}: boundingVolume is missing or not an object", where);
  BoundingVolume v;
  if (j.contains("box")) {
    v.kind = BoundingVolume::Kind::Box;
    auto b = numbers(j["box"], 12, "boundingVolume.box", where);
    std::copy(b.begin(), b.end(), v.box.begin());
  } else if (j.contains("region")) {
    v.kind = BoundingVolume::Kind::Region;
    auto r = numbers(j["region"], 6, "boundingVolume.region", where);
    std::copy(r.begin(), r.end(), v.region.begin());
    if (std::abs(r[0]) > 2 * M_PI || std::abs(r[2]) > 2 * M_PI || std::abs(r[1]) > M_PI ||
        std::abs(r[3]) > M_PI)
      fail("{}: boundingVolume.region angles must be radians", where);
  } else if (j.contains("sphere")) {
    v.kind = BoundingVolume::Kind::Sphere;
    auto s = numbers(j["sphere"], 4, "boundingVolume.sphere", where);
    if (s[3] < 0) fail("{}: boundingVolume.sphere has a negative radius", where);
    std::copy(s.begin(), s.end(), v.sphere.begin());
  } else {
    fail("{}: boundingVolume has none of box, region, sphere", where);
  }
  return v;
}

BoundingVolume subdivide(const BoundingVolume& root, int level, uint32_t x, uint32_t y, uint32_t z,
                         bool octree) {
  BoundingVolume v = root;
  double n = std::ldexp(1.0, level);
  if (root.kind == BoundingVolume::Kind::Box) {
    const auto& b = root.box;
    glm::dvec3 c(b[0], b[1], b[2]);
    glm::dvec3 axes[3] = {{b[3], b[4], b[5]}, {b[6], b[7], b[8]}, {b[9], b[10], b[11]}};
    double t[3] = {(2.0 * x + 1) / n - 1, (2.0 * y + 1) / n - 1,
                   octree ? (2.0 * z + 1) / n - 1 : 0};
    for (int i = 0; i < 3; ++i) c += axes[i] * t[i];
    v.box[0] = c.x, v.box[1] = c.y, v.box[2] = c.z;
    for (int i = 0; i < 3; ++i) {
      glm::dvec3 a = (i < 2 || octree) ? axes[i] / n : axes[i];
      v.box[3 + i * 3] = a.x, v.box[4 + i * 3] = a.y, v.box[5 + i * 3] = a.z;
    }
  } else if (root.kind == BoundingVolume::Kind::Region) {
    const auto& r = root.region;
    double dx = (r[2] - r[0]) / n, dy = (r[3] - r[1]) / n;
    v.region[0] = r[0] + dx * x, v.region[2] = r[0] + dx * (x + 1);
    v.region[1] = r[1] + dy * y, v.region[3] = r[1] + dy * (y + 1);
    if (octree) {
      double dz = (r[5] - r[4]) / n;
      v.region[4] = r[4] + dz * z, v.region[5] = r[4] + dz * (z + 1);
    }
  }
  return v;
}

std::string expand_template(std::string t, int level, uint32_t x, uint32_t y, uint32_t z) {
  auto replace = [&t](const std::string& key, uint64_t value) {
    for (size_t at; (at = t.find(key)) != std::string::npos;)
      t.replace(at, key.size(), std::to_string(value));
  };
  replace("{level}", uint64_t(level));
  replace("{x}", x);
  replace("{y}", y);
  replace("{z}", z);
  return t;
}

// Builds tiles into an Expansion: index -1 is the tile being expanded (or, for the root document,
// nothing). External tilesets and child subtrees it meets are left pending on their tile.
class Builder {
 public:
  Builder(Expansion& out, const Fetcher& fetcher, const TilesetOptions& options, size_t tiles_now,
          std::vector<std::string> chain)
      : out_(out),
        fetch_(fetcher),
        options_(options),
        tiles_now_(tiles_now),
        chain_(std::move(chain)) {}

  // Parses a tileset document and attaches its root under `parent`. `top` receives the
  // document's version and geometric error (the root document only).
  void document(std::span<const uint8_t> bytes, const std::string& uri, int32_t parent,
                const glm::dmat4& parent_transform, Refine parent_refine, Tileset* top = nullptr) {
    if (bytes.size() > options_.max_json_bytes) fail("{}: tileset JSON too large", uri);
    if (looks_like_html(bytes.data(), bytes.size()))
      fail("{}: this is an HTML page, not a tileset", uri);
    json j = json::parse(bytes.begin(), bytes.end(), nullptr, false);
    if (j.is_discarded()) fail("{}: not valid JSON", uri);
    if (!j.is_object()) fail("{}: a tileset must be a JSON object", uri);
    if (!j.contains("asset") || !j["asset"].is_object() || !j["asset"].contains("version"))
      fail("{}: asset.version is missing", uri);
    std::string version =
        j["asset"]["version"].is_string() ? j["asset"]["version"].get<std::string>() : "";
    if (version != "1.0" && version != "1.1" && version != "0.0")
      fail("{}: asset.version '{}' is not 1.0 or 1.1", uri, version);
    static const std::set<std::string> supported = {
        "3DTILES_implicit_tiling", "3DTILES_multiple_contents", "3DTILES_content_gltf",
        "3DTILES_draco_point_compression"};
    if (auto req = j.find("extensionsRequired"); req != j.end() && req->is_array())
      for (const auto& e : *req)
        if (!e.is_string() || !supported.count(e.get<std::string>()))
          fail("{}: requires extension {}, which stipple does not support", uri, e.dump());
    if (auto used = j.find("extensionsUsed"); used != j.end() && used->is_array())
      for (const auto& e : *used)
        if (e.is_string() && !supported.count(e.get<std::string>()))
          warn(fmt::format("{}: extension {} is not supported and ignored", uri,
                           e.get<std::string>()));
    if (!j.contains("root") || !j["root"].is_object())
      fail("{}: the tileset has no root tile", uri);
    if (top) {
      top->version = version;
      top->geometric_error = j.value("geometricError", 0.0);
    }
    tile(j["root"], uri, parent, parent_transform, parent_refine, 0);
  }

  // Reads the subtree rooted at (level, x, y, z), whose root tile is `root_tile`, and adds the
  // tiles it makes available; child subtrees are left pending on their root tiles.
  void subtree(const std::shared_ptr<const ImplicitTiling>& im, int32_t root_tile,
               const std::string& uri, int level, uint32_t x, uint32_t y, uint32_t z) {
    Subtree s;
    try {
      auto bytes = fetch_(uri);
      s = decode_subtree(bytes, uri, im->branching, im->subtree_levels,
                         [&](const std::string& u) { return fetch_(resolve_uri(uri, u)); });
      ++out_.subtrees;
    } catch (const Error& e) {
      tile_error(root_tile, e.what());
      return;
    }
    if (!s.tiles.get(0)) return;  // an empty subtree
    set_contents(*im, s, root_tile, 0, 0, level, x, y, z);
    visit(im, s, root_tile, 0, level, x, y, z);
  }

  // A failure that costs one tile (-1: the expanded one), recorded on it. Not logged: whoever
  // reads the tileset reports it (once).
  void tile_error(int32_t index, const std::string& text) {
    if (index >= 0) {
      auto& error = out_.tiles[size_t(index)].error;
      if (!error.empty()) error += "; ";
      error += text;
    }
    out_.errors.emplace_back(index, text);
  }

 private:
  Expansion& out_;
  const Fetcher& fetch_;
  const TilesetOptions& options_;
  size_t tiles_now_;                // tiles the tileset has besides out_.tiles
  std::vector<std::string> chain_;  // external tilesets from the root down (cycle detection)

  void warn(std::string text) { out_.warnings.push_back(std::move(text)); }
  int32_t add_tile(Tile t) {
    if (tiles_now_ + out_.tiles.size() >= options_.max_tiles) {
      out_.over_limit = true;
      fail("the tile limit is reached: {} tiles are materialised (TilesetOptions::max_tiles)",
           options_.max_tiles);
    }
    int32_t index = int32_t(out_.tiles.size());
    if (t.parent >= 0) {
      t.depth = out_.tiles[size_t(t.parent)].depth + 1;
      out_.tiles[size_t(t.parent)].children.push_back(uint32_t(index));
    }
    out_.tiles.push_back(std::move(t));
    return index;
  }
  std::vector<std::string>& contents_of(int32_t index) {
    return index >= 0 ? out_.tiles[size_t(index)].contents : out_.contents;
  }

  void tile(const json& j, const std::string& uri, int32_t parent,
            const glm::dmat4& parent_transform, Refine parent_refine, int depth) {
    std::string where = fmt::format("{} (tile at depth {})", uri, depth);
    if (depth > 256) fail("{}: tile tree deeper than 256 levels", where);
    if (!j.is_object()) fail("{}: a tile is not a JSON object", where);
    Tile t;
    t.parent = parent;
    t.volume = parse_volume(j.value("boundingVolume", json()), where);
    glm::dmat4 local(1.0);
    if (j.contains("transform")) {
      auto m = numbers(j["transform"], 16, "transform", where);
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) local[c][r] = m[c * 4 + r];
    }
    t.transform = parent_transform * local;
    t.box = obb_of(t.volume, t.transform);
    if (!j.contains("geometricError") || !j["geometricError"].is_number() ||
        j["geometricError"].get<double>() < 0)
      fail("{}: geometricError is missing or negative", where);
    t.geometric_error = j["geometricError"].get<double>();
    t.refine = parent_refine;
    if (auto r = j.find("refine"); r != j.end()) {
      std::string s = r->is_string() ? r->get<std::string>() : "";
      if (s == "ADD" || s == "add")
        t.refine = Refine::Add;
      else if (s == "REPLACE" || s == "replace")
        t.refine = Refine::Replace;
      else
        fail("{}: refine '{}' is neither ADD nor REPLACE", where, s);
    }
    // Contents: 1.0 content, 1.1 contents, or the 3DTILES_multiple_contents extension.
    std::vector<const json*> contents;
    if (auto c = j.find("content"); c != j.end()) contents.push_back(&*c);
    if (auto c = j.find("contents"); c != j.end() && c->is_array())
      for (const auto& x : *c) contents.push_back(&x);
    const json* ext =
        j.contains("extensions") && j["extensions"].is_object() ? &j["extensions"] : nullptr;
    if (ext && ext->contains("3DTILES_multiple_contents")) {
      const json& mc = (*ext)["3DTILES_multiple_contents"];
      if (mc.contains("content") && mc["content"].is_array())
        for (const auto& x : mc["content"]) contents.push_back(&x);
    }
    std::vector<std::string> content_uris;
    for (const json* c : contents) {
      if (!c->is_object()) fail("{}: content is not an object", where);
      std::string u = c->contains("uri") && (*c)["uri"].is_string() ? (*c)["uri"].get<std::string>()
                      : c->contains("url") && (*c)["url"].is_string()
                          ? (*c)["url"].get<std::string>()
                          : "";
      if (u.empty()) fail("{}: content has no uri", where);
      content_uris.push_back(u);
    }
    const json* implicit = j.contains("implicitTiling") ? &j["implicitTiling"]
                           : ext && ext->contains("3DTILES_implicit_tiling")
                               ? &(*ext)["3DTILES_implicit_tiling"]
                               : nullptr;
    if (auto ch = j.find("children"); ch != j.end() && !ch->is_array())
      fail("{}: children is not an array", where);
    glm::dmat4 transform = t.transform;
    Refine refine = t.refine;
    int32_t index = add_tile(std::move(t));
    if (implicit) {
      implicit_root(*implicit, index, content_uris, uri, where);
      return;
    }
    std::vector<std::string> externals;
    for (const auto& u : content_uris) {
      std::string resolved = resolve_uri(uri, u);
      if (!is_tileset_uri(resolved)) {
        out_.tiles[size_t(index)].contents.push_back(resolved);
      } else if (std::find(chain_.begin(), chain_.end(), resolved) != chain_.end()) {
        std::string cycle;
        for (const auto& c : chain_) cycle += c + " -> ";
        tile_error(index, fmt::format("external tileset cycle: {}{}", cycle, resolved));
      } else if (int(chain_.size()) >= options_.max_external_depth) {
        tile_error(index, fmt::format("{}: external tilesets nested deeper than {}", resolved,
                                      options_.max_external_depth));
      } else {
        externals.push_back(resolved);
      }
    }
    if (!externals.empty()) {
      // Read when a traversal wants to refine this tile, not now.
      auto p = std::make_shared<PendingChildren>();
      p->kind = PendingChildren::Kind::External;
      p->uris = std::move(externals);
      p->chain = chain_;
      p->transform = transform;
      p->refine = refine;
      out_.tiles[size_t(index)].pending = std::move(p);
    }
    if (auto ch = j.find("children"); ch != j.end())
      for (const auto& c : *ch) tile(c, uri, index, transform, refine, depth + 1);
  }

 public:
  // Reads the external tilesets of `pending` and attaches their roots under tile -1.
  void externals(const PendingChildren& pending) {
    for (const auto& uri : pending.uris) {
      // A broken external tileset costs its own tiles only: a partly added one is rolled back.
      size_t tiles_before = out_.tiles.size();
      size_t errors_before = out_.errors.size(), warnings_before = out_.warnings.size();
      chain_.push_back(uri);
      try {
        std::vector<uint8_t> bytes = fetch_(uri);
        document(bytes, uri, -1, pending.transform, pending.refine);
        ++out_.external_tilesets;
      } catch (const std::exception& e) {
        out_.tiles.resize(tiles_before);
        out_.errors.resize(errors_before);
        out_.warnings.resize(warnings_before);
        const bool json_error = dynamic_cast<const nlohmann::json::exception*>(&e) != nullptr;
        tile_error(-1, json_error ? fmt::format("{}: malformed JSON: {}", uri, e.what())
                                  : std::string(e.what()));
      }
      chain_.pop_back();
    }
  }

 private:
  void implicit_root(const json& j, int32_t index,
                     const std::vector<std::string>& content_templates, const std::string& uri,
                     const std::string& where) {
    out_.implicit = true;
    auto im = std::make_shared<ImplicitTiling>();
    std::string scheme = j.value("subdivisionScheme", "");
    if (scheme != "QUADTREE" && scheme != "OCTREE")
      fail("{}: implicitTiling.subdivisionScheme '{}' is not QUADTREE or OCTREE", where, scheme);
    im->octree = scheme == "OCTREE";
    im->branching = im->octree ? 8 : 4;
    im->subtree_levels = j.value("subtreeLevels", 0);
    im->available_levels = j.contains("availableLevels") ? j.value("availableLevels", 0)
                                                         : j.value("maximumLevel", -1) + 1;
    if (im->subtree_levels < 1 || im->available_levels < 1 || im->available_levels > 31)
      fail("{}: implicitTiling needs subtreeLevels >= 1 and 1 <= availableLevels <= 31", where);
    const json& subtrees = j.value("subtrees", json::object());
    if (!subtrees.is_object() || !subtrees.contains("uri") || !subtrees["uri"].is_string())
      fail("{}: implicitTiling.subtrees.uri is missing", where);
    im->subtrees = resolve_uri(uri, subtrees["uri"].get<std::string>());
    for (const auto& c : content_templates) im->contents.push_back(resolve_uri(uri, c));
    const Tile& root = out_.tiles[size_t(index)];
    if (root.volume.kind == BoundingVolume::Kind::Sphere)
      fail("{}: implicit tiling needs a box or region bounding volume", where);
    im->root_volume = root.volume;
    im->transform = root.transform;
    im->root_error = root.geometric_error;
    im->refine = root.refine;
    // The root subtree is read now: it holds the root's content and the first levels.
    subtree(im, index, expand_template(im->subtrees, 0, 0, 0, 0), 0, 0, 0, 0);
  }

  void set_contents(const ImplicitTiling& im, const Subtree& s, int32_t tile, int local_level,
                    uint64_t morton, int level, uint32_t x, uint32_t y, uint32_t z) {
    for (size_t c = 0; c < im.contents.size() && c < s.contents.size(); ++c)
      if (s.contents[c].get(availability_index(im.branching, local_level, morton))) {
        std::string u = expand_template(im.contents[c], level, x, y, z);
        if (is_tileset_uri(u)) {
          tile_error(
              tile,
              fmt::format("{}: external tilesets inside implicit tiling are not supported", u));
        } else {
          contents_of(tile).push_back(u);
        }
      }
  }

  // Adds the available children of `tile` in this subtree, depth first. Tiles of the subtree's
  // last level are only made when available; the roots of child subtrees are made (their
  // volume is known) with the subtree pending.
  void visit(const std::shared_ptr<const ImplicitTiling>& imp, const Subtree& s, int32_t tile,
             int local_level, int level, uint32_t x, uint32_t y, uint32_t z) {
    const ImplicitTiling& im = *imp;
    if (level + 1 >= im.available_levels) return;
    for (int c = 0; c < im.branching; ++c) {
      uint32_t cx = 2 * x + (c & 1), cy = 2 * y + ((c >> 1) & 1),
               cz = im.octree ? 2 * z + ((c >> 2) & 1) : 0;
      int child_local = local_level + 1, child_level = level + 1;
      // Coordinates within the subtree: the low bits of the global ones.
      uint32_t mask = (1u << child_local) - 1;
      uint64_t morton = morton_index(cx & mask, cy & mask, cz & mask, im.branching);
      auto make = [&] {
        Tile t;
        t.parent = tile;
        t.volume = subdivide(im.root_volume, child_level, cx, cy, cz, im.octree);
        t.transform = im.transform;
        t.box = obb_of(t.volume, t.transform);
        t.geometric_error = im.root_error / std::ldexp(1.0, child_level);
        t.refine = im.refine;
        return add_tile(std::move(t));
      };
      if (child_local < im.subtree_levels) {
        if (!s.tiles.get(availability_index(im.branching, child_local, morton))) continue;
        int32_t child = make();
        set_contents(im, s, child, child_local, morton, child_level, cx, cy, cz);
        visit(imp, s, child, child_local, child_level, cx, cy, cz);
      } else if (s.child_subtrees.get(morton)) {
        int32_t child = make();
        auto p = std::make_shared<PendingChildren>();
        p->kind = PendingChildren::Kind::Subtree;
        p->uris = {expand_template(im.subtrees, child_level, cx, cy, cz)};
        p->implicit = imp;
        p->level = uint32_t(child_level), p->x = cx, p->y = cy, p->z = cz;
        out_.tiles[size_t(child)].pending = std::move(p);
      }
    }
  }
};

uint32_t count_pending(const std::vector<Tile>& tiles) {
  uint32_t n = 0;
  for (const auto& t : tiles) n += t.pending != nullptr;
  return n;
}

}  // namespace

// JSON accessors throw nlohmann exceptions on a wrong type; the public entry point below turns
// them into stipple::Error naming the file.
static Tileset parse_tileset_unchecked(std::span<const uint8_t> json_bytes, const std::string& uri,
                                       const Fetcher& fetcher, const TilesetOptions& options) {
  Tileset ts;
  ts.uri = uri;
  Expansion e;
  // The root document is in the chain: a reference back to it is a cycle too.
  Builder builder(e, fetcher, options, 0, {uri});
  try {
    builder.document(json_bytes, uri, -1, glm::dmat4(1.0), Refine::Replace, &ts);
  } catch (const Error&) {
    if (e.tiles.empty()) throw;
    // Past the root, running over max_tiles keeps what was built.
    e.errors.emplace_back(
        0, fmt::format("{}: the tile tree was cut off at {} tiles", uri, e.tiles.size()));
  }
  ts.tiles = std::move(e.tiles);
  for (auto& [tile, text] : e.errors) ts.errors.push_back(std::move(text));
  ts.warnings = std::move(e.warnings);
  ts.subtrees = e.subtrees;
  ts.implicit = e.implicit;
  ts.pending = count_pending(ts.tiles);
  return ts;
}

Tileset load_tileset(const std::string& uri, const TilesetOptions& options) {
  Fetcher fetcher = [&options](const std::string& u) { return fetch(u, options.fetch); };
  return load_tileset(uri, fetcher, options);
}

Tileset load_tileset(const std::string& uri, const Fetcher& fetcher,
                     const TilesetOptions& options) {
  return load_tileset(uri, source_format(uri), fetcher, options);
}

Tileset load_tileset(const std::string& uri, SourceFormat format, const Fetcher& fetcher,
                     const TilesetOptions& options) {
  switch (format) {
    case SourceFormat::Copc:
      return load_copc_tileset(uri, fetcher, options);
    case SourceFormat::Potree:
      return load_potree_tileset(uri, fetcher, options);
    case SourceFormat::Ept:
      return load_ept_tileset(uri, fetcher, options);
    case SourceFormat::Tileset:
    case SourceFormat::Las:  // not a tileset: its bytes say so (parse_tileset's error)
      break;
  }
  auto bytes = fetcher(uri);
  return parse_tileset(bytes, uri, fetcher, options);
}

Tileset parse_tileset(std::span<const uint8_t> json_bytes, const std::string& uri,
                      const Fetcher& fetcher, const TilesetOptions& options) {
  try {
    return parse_tileset_unchecked(json_bytes, uri, fetcher, options);
  } catch (const nlohmann::json::exception& e) {
    fail("{}: malformed JSON: {}", uri, e.what());
  }
}

Expansion read_children(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                        const Fetcher& fetcher, const TilesetOptions& options) {
  if (pending.kind == PendingChildren::Kind::CopcPage)
    return read_copc_page(tile, pending, tiles_now, fetcher, options);
  if (pending.kind == PendingChildren::Kind::PotreeChunk)
    return read_potree_chunk(tile, pending, tiles_now, fetcher, options);
  if (pending.kind == PendingChildren::Kind::EptHierarchy)
    return read_ept_hierarchy(tile, pending, tiles_now, fetcher, options);
  Expansion e;
  e.tile = tile;
  Builder builder(e, fetcher, options, tiles_now, pending.chain);
  if (pending.kind == PendingChildren::Kind::External) {
    builder.externals(pending);
    return e;
  }
  try {
    if (!pending.implicit || pending.uris.size() != 1) fail("a pending subtree without tiling");
    builder.subtree(pending.implicit, -1, pending.uris[0], int(pending.level), pending.x, pending.y,
                    pending.z);
  } catch (const std::exception& err) {
    // Over max_tiles: the subtree is dropped as a whole.
    e.tiles.clear();
    e.contents.clear();
    builder.tile_error(-1, fmt::format("{}: {}", pending.uris[0], err.what()));
  }
  return e;
}

std::vector<std::pair<uint32_t, std::string>> attach_children(Tileset& ts, Expansion&& e,
                                                              const TilesetOptions& options) {
  std::vector<std::pair<uint32_t, std::string>> errors;
  if (e.tile >= ts.tiles.size() || !ts.tiles[e.tile].pending) return errors;
  ts.tiles[e.tile].pending.reset();
  --ts.pending;
  const size_t base = ts.tiles.size();
  if (base + e.tiles.size() > options.max_tiles) {
    // The limit can be passed by expansions read at the same time: refused here.
    e.over_limit = true;
    e.tiles.clear();
    e.contents.clear();
    e.errors.assign(1, {-1, fmt::format("the tile limit is reached: {} tiles are materialised "
                                        "(TilesetOptions::max_tiles); children not read",
                                        base)});
  }
  ts.external_tilesets += e.external_tilesets;
  ts.subtrees += e.subtrees;
  ts.implicit = ts.implicit || e.implicit;
  for (auto& w : e.warnings) ts.warnings.push_back(std::move(w));
  for (auto& c : e.contents) ts.tiles[e.tile].contents.push_back(std::move(c));
  ts.tiles[e.tile].content_points += e.content_points;
  const uint32_t depth = ts.tiles[e.tile].depth + 1;
  // Geometric growth: reserving the exact size here reallocated (and moved) the whole array on
  // every expansion, quadratic in the number of tiles over a tree's reading.
  if (ts.tiles.capacity() < base + e.tiles.size())
    ts.tiles.reserve(std::max(base + e.tiles.size(), 2 * ts.tiles.capacity()));
  for (size_t i = 0; i < e.tiles.size(); ++i) {
    Tile& t = e.tiles[i];
    if (t.parent < 0) {
      t.parent = int32_t(e.tile);
      ts.tiles[e.tile].children.push_back(uint32_t(base + i));
    } else {
      t.parent += int32_t(base);
    }
    for (auto& c : t.children) c += uint32_t(base);
    t.depth += depth;
    ts.pending += t.pending != nullptr;
    ts.tiles.push_back(std::move(t));
  }
  for (auto& [local, text] : e.errors) {
    uint32_t index = local < 0 ? e.tile : uint32_t(base + size_t(local));
    if (local < 0) {
      auto& error = ts.tiles[index].error;
      if (!error.empty()) error += "; ";
      error += text;
    }
    ts.errors.push_back(text);
    errors.emplace_back(index, std::move(text));
  }
  return errors;
}

bool expand_all(Tileset& ts, const Fetcher& fetcher, const TilesetOptions& options,
                size_t max_tiles) {
  TilesetOptions limited = options;
  limited.max_tiles = std::min(options.max_tiles, max_tiles);
  // New tiles are appended, so one pass in index order reads the tree breadth first.
  for (size_t i = 0; i < ts.tiles.size() && ts.pending > 0; ++i) {
    if (!ts.tiles[i].pending) continue;
    if (ts.tiles.size() >= limited.max_tiles) return false;
    auto pending = ts.tiles[i].pending;
    Expansion e = read_children(uint32_t(i), *pending, ts.tiles.size(), fetcher, limited);
    if (e.over_limit) return false;  // the tile stays pending: its children were not read
    attach_children(ts, std::move(e), limited);
  }
  return ts.pending == 0;
}

}  // namespace stipple::io
