// A splat tileset (3D Tiles whose contents are KHR_gaussian_splatting glb, as `stipple tile`
// writes from splat files) read as one splat set: a cut through its tree under a splat budget,
// refined from the root, the tile of largest geometric error first, while the cut stays within
// the budget. Not streaming: the cut is chosen once, for no particular view (until splat
// tilesets go through tiles3d's traversal).
#include <queue>

#include <nlohmann/json.hpp>

#include "splat_detail.hpp"
#include "stipple/io/fetch.hpp"

namespace stipple::io::splat_detail {

namespace {

using json = nlohmann::json;

// glTF's Y-up frame to 3D Tiles' Z-up: (x, y, z) -> (x, -z, y).
const glm::dmat4 kYupToZup(1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1);

glm::dmat4 tile_transform(const json& tile, std::string_view name) {
  glm::dmat4 m(1.0);
  if (!tile.contains("transform")) return m;
  const json& t = tile["transform"];
  if (!t.is_array() || t.size() != 16) fail("{}: a tile transform is not 16 numbers", name);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) {
      const json& v = t[size_t(c * 4 + r)];
      if (!v.is_number()) fail("{}: a tile transform holds a non-number", name);
      m[c][r] = v.get<double>();
    }
  return m;
}

struct Node {
  const json* tile;
  glm::dmat4 world;  // tile frame (Z-up) to the tileset's
  double error;
};

}  // namespace

bool is_splat_tileset_json(std::span<const uint8_t> head) {
  const std::string_view text(reinterpret_cast<const char*>(head.data()), head.size());
  return text.find("\"root\"") != std::string_view::npos &&
         text.find("\"asset\"") != std::string_view::npos &&
         text.find("KHR_gaussian_splatting") != std::string_view::npos;
}

namespace {

SplatSet read_unchecked(const std::string& path, std::span<const uint8_t> bytes,
                        const SplatLimits& limits) {
  const json ts = json::parse(bytes.begin(), bytes.end(), nullptr, false);
  if (ts.is_discarded() || !ts.is_object() || !ts.contains("root") || !ts["root"].is_object())
    fail("{}: not a tileset (no root tile)", path);
  FetchOptions options;
  options.reject_html = true;
  auto load = [&](const Node& n) {
    const json& content = n.tile->value("content", json::object());
    if (!content.is_object() || !content.contains("uri")) return SplatSet{};
    if (!content["uri"].is_string()) fail("{}: a content uri is not a string", path);
    const std::string uri = resolve_uri(path, content["uri"].get<std::string>());
    if (const std::string u = uri_path(uri); u.size() >= 5 && u.substr(u.size() - 5) == ".json")
      fail("{}: external tilesets are not supported for splats ({})", path, uri);
    const std::vector<uint8_t> glb = fetch(uri, options);
    SplatSet s = decode_splats_glb(glb, uri, limits);
    // Into the root tile's frame: node matrix, Y-up to Z-up, tile transforms, back to Y-up.
    const glm::dmat4 m = glm::inverse(kYupToZup) * n.world * kYupToZup * s.transform;
    for (glm::vec3& p : s.positions) p = glm::vec3(m * glm::dvec4(glm::dvec3(p), 1.0));
    const glm::dmat3 linear(m);
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r)
        if (std::abs(linear[c][r] - (c == r ? 1.0 : 0.0)) > 1e-9)
          fail(
              "{}: tile {} turns or scales its splats relative to the root, which is not "
              "supported",
              path, uri);
    s.transform = glm::dmat4(1.0);
    return s;
  };
  auto error_of = [&](const json& tile) {
    const json& e = tile.value("geometricError", json(0.0));
    return e.is_number() ? e.get<double>() : 0.0;
  };
  const json& root = ts["root"];
  const glm::dmat4 root_world = tile_transform(root, path);
  // The cut: tiles with their splats, refined (replaced by their children: REPLACE, as the tiler
  // writes; ADD keeps the parent's splats too) largest error first.
  struct Entry {
    Node node;
    SplatSet splats;
  };
  std::vector<Entry> cut;
  cut.push_back({{&root, glm::dmat4(1.0), error_of(root)}, {}});
  cut.back().splats = load(cut.back().node);
  size_t total = cut.back().splats.size();
  auto larger = [&](size_t a, size_t b) { return cut[a].node.error < cut[b].node.error; };
  std::priority_queue<size_t, std::vector<size_t>, decltype(larger)> open(larger);
  open.push(0);
  std::vector<bool> dropped(1, false);
  while (!open.empty()) {
    const size_t at = open.top();
    open.pop();
    const json& tile = *cut[at].node.tile;
    // By reference into the document: the cut keeps pointers to its tiles.
    const auto found = tile.find("children");
    if (found == tile.end() || !found->is_array() || found->empty()) continue;
    const json& kids = *found;
    const bool add = tile.value("refine", std::string("REPLACE")) == "ADD";
    std::vector<Entry> next;
    size_t more = 0;
    for (const json& k : kids) {
      if (!k.is_object()) fail("{}: a child tile is not an object", path);
      Node n{&k, cut[at].node.world * tile_transform(k, path), error_of(k)};
      SplatSet s = load(n);
      more += s.size();
      next.push_back({n, std::move(s)});
    }
    const size_t after = total - (add ? 0 : cut[at].splats.size()) + more;
    if (after > limits.tileset_splats) break;  // the largest error cannot refine: done
    total = after;
    if (!add) dropped[at] = true;
    for (Entry& e : next) {
      cut.push_back(std::move(e));
      dropped.push_back(false);
      open.push(cut.size() - 1);
    }
  }
  SplatSet all;
  all.format = "3D Tiles of glTF KHR_gaussian_splatting";
  bool first = true;
  for (size_t i = 0; i < cut.size(); ++i) {
    if (dropped[i] || cut[i].splats.size() == 0) continue;
    SplatSet& s = cut[i].splats;
    if (first) {
      all.sh_degree = s.sh_degree;
      first = false;
    } else if (s.sh_degree != all.sh_degree) {
      fail("{}: tiles of different SH degrees are not supported", path);
    }
    append_splats(all, s);
  }
  // The root's transform, seen from glTF's Y-up frame, is the set's.
  all.transform = glm::inverse(kYupToZup) * root_world * kYupToZup;
  return all;
}

}  // namespace

SplatSet read_splat_tileset(const std::string& path, std::span<const uint8_t> bytes,
                            const SplatLimits& limits) {
  try {
    return read_unchecked(path, bytes, limits);
  } catch (const json::exception& e) {
    fail("{}: malformed tileset JSON: {}", path, e.what());
  }
}

}  // namespace stipple::io::splat_detail
