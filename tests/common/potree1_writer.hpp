#pragma once
// A small Potree 1.x writer for tests, written from the format's description (PotreeConverter
// 1.x: cloud.js, an octreeDir of nodes named r0123..., folders of hierarchyStepSize digits, .hrc
// hierarchy files of 5-byte records breadth first down to `step` levels, .bin nodes of records
// with uint32 positions relative to the node's corner, or .las/.laz nodes): the reader is
// checked against independently built files. Format 1.7 names its attributes by strings, 1.8 by
// objects (with a type each); both carry a normal, oct16 (1.7) or three floats (1.8). Formats 1.3
// and 1.4 (PotreeConverter before 1.5) list the octree in cloud.js ("hierarchy": [name, points]
// a node, breadth first) with every node's file directly in data/: 1.4 as <name>.bin with uint32
// positions, 1.3 as <name> with float32 positions in the cloud's coordinates; their binary nodes
// hold POSITION_CARTESIAN and COLOR_PACKED, as those converters wrote them.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "potree_writer.hpp"
#include "stipple/io/las.hpp"

namespace stipple::test {

struct Potree1Options {
  std::string version = "1.8";    // 1.7: attribute names; 1.8: attribute objects; 1.3, 1.4: listed
  std::string format = "BINARY";  // or LAS, LAZ
  size_t node_cap = 500;
  int step = 2;  // hierarchyStepSize
};

struct Potree1WriteResult {
  size_t nodes = 0, hrc_files = 0;
  int depth = 0;
};

// The unit normal the writer gives point i.
inline std::array<float, 3> potree1_normal(size_t i) {
  const double a = double(i) * 0.7, b = double(i) * 0.3;
  const double n[3] = {std::cos(a) * std::cos(b), std::sin(a) * std::cos(b), std::sin(b)};
  return {float(n[0]), float(n[1]), float(n[2])};
}

// Octahedral encoding as PotreeConverter 1.x writes NORMAL_OCT16.
inline std::array<uint8_t, 2> potree1_oct16(std::array<float, 3> n) {
  const float norm1 = std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]);
  float x = n[0] / norm1, y = n[1] / norm1;
  const float z = n[2] / norm1;
  auto sign = [](float s) { return s < 0 ? -1.0f : 1.0f; };
  if (z < 0) {
    const float u = sign(x) * (1 - sign(y) * y), v = sign(y) * (1 - sign(x) * x);
    x = u, y = v;
  }
  return {uint8_t(std::min((x + 1) * 128, 255.0f)), uint8_t(std::min((y + 1) * 128, 255.0f))};
}

inline std::string potree1_folder(const std::string& name, int step) {
  std::string path = "r";
  const std::string digits = name.substr(1);
  for (size_t i = 0; i + size_t(step) <= digits.size(); i += size_t(step))
    path += "/" + digits.substr(i, size_t(step));
  return path;
}

// Writes cloud.js and data/ into `dir`. The cube is lo + 0.001 m x 2^17 so that every node's
// corner is on the millimetre grid of the points (positions come back exactly).
inline Potree1WriteResult write_potree1(const std::filesystem::path& dir,
                                        const std::vector<PotreePoint>& points,
                                        const Potree1Options& o = {}) {
  namespace fs = std::filesystem;
  fs::create_directories(dir / "data");
  const double scale = 0.001, size = 0.001 * (1 << 17);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const auto& p : points) {
    const double c[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], c[k]), hi[k] = std::max(hi[k], c[k]);
  }
  std::vector<PotreeTestNode> nodes = potree_octree(points, o.node_cap, lo, size);
  const bool names = o.version == "1.7";
  const bool listed = o.version == "1.3" || o.version == "1.4";  // the octree in cloud.js
  const std::string ext = o.format == "LAS"    ? ".las"
                          : o.format == "LAZ"  ? ".laz"
                          : o.version == "1.3" ? ""
                                               : ".bin";
  Potree1WriteResult result;
  result.nodes = nodes.size();
  for (const auto& n : nodes) {
    result.depth = std::max(result.depth, n.level);
    const fs::path folder = listed ? dir / "data" : dir / "data" / potree1_folder(n.name, o.step);
    fs::create_directories(folder);
    if (o.format != "BINARY") {
      io::LasWriteOptions w;
      w.version_minor = 2;
      w.point_format = 3;
      w.scale = glm::dvec3(scale);
      w.offset = glm::dvec3(lo[0], lo[1], lo[2]);
      w.compress = o.format == "LAZ";
      io::LasWriter writer(folder / (n.name + ext), w);
      io::PointBatch b;
      for (uint32_t i : n.points) {
        const PotreePoint& p = points[i];
        b.positions.emplace_back(p.x, p.y, p.z);
        b.intensity.push_back(p.intensity);
        b.return_number.push_back(p.return_number);
        b.number_of_returns.push_back(p.number_of_returns);
        b.classification.push_back(uint8_t(p.classification % 32));
        b.gps_time.push_back(p.gps_time);
        b.rgb.emplace_back(p.r, p.g, p.b);
      }
      writer.write(b);
      writer.close();
      continue;
    }
    std::vector<uint8_t> out;
    auto put = [&](const auto& v) {
      const auto* b = reinterpret_cast<const uint8_t*>(&v);
      out.insert(out.end(), b, b + sizeof(v));
    };
    for (uint32_t i : n.points) {
      const PotreePoint& p = points[i];
      const double c[3] = {p.x, p.y, p.z};
      if (listed) {
        for (int k = 0; k < 3; ++k)
          if (o.version == "1.3")
            put(float(c[k]));
          else
            put(uint32_t(std::lround((c[k] - n.min[k]) / scale)));
        put(uint8_t(p.r / 256)), put(uint8_t(p.g / 256)), put(uint8_t(p.b / 256)),
            put(uint8_t(255));
        continue;
      }
      for (int k = 0; k < 3; ++k) put(uint32_t(std::lround((c[k] - n.min[k]) / scale)));
      put(uint8_t(p.r / 256)), put(uint8_t(p.g / 256)), put(uint8_t(p.b / 256)), put(uint8_t(255));
      put(p.intensity), put(p.classification), put(p.return_number), put(p.number_of_returns);
      put(uint16_t(p.u32 & 0xffff));  // source id
      put(p.gps_time);
      if (names) {
        const auto oct = potree1_oct16(potree1_normal(i));
        put(oct[0]), put(oct[1]);
      } else {
        const auto nv = potree1_normal(i);
        put(nv[0]), put(nv[1]), put(nv[2]);
        put(p.i16), put(p.f32);
      }
    }
    std::ofstream(folder / (n.name + ext), std::ios::binary)
        .write(reinterpret_cast<const char*>(out.data()), std::streamsize(out.size()));
  }
  // .hrc: for the root and every node at a level multiple of `step` with children, its subtree
  // breadth first down to `step` levels below it.
  for (size_t r = 0; r < nodes.size() && !listed; ++r) {
    const PotreeTestNode& root = nodes[r];
    const bool has_children =
        std::any_of(root.children.begin(), root.children.end(), [](int c) { return c >= 0; });
    if (root.level % o.step != 0 || (r != 0 && !has_children)) continue;
    std::vector<int> order{int(r)};
    std::vector<uint8_t> hrc;
    for (size_t k = 0; k < order.size(); ++k) {
      const PotreeTestNode& n = nodes[size_t(order[k])];
      uint8_t mask = 0;
      for (int c = 0; c < 8; ++c)
        if (n.children[c] >= 0) mask |= uint8_t(1 << c);
      const uint32_t count = uint32_t(n.points.size());
      hrc.push_back(mask);
      const auto* cb = reinterpret_cast<const uint8_t*>(&count);
      hrc.insert(hrc.end(), cb, cb + 4);
      if (n.level < root.level + o.step)
        for (int c = 0; c < 8; ++c)
          if (n.children[c] >= 0) order.push_back(n.children[c]);
    }
    std::ofstream(dir / "data" / potree1_folder(root.name, o.step) / (root.name + ".hrc"),
                  std::ios::binary)
        .write(reinterpret_cast<const char*>(hrc.data()), std::streamsize(hrc.size()));
    ++result.hrc_files;
  }
  using nlohmann::json;
  json attributes;
  if (o.format != "BINARY") {
    attributes = o.format;
  } else if (listed) {
    attributes = {"POSITION_CARTESIAN", "COLOR_PACKED"};
  } else if (names) {
    attributes = {"POSITION_CARTESIAN", "COLOR_PACKED",  "INTENSITY",
                  "CLASSIFICATION",     "RETURN_NUMBER", "NUMBER_OF_RETURNS",
                  "SOURCE_ID",          "GPS_TIME",      "NORMAL_OCT16"};
  } else {
    auto a = [](const char* name, int size, int elements, const char* type) {
      return json{{"name", name},         {"size", size},
                  {"elements", elements}, {"elementSize", size / elements},
                  {"type", type},         {"description", ""}};
    };
    attributes = {a("POSITION_CARTESIAN", 12, 3, "int32"),
                  a("RGBA", 4, 4, "uint8"),
                  a("intensity", 2, 1, "uint16"),
                  a("classification", 1, 1, "uint8"),
                  a("return number", 1, 1, "uint8"),
                  a("number of returns", 1, 1, "uint8"),
                  a("source id", 2, 1, "uint16"),
                  a("gps-time", 8, 1, "double"),
                  a("NORMAL", 12, 3, "float"),
                  a("extra int16", 2, 1, "int16"),
                  a("extra float", 4, 1, "float")};
  }
  auto bbox = [](const double* l, const double* u) {
    return json{{"lx", l[0]}, {"ly", l[1]}, {"lz", l[2]}, {"ux", u[0]}, {"uy", u[1]}, {"uz", u[2]}};
  };
  const double cube_hi[3] = {lo[0] + size, lo[1] + size, lo[2] + size};
  json cloud = {{"version", o.version},
                {"octreeDir", "data"},
                {"projection", ""},
                {"points", points.size()},
                {"boundingBox", bbox(lo, cube_hi)},
                {"tightBoundingBox", bbox(lo, hi)},
                {"pointAttributes", attributes},
                {"spacing", size / 128},
                {"scale", scale}};
  if (listed) {
    json hierarchy = json::array();
    for (const auto& n : nodes) hierarchy.push_back({n.name, n.points.size()});
    cloud["hierarchy"] = hierarchy;
  } else {
    cloud["hierarchyStepSize"] = o.step;
  }
  std::ofstream(dir / "cloud.js") << cloud.dump(1);
  return result;
}

}  // namespace stipple::test
