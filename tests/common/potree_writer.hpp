#pragma once
// A small Potree 2.0 writer for tests, written from the format's description (PotreeConverter 2's
// metadata.json, hierarchy.bin of 22-byte records in breadth-first chunks with proxy nodes, and
// octree.bin, encoding DEFAULT): the readers are checked against independently built files.
// Every attribute type Potree defines is written (int8 ... uint64, float, double); or, for a real
// cloud (a LAS file's points, bench/web_vs_potree.mjs), the attributes PotreeConverter writes for
// LAS (potree_las_attributes).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace stipple::test {

struct PotreePoint {
  double x, y, z;
  uint16_t r, g, b, intensity;
  uint8_t classification, return_number, number_of_returns;
  double gps_time;
  int8_t i8;
  int16_t i16;
  int32_t i32;
  int64_t i64;
  uint32_t u32;
  uint64_t u64;
  float f32;
  // LAS fields the test attributes leave out (potree_las_attributes writes them).
  int16_t scan_angle;  // degrees: the rank of formats 0-5, the 0.006-degree count of 6-10
  uint8_t user_data;
  uint16_t point_source_id;
};

// n points on a jittered grid in [0, 100]^2 x [0, 20] around `origin`, every field varying.
inline std::vector<PotreePoint> potree_points(size_t n, double ox = 500000, double oy = 4000000) {
  std::vector<PotreePoint> pts(n);
  for (size_t i = 0; i < n; ++i) {
    PotreePoint& p = pts[i];
    const double u = double((i * 7919) % n) / double(n), v = double((i * 104729) % n) / double(n);
    p.x = ox + std::round(u * 100000) / 1000;
    p.y = oy + std::round(v * 100000) / 1000;
    p.z = 100 + std::round(20000 * std::sin(double(i) * 0.37) * std::sin(double(i) * 0.11)) / 1000;
    p.r = uint16_t((i * 37 % 256) * 257), p.g = uint16_t((i * 91 % 256) * 257);
    p.b = uint16_t((i * 13 % 256) * 257), p.intensity = uint16_t(i * 131);
    p.classification = uint8_t(i % 19), p.return_number = uint8_t(1 + i % 3);
    p.number_of_returns = 3, p.gps_time = 300000.0 + double(i) * 1e-4;
    p.i8 = int8_t(int(i % 256) - 128), p.i16 = int16_t(-int(i)), p.i32 = -int32_t(i) * 1000;
    p.i64 = -int64_t(i) * 100000000000LL, p.u32 = uint32_t(i) * 3u;
    p.u64 = uint64_t(i) * 10000000000ULL, p.f32 = float(i) * 0.25f;
  }
  return pts;
}

struct PotreeWriteResult {
  size_t nodes = 0, chunks = 0;
  int depth = 0;
};

// A node of the octree the writers build: its name (r, then child indices), cube corner and the
// points it keeps.
struct PotreeTestNode {
  std::string name;
  int level = 0;
  double min[3];
  std::vector<uint32_t> points;
  std::vector<int> children = std::vector<int>(8, -1);
  uint64_t offset = 0, bytes = 0;
};

// Builds the octree breadth first over the cube at `lo` of edge `size`: a node keeps every k-th
// of its points up to `node_cap` and passes the rest to its octants (x: bit 2, z: bit 0).
inline std::vector<PotreeTestNode> potree_octree(const std::vector<PotreePoint>& points,
                                                 size_t node_cap, const double lo[3], double size) {
  std::vector<PotreeTestNode> nodes;
  nodes.push_back({"r", 0, {lo[0], lo[1], lo[2]}, {}, std::vector<int>(8, -1)});
  std::vector<std::vector<uint32_t>> pending{{}};
  for (uint32_t i = 0; i < points.size(); ++i) pending[0].push_back(i);
  for (size_t at = 0; at < nodes.size(); ++at) {
    std::vector<uint32_t> mine = std::move(pending[at]);
    const double side = size / std::ldexp(1.0, nodes[at].level);
    std::vector<uint32_t> keep, rest[8];
    const size_t stride = std::max<size_t>(1, mine.size() / node_cap);
    // (A real cloud may hold more than node_cap points at one spot: kept at depth 24.)
    const bool last = nodes[at].level >= 24;
    for (size_t k = 0; k < mine.size(); ++k) {
      if (last || mine.size() <= node_cap || (k % stride == 0 && keep.size() < node_cap)) {
        keep.push_back(mine[k]);
        continue;
      }
      const PotreePoint& p = points[mine[k]];
      const double c[3] = {p.x, p.y, p.z};
      int child = 0;
      for (int a = 0; a < 3; ++a)
        if (c[a] >= nodes[at].min[a] + side / 2) child |= 1 << (2 - a);
      rest[child].push_back(mine[k]);
    }
    nodes[at].points = std::move(keep);
    for (int c = 0; c < 8; ++c) {
      if (rest[c].empty()) continue;
      PotreeTestNode child;
      child.name = nodes[at].name + char('0' + c);
      child.level = nodes[at].level + 1;
      for (int a = 0; a < 3; ++a)
        child.min[a] = nodes[at].min[a] + ((c >> (2 - a)) & 1 ? side / 2 : 0);
      nodes[at].children[c] = int(nodes.size());
      nodes.push_back(std::move(child));
      pending.push_back(std::move(rest[c]));
    }
  }
  return nodes;
}

// 48 bits of Morton code of three 16-bit values: bit 3k + axis is bit k of that axis.
inline uint64_t potree_morton(uint32_t x, uint32_t y, uint32_t z) {
  uint64_t code = 0;
  for (int k = 0; k < 16; ++k)
    code |= uint64_t((x >> k) & 1) << (3 * k) | uint64_t((y >> k) & 1) << (3 * k + 1) |
            uint64_t((z >> k) & 1) << (3 * k + 2);
  return code;
}

// An attribute after the position, as metadata.json names it: its bytes in a point's record
// (`put`) and its elements' values for the ranges metadata.json gives.
struct PotreeAttributeSpec {
  std::string name, type;
  int elements = 1, element_size = 1;
  std::function<void(const PotreePoint&, std::vector<uint8_t>&)> put;
  std::function<double(const PotreePoint&, int)> value;
};

// A scalar attribute of type T read from a point by `get`.
template <class T, class Get>
PotreeAttributeSpec potree_scalar(const char* name, const char* type, Get get) {
  return {name,
          type,
          1,
          int(sizeof(T)),
          [get](const PotreePoint& p, std::vector<uint8_t>& out) {
            const T v = T(get(p));
            const auto* b = reinterpret_cast<const uint8_t*>(&v);
            out.insert(out.end(), b, b + sizeof(T));
          },
          [get](const PotreePoint& p, int) { return double(T(get(p))); }};
}

inline PotreeAttributeSpec potree_rgb() {
  return {"rgb",
          "uint16",
          3,
          2,
          [](const PotreePoint& p, std::vector<uint8_t>& out) {
            for (uint16_t v : {p.r, p.g, p.b}) {
              out.push_back(uint8_t(v & 0xff));
              out.push_back(uint8_t(v >> 8));
            }
          },
          [](const PotreePoint& p, int k) {
            return double(k == 0 ? p.r : k == 1 ? p.g : p.b);
          }};
}

// The tests' attributes: every type Potree defines. `int64`: with the int64 and uint64 ones
// (potree-core's decoder has no 64-bit integers).
inline std::vector<PotreeAttributeSpec> potree_test_attributes(bool int64 = true) {
  using P = PotreePoint;
  std::vector<PotreeAttributeSpec> a{
      potree_rgb(),
      potree_scalar<uint16_t>("intensity", "uint16", [](const P& p) { return p.intensity; }),
      potree_scalar<uint8_t>("classification", "uint8",
                             [](const P& p) { return p.classification; }),
      potree_scalar<uint8_t>("return number", "uint8", [](const P& p) { return p.return_number; }),
      potree_scalar<uint8_t>("number of returns", "uint8",
                             [](const P& p) { return p.number_of_returns; }),
      potree_scalar<double>("gps-time", "double", [](const P& p) { return p.gps_time; }),
      potree_scalar<int8_t>("extra int8", "int8", [](const P& p) { return p.i8; }),
      potree_scalar<int16_t>("extra int16", "int16", [](const P& p) { return p.i16; }),
      potree_scalar<int32_t>("extra int32", "int32", [](const P& p) { return p.i32; })};
  if (int64)
    a.push_back(potree_scalar<int64_t>("extra int64", "int64", [](const P& p) { return p.i64; }));
  a.push_back(potree_scalar<uint32_t>("extra uint32", "uint32", [](const P& p) { return p.u32; }));
  if (int64)
    a.push_back(
        potree_scalar<uint64_t>("extra uint64", "uint64", [](const P& p) { return p.u64; }));
  a.push_back(potree_scalar<float>("extra float", "float", [](const P& p) { return p.f32; }));
  return a;
}

// The attributes PotreeConverter 2 writes for a LAS file's points, in its order: rgb and GPS time
// where the file has them; the scan angle as formats 0-5 give it (an int8 rank) or as 6-10 do (an
// int16 count of 0.006 degrees).
inline std::vector<PotreeAttributeSpec> potree_las_attributes(bool rgb, bool gps_time,
                                                              bool extended) {
  using P = PotreePoint;
  std::vector<PotreeAttributeSpec> a{
      potree_scalar<uint16_t>("intensity", "uint16", [](const P& p) { return p.intensity; }),
      potree_scalar<uint8_t>("return number", "uint8", [](const P& p) { return p.return_number; }),
      potree_scalar<uint8_t>("number of returns", "uint8",
                             [](const P& p) { return p.number_of_returns; }),
      potree_scalar<uint8_t>("classification", "uint8",
                             [](const P& p) { return p.classification; })};
  if (extended)
    a.push_back(
        potree_scalar<int16_t>("scan angle", "int16", [](const P& p) { return p.scan_angle; }));
  else
    a.push_back(
        potree_scalar<int8_t>("scan angle rank", "int8", [](const P& p) { return p.scan_angle; }));
  a.push_back(potree_scalar<uint8_t>("user data", "uint8", [](const P& p) { return p.user_data; }));
  a.push_back(potree_scalar<uint16_t>("point source id", "uint16",
                                      [](const P& p) { return p.point_source_id; }));
  if (gps_time)
    a.push_back(potree_scalar<double>("gps-time", "double", [](const P& p) { return p.gps_time; }));
  if (rgb) a.push_back(potree_rgb());
  return a;
}

// Writes metadata.json, hierarchy.bin and octree.bin into `dir`: the position (int32 at `scale`
// from the points' lower corner) and then `attributes`. A node keeps every k-th of its points up
// to `node_cap` and passes the rest to its octants; hierarchy chunks of `step` levels.
// `brotli`: a function compressing a node's bytes, for the BROTLI encoding (the attributes one
// after the other, position and rgb as Morton codes); empty: DEFAULT.
inline PotreeWriteResult write_potree_attributes(
    const std::filesystem::path& dir, const std::vector<PotreePoint>& points,
    const std::vector<PotreeAttributeSpec>& attributes, size_t node_cap = 500, int step = 2,
    const std::function<std::vector<uint8_t>(const std::vector<uint8_t>&)>& brotli = {},
    double scale = 0.001, const std::string& name = "stipple-test") {
  namespace fs = std::filesystem;
  fs::create_directories(dir);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const auto& p : points) {
    const double c[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], c[k]), hi[k] = std::max(hi[k], c[k]);
  }
  const double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}) * 1.01 + 1;
  const double offset[3] = {lo[0], lo[1], lo[2]};
  using Node = PotreeTestNode;
  std::vector<Node> nodes = potree_octree(points, node_cap, lo, size);
  // octree.bin: DEFAULT encoding, records in the attribute order below.
  std::vector<uint8_t> octree;
  auto put = [&](const auto& v) {
    const auto* b = reinterpret_cast<const uint8_t*>(&v);
    octree.insert(octree.end(), b, b + sizeof(v));
  };
  // Attribute sizes in record order, for BROTLI's attribute-after-attribute layout.
  std::vector<int> sizes{12};
  for (const auto& a : attributes) sizes.push_back(a.elements * a.element_size);
  size_t record = 0;
  for (int sz : sizes) record += size_t(sz);
  for (Node& n : nodes) {
    n.offset = octree.size();
    const size_t start = octree.size();
    for (uint32_t i : n.points) {
      const PotreePoint& p = points[i];
      put(int32_t(std::lround((p.x - offset[0]) / scale)));
      put(int32_t(std::lround((p.y - offset[1]) / scale)));
      put(int32_t(std::lround((p.z - offset[2]) / scale)));
      for (const auto& a : attributes) a.put(p, octree);
    }
    if (brotli && !n.points.empty()) {
      const size_t count = n.points.size();
      std::vector<uint8_t> packed;
      size_t in_record = 0;
      for (size_t a = 0; a < sizes.size(); ++a) {
        const bool position = a == 0, rgb = a > 0 && attributes[a - 1].name == "rgb";
        for (size_t i = 0; i < count; ++i) {
          const uint8_t* r = octree.data() + start + i * record + in_record;
          if (position || rgb) {
            uint32_t v[3] = {0, 0, 0};
            for (int k = 0; k < 3; ++k) {
              if (position) std::memcpy(&v[k], r + 4 * k, 4);
              if (rgb) v[k] = uint32_t(r[2 * k] | r[2 * k + 1] << 8);
            }
            const uint64_t lower = potree_morton(v[0] & 0xffff, v[1] & 0xffff, v[2] & 0xffff);
            const uint64_t upper = potree_morton(v[0] >> 16, v[1] >> 16, v[2] >> 16);
            const auto* l = reinterpret_cast<const uint8_t*>(&lower);
            const auto* u = reinterpret_cast<const uint8_t*>(&upper);
            if (position) packed.insert(packed.end(), u, u + 8);  // upper 64 bits first
            packed.insert(packed.end(), l, l + 8);
          } else {
            packed.insert(packed.end(), r, r + sizes[a]);
          }
        }
        in_record += size_t(sizes[a]);
      }
      octree.resize(start);
      const std::vector<uint8_t> z = brotli(packed);
      octree.insert(octree.end(), z.begin(), z.end());
    }
    n.bytes = octree.size() - n.offset;
  }
  // hierarchy.bin: a chunk for the root and for every node at a level multiple of `step`, each
  // its nodes breadth first down to `step` levels below its root; deeper roots are proxies.
  std::vector<uint8_t> hierarchy;
  PotreeWriteResult result;
  result.nodes = nodes.size();
  std::map<int, std::pair<uint64_t, uint64_t>> chunk_of;  // root node -> (offset, size)
  std::function<void(int)> write_chunk = [&](int root) {
    std::vector<int> order{root}, proxies;
    for (size_t k = 0; k < order.size(); ++k) {
      const Node& n = nodes[size_t(order[k])];
      const bool proxy =
          n.level > nodes[size_t(root)].level && n.level == nodes[size_t(root)].level + step;
      if (proxy) {
        proxies.push_back(order[k]);
        continue;
      }
      for (int c = 0; c < 8; ++c)
        if (n.children[c] >= 0) order.push_back(n.children[c]);
    }
    for (int p : proxies) write_chunk(p);  // children first: their offsets are known here
    const uint64_t start = hierarchy.size();
    for (int id : order) {
      const Node& n = nodes[size_t(id)];
      const bool proxy = std::find(proxies.begin(), proxies.end(), id) != proxies.end();
      uint8_t mask = 0;
      for (int c = 0; c < 8; ++c)
        if (n.children[c] >= 0) mask |= uint8_t(1 << c);
      const uint8_t type = proxy ? 2 : mask ? 0 : 1;
      const uint32_t count = uint32_t(n.points.size());
      const uint64_t off = proxy ? chunk_of[id].first : n.offset;
      const uint64_t len = proxy ? chunk_of[id].second : n.bytes;
      uint8_t rec[22];
      rec[0] = type, rec[1] = mask;
      std::memcpy(rec + 2, &count, 4);
      std::memcpy(rec + 6, &off, 8);
      std::memcpy(rec + 14, &len, 8);
      hierarchy.insert(hierarchy.end(), rec, rec + 22);
    }
    chunk_of[root] = {start, hierarchy.size() - start};
    ++result.chunks;
  };
  // The root chunk must come first in the file (firstChunkSize at offset 0): write the others
  // into a separate buffer and place the root chunk in front.
  write_chunk(0);
  const auto [root_at, root_size] = chunk_of[0];
  std::vector<uint8_t> ordered(hierarchy.begin() + std::ptrdiff_t(root_at),
                               hierarchy.begin() + std::ptrdiff_t(root_at + root_size));
  ordered.insert(ordered.end(), hierarchy.begin(), hierarchy.begin() + std::ptrdiff_t(root_at));
  // Proxy offsets pointed into `hierarchy`; everything before the root chunk moved up by its size.
  for (size_t at = 0; at < ordered.size(); at += 22) {
    if (ordered[at] != 2) continue;
    uint64_t off;
    std::memcpy(&off, &ordered[at + 6], 8);
    off += root_size;
    std::memcpy(&ordered[at + 6], &off, 8);
  }
  for (const Node& n : nodes) result.depth = std::max(result.depth, n.level);
  std::ofstream(dir / "octree.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(octree.data()), std::streamsize(octree.size()));
  std::ofstream(dir / "hierarchy.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(ordered.data()), std::streamsize(ordered.size()));
  using nlohmann::json;
  // Every attribute with its range, as PotreeConverter writes them (Potree's reader needs them).
  auto ranges = [&](int n, auto value) {
    std::vector<double> mn(size_t(n), 1e300), mx(size_t(n), -1e300);
    for (const auto& p : points)
      for (int k = 0; k < n; ++k) {
        const double v = double(value(p, k));
        mn[size_t(k)] = std::min(mn[size_t(k)], v), mx[size_t(k)] = std::max(mx[size_t(k)], v);
      }
    return std::pair{mn, mx};
  };
  auto attr = [](const std::string& a_name, int n, int a_size, const std::string& type,
                 const std::pair<std::vector<double>, std::vector<double>>& range) {
    return json{{"name", a_name},     {"description", ""},     {"size", n * a_size},
                {"numElements", n},   {"elementSize", a_size}, {"type", type},
                {"min", range.first}, {"max", range.second}};
  };
  // json::array: a braced list of one object is that object under clang, an array under gcc.
  json meta_attributes =
      json::array({attr("position", 3, 4, "int32", ranges(3, [](const PotreePoint& p, int k) {
                          return k == 0 ? p.x : k == 1 ? p.y : p.z;
                        }))});
  for (const auto& a : attributes)
    meta_attributes.push_back(
        attr(a.name, a.elements, a.element_size, a.type, ranges(a.elements, a.value)));
  json meta = {
      {"version", "2.0"},
      {"name", name},
      {"description", ""},
      {"points", points.size()},
      {"projection", ""},
      {"hierarchy", {{"firstChunkSize", root_size}, {"stepSize", step}, {"depth", result.depth}}},
      {"offset", {offset[0], offset[1], offset[2]}},
      {"scale", {scale, scale, scale}},
      {"spacing", size / 128},
      {"boundingBox",
       {{"min", {lo[0], lo[1], lo[2]}}, {"max", {lo[0] + size, lo[1] + size, lo[2] + size}}}},
      {"encoding", brotli ? "BROTLI" : "DEFAULT"},
      {"attributes", meta_attributes}};
  std::ofstream(dir / "metadata.json") << meta.dump(1);
  return result;
}

// The tests' cloud: every attribute type (`int64`: with the int64 and uint64 ones).
inline PotreeWriteResult write_potree(
    const std::filesystem::path& dir, const std::vector<PotreePoint>& points, size_t node_cap = 500,
    int step = 2, bool int64 = true,
    const std::function<std::vector<uint8_t>(const std::vector<uint8_t>&)>& brotli = {}) {
  return write_potree_attributes(dir, points, potree_test_attributes(int64), node_cap, step,
                                 brotli);
}

}  // namespace stipple::test
