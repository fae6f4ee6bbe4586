#include "tiler_tileset.hpp"

#include <algorithm>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stipple/io/subtree.hpp"
#include "stipple/tiler/subtree_writer.hpp"
#include "tiler_files.hpp"

namespace stipple::tiler::detail {

namespace {

// Implicit octree over the cube: availability from the nodes (every node and its ancestors are
// tiles; those with points have content), in subtrees of S levels rooted at levels 0, S, 2S...
// Tile (level, x, y, z) is NodeKey{level, x, y, z}: the cube's subdivision, as implicit tiling
// subdivides the root box, with geometric error root / 2^level (the spacing halves per level).
nlohmann::json write_implicit(Build& b) {
  using nlohmann::json;
  std::map<NodeKey, bool> available;  // key -> has content
  int deepest = 0;
  for (auto& [k, info] : b.nodes) {
    available[k] = available[k] || info.points > 0;
    deepest = std::max(deepest, k.level);
    for (NodeKey a = k; a.level > 0;) {
      a = a.parent();
      if (!available.emplace(a, false).second) break;
    }
  }
  const int levels = deepest + 1, S = std::min(b.opt.subtree_levels, levels);
  struct Bits {
    std::vector<bool> tiles, content, children;
  };
  std::map<NodeKey, Bits> subtrees;
  const uint64_t tiles_per_subtree = io::subtree_tile_count(8, S);
  auto bits_of = [&](const NodeKey& root) -> Bits& {
    Bits& bits = subtrees[root];
    if (bits.tiles.empty()) {
      bits.tiles.assign(tiles_per_subtree, false);
      bits.content.assign(tiles_per_subtree, false);
      bits.children.assign(size_t(1) << (3 * S), false);
    }
    return bits;
  };
  for (auto& [k, has_content] : available) {
    const int base = k.level / S * S, local = k.level - base;
    const NodeKey root{base, k.x >> local, k.y >> local, k.z >> local};
    const uint64_t morton = io::morton_index(k.x - (root.x << local), k.y - (root.y << local),
                                             k.z - (root.z << local), 8);
    Bits& bits = bits_of(root);
    const uint64_t index = io::availability_index(8, local, morton);
    bits.tiles[index] = true;
    bits.content[index] = has_content;
    if (local == 0 && k.level > 0) {
      // A subtree's root: available as a child subtree of the subtree above.
      const NodeKey parent{base - S, k.x >> S, k.y >> S, k.z >> S};
      bits_of(parent).children[io::morton_index(k.x - (parent.x << S), k.y - (parent.y << S),
                                                k.z - (parent.z << S), 8)] = true;
    }
  }
  fs::create_directories(b.dir / "subtrees");
  for (auto& [root, bits] : subtrees) {
    std::vector<uint8_t> bytes = write_subtree(bits.tiles, bits.content, bits.children);
    write_file(
        b.dir / "subtrees" / fmt::format("{}.{}.{}.{}.subtree", root.level, root.x, root.y, root.z),
        bytes.data(), bytes.size());
  }
  const double h = b.cube_size * 0.5;
  const glm::dvec3 c = b.cube_min + glm::dvec3(h);
  const char* ext = b.opt.format == Format::Glb ? "glb" : "pnts";
  return {{"boundingVolume", {{"box", {c.x, c.y, c.z, h, 0, 0, 0, h, 0, 0, 0, h}}}},
          {"geometricError", spacing(b, 0)},
          {"refine", "ADD"},
          {"content", {{"uri", fmt::format("tiles/{{level}}-{{x}}-{{y}}-{{z}}.{}", ext)}}},
          {"implicitTiling",
           {{"subdivisionScheme", "OCTREE"},
            {"subtreeLevels", S},
            {"availableLevels", levels},
            {"subtrees", {{"uri", "subtrees/{level}.{x}.{y}.{z}.subtree"}}}}}};
}

}  // namespace

void write_tileset(Build& b) {
  using nlohmann::json;
  const TileOptions& opt = b.opt;
  std::map<NodeKey, std::vector<NodeKey>> children;
  for (auto& [k, info] : b.nodes)
    if (k.level > 0) children[k.parent()].push_back(k);
  // Boxes: content union children, padded a little so float rounding never leaves a point out.
  const double pad = std::max(0.001, b.content.precision);
  const char* ext = opt.format == Format::Glb ? ".glb" : ".pnts";
  std::function<json(const NodeKey&, Box&)> tile = [&](const NodeKey& k, Box& box) {
    const NodeInfo& info = b.nodes.at(k);
    box = info.content;
    json kids = json::array();
    for (const NodeKey& c : children[k]) {
      Box cb;
      kids.push_back(tile(c, cb));
      box.add(cb);
    }
    glm::dvec3 lo = box.min - pad, hi = box.max + pad;
    glm::dvec3 c = (lo + hi) * 0.5, h = (hi - lo) * 0.5;
    json t = {{"boundingVolume", {{"box", {c.x, c.y, c.z, h.x, 0, 0, 0, h.y, 0, 0, 0, h.z}}}},
              {"geometricError", spacing(b, k.level)},
              {"refine", "ADD"}};
    if (info.points > 0) t["content"] = {{"uri", "tiles/" + k.name() + ext}};
    if (!kids.empty()) t["children"] = std::move(kids);
    return t;
  };
  json root;
  if (opt.implicit) {
    root = write_implicit(b);
  } else {
    Box root_box;
    root = tile(NodeKey{}, root_box);
  }
  const glm::dmat3& m = b.frame.enu_to_ecef;
  const glm::dvec3& o = b.frame.origin_ecef;
  // Column-major ENU -> ECEF.
  root["transform"] = {m[0].x, m[0].y, m[0].z, 0, m[1].x, m[1].y, m[1].z, 0,
                       m[2].x, m[2].y, m[2].z, 0, o.x,    o.y,    o.z,    1};
  json tileset = {{"asset",
                   {{"version", opt.format == Format::Glb || opt.implicit ? "1.1" : "1.0"},
                    {"generator", "stipple tile"}}},
                  {"geometricError", 2 * b.root_spacing},
                  {"root", root},
                  {"extras",
                   {{"stipple",
                     {{"points", b.total_points},
                      {"rootSpacing", b.root_spacing},
                      {"geometricErrorPerSpacing", 1.0},
                      {"cube", {b.cube_min.x, b.cube_min.y, b.cube_min.z, b.cube_size}}}}}}};
  std::string text = tileset.dump(1);
  Profiler::Scope write(&b.prof, Step::Write, text.size());
  write_file(b.dir / "tileset.json", text.data(), text.size());
}

}  // namespace stipple::tiler::detail
