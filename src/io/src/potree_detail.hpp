#pragma once
// What the Potree 2.0 (potree.cpp) and Potree 1.x (potree1.cpp) readers share: node keys and
// names, a node's tile, and reading Potree's attribute types. Private to the io module.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/core/error.hpp"
#include "stipple/io/potree.hpp"

namespace stipple::io::potree_detail {

// A node: its level and cell on each axis. Child i is the octant x = bit 2, y = bit 1, z = bit 0.
struct Key {
  uint32_t level = 0, x = 0, y = 0, z = 0;
  Key child(int i) const {
    return {level + 1, 2 * x + ((i >> 2) & 1), 2 * y + ((i >> 1) & 1), 2 * z + (i & 1)};
  }
};

// Potree's node name: "r" and a child index a level.
inline std::string node_name(const Key& k) {
  std::string name = "r";
  for (uint32_t l = k.level; l > 0; --l) {
    const uint32_t b = l - 1;
    name += char('0' + (((k.x >> b) & 1) << 2 | ((k.y >> b) & 1) << 1 | ((k.z >> b) & 1)));
  }
  return name;
}

// The key of a node name; false when it is not "r" and octant digits (or deeper than the limit).
inline bool parse_node_name(const std::string& name, Key* k) {
  if (name.empty() || name[0] != 'r' || name.size() - 1 > size_t(kMaxPotreeDepth)) return false;
  *k = {};
  for (size_t i = 1; i < name.size(); ++i) {
    if (name[i] < '0' || name[i] > '7') return false;
    *k = k->child(name[i] - '0');
  }
  return true;
}

// A node's cube: the root cube halved `level` times.
inline glm::dvec3 node_min(const PotreeCloud& c, const Key& k) {
  const glm::dvec3 size = (c.cube_max - c.cube_min) / std::ldexp(1.0, int(k.level));
  return c.cube_min + size * glm::dvec3(k.x, k.y, k.z);
}

inline Tile node_tile(const PotreeCloud& c, const Key& k) {
  const double n = std::ldexp(1.0, int(k.level));
  const glm::dvec3 size = (c.cube_max - c.cube_min) / n;
  const glm::dvec3 centre = node_min(c, k) + size * 0.5;
  Tile t;
  t.volume.kind = BoundingVolume::Kind::Box;
  t.volume.box = {centre.x, centre.y,   centre.z, size.x / 2, 0, 0,
                  0,        size.y / 2, 0,        0,          0, size.z / 2};
  t.box = obb_of(t.volume, t.transform);
  t.geometric_error = c.spacing / n;
  t.refine = Refine::Add;
  return t;
}

// Bytes of one value of a Potree type (int8 ... uint64, float, double); 0 for any other.
inline int type_size(const std::string& t) {
  if (t == "int8" || t == "uint8") return 1;
  if (t == "int16" || t == "uint16") return 2;
  if (t == "int32" || t == "uint32" || t == "float") return 4;
  if (t == "int64" || t == "uint64" || t == "double") return 8;
  return 0;
}

template <typename T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

inline double read_value(const uint8_t* p, const std::string& t) {
  if (t == "int8") return load<int8_t>(p);
  if (t == "uint8") return load<uint8_t>(p);
  if (t == "int16") return load<int16_t>(p);
  if (t == "uint16") return load<uint16_t>(p);
  if (t == "int32") return load<int32_t>(p);
  if (t == "uint32") return load<uint32_t>(p);
  if (t == "int64") return double(load<int64_t>(p));
  if (t == "uint64") return double(load<uint64_t>(p));
  if (t == "float") return load<float>(p);
  return load<double>(p);
}

// The point count a node's URI carries (#points=N); throws naming the URI when absent or over
// the limit.
uint64_t node_points(const std::string& uri, const DecodeLimits& limits);

// Points relative to their centre, from absolute positions.
void set_positions(PointContent& out, const std::vector<glm::dvec3>& absolute);

// Potree 1.x (potree1.cpp): the tileset of a cloud.js, one .hrc file read into tiles, a node
// decoded.
// A node waiting in a hierarchy chunk's breadth-first order: its tile in the expansion (-1: the
// expanded tile itself) and its key.
struct QueuedNode {
  int32_t tile;
  Key key;
};

// Appends to `e` the children that `mask` names of `parent`, below the chunk's `root`, and
// queues them for their records; a child deeper than Potree's limit or past the tile limit is
// an error (`name`: the chunk, for messages).
inline void add_mask_children(const PotreeCloud& c, const Key& root, const QueuedNode& parent,
                              uint8_t mask, size_t tiles_now, const TilesetOptions& options,
                              const std::string& name, Expansion& e,
                              std::vector<QueuedNode>& queue) {
  for (int i = 0; i < 8; ++i) {
    if (!(mask & (1 << i))) continue;
    const Key k = parent.key.child(i);
    if (int(k.level) > kMaxPotreeDepth)
      fail("{}: node below depth {} (a corrupt child mask)", name, kMaxPotreeDepth);
    if (tiles_now + e.tiles.size() + 1 > options.max_tiles) {
      e.over_limit = true;
      fail("the tile limit of {} is reached (TilesetOptions::max_tiles)", options.max_tiles);
    }
    Tile child = node_tile(c, k);
    child.parent = parent.tile;
    child.depth = k.level - root.level - 1;
    const int32_t local = int32_t(e.tiles.size());
    if (parent.tile >= 0) e.tiles[size_t(parent.tile)].children.push_back(uint32_t(local));
    e.tiles.push_back(std::move(child));
    queue.push_back({local, k});
  }
}

Tileset load_potree1(const std::string& uri, const Fetcher& fetcher, const TilesetOptions& options);
Expansion read_hrc(uint32_t tile, const PendingChildren& pending, size_t tiles_now,
                   const Fetcher& fetcher, const TilesetOptions& options);
PointContent decode_node1(const PotreeCloud& c, std::span<const uint8_t> bytes,
                          const std::string& uri, const DecodeLimits& limits);

}  // namespace stipple::io::potree_detail
