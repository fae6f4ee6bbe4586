#pragma once
// A small Entwine Point Tile writer for tests, written from the EPT description (entwine.io):
// ept.json with the schema and cube bounds, ept-hierarchy/D-X-Y-Z.json files (a count per node,
// -1 where the subtree continues in its own file) and ept-data/D-X-Y-Z.{laz,bin,zst}. Binary
// records hold the schema's dimensions in order: X, Y, Z as scaled int32, then every type EPT
// defines (signed and unsigned 1-8 bytes, float 4 and 8). LAZ nodes are written by stipple's
// LAS writer (LASzip); zstd nodes by libzstd.
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "stipple/io/las.hpp"
#include "stipple/io/point_batch.hpp"

namespace stipple::test {

struct EptPoint {
  double x, y, z;  // on a 0.01 grid
  uint16_t intensity, red, green, blue;
  uint8_t classification, return_number, number_of_returns;
  double gps_time;
  int8_t i8;
  int16_t i16;
  int64_t i64;
  uint32_t u32;
  uint64_t u64;
  float f32;
};

inline std::vector<EptPoint> ept_points(size_t n) {
  std::vector<EptPoint> pts(n);
  for (size_t i = 0; i < n; ++i) {
    EptPoint& p = pts[i];
    const double u = double((i * 7919) % n) / double(n), v = double((i * 104729) % n) / double(n);
    p.x = 600000 + std::round(u * 20000) / 100;
    p.y = 5000000 + std::round(v * 20000) / 100;
    p.z = 50 + std::round(1000 * std::sin(double(i) * 0.3)) / 100;
    p.intensity = uint16_t(i * 17), p.red = uint16_t((i * 37 % 256) * 256);
    p.green = uint16_t((i * 91 % 256) * 256), p.blue = uint16_t((i * 13 % 256) * 256);
    p.classification = uint8_t(i % 20), p.return_number = uint8_t(1 + i % 2);
    p.number_of_returns = 2, p.gps_time = 1e8 + double(i) * 1e-3;
    p.i8 = int8_t(int(i % 256) - 128), p.i16 = int16_t(-int(i));
    p.i64 = -int64_t(i) * 1000000007LL, p.u32 = uint32_t(i) * 7u;
    p.u64 = uint64_t(i) * 1000000000039ULL, p.f32 = float(i) * 0.5f;
  }
  return pts;
}

struct EptWriteResult {
  size_t nodes = 0, hierarchy_files = 0;
  int depth = 0;
};

// `data_type`: laszip, binary or zstandard. A node keeps every k-th of its points up to
// `node_cap`; hierarchy files are split every `step` levels.
inline EptWriteResult write_ept(const std::filesystem::path& dir, const std::vector<EptPoint>& pts,
                                const std::string& data_type, size_t node_cap = 400, int step = 2) {
  namespace fs = std::filesystem;
  using nlohmann::json;
  fs::create_directories(dir / "ept-hierarchy");
  fs::create_directories(dir / "ept-data");
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (const auto& p : pts) {
    const double c[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], c[k]), hi[k] = std::max(hi[k], c[k]);
  }
  const double size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}) * 1.01 + 1;
  const double offset[3] = {std::floor(lo[0]), std::floor(lo[1]), std::floor(lo[2])};
  const double scale = 0.01;
  using Key = std::tuple<int, int, int, int>;
  std::map<Key, std::vector<uint32_t>> nodes;
  std::vector<std::pair<Key, std::vector<uint32_t>>> work{{{0, 0, 0, 0}, {}}};
  for (uint32_t i = 0; i < pts.size(); ++i) work[0].second.push_back(i);
  EptWriteResult r;
  while (!work.empty()) {
    auto [key, mine] = std::move(work.back());
    work.pop_back();
    const auto [d, x, y, z] = key;
    const double side = size / std::ldexp(1.0, d);
    std::vector<uint32_t> keep;
    std::map<int, std::vector<uint32_t>> rest;
    const size_t stride = std::max<size_t>(1, mine.size() / node_cap);
    for (size_t k = 0; k < mine.size(); ++k) {
      if (mine.size() <= node_cap || (k % stride == 0 && keep.size() < node_cap)) {
        keep.push_back(mine[k]);
        continue;
      }
      const EptPoint& p = pts[mine[k]];
      const int cx = p.x >= lo[0] + (x + 0.5) * side, cy = p.y >= lo[1] + (y + 0.5) * side,
                cz = p.z >= lo[2] + (z + 0.5) * side;
      rest[cx | cy << 1 | cz << 2].push_back(mine[k]);
    }
    nodes[key] = std::move(keep);
    r.depth = std::max(r.depth, d);
    for (auto& [c, list] : rest)
      work.push_back(
          {{d + 1, 2 * x + (c & 1), 2 * y + (c >> 1 & 1), 2 * z + (c >> 2 & 1)}, std::move(list)});
  }
  r.nodes = nodes.size();
  // Data files.
  auto name = [](const Key& k) {
    return std::to_string(std::get<0>(k)) + "-" + std::to_string(std::get<1>(k)) + "-" +
           std::to_string(std::get<2>(k)) + "-" + std::to_string(std::get<3>(k));
  };
  for (const auto& [key, list] : nodes) {
    if (data_type == "laszip") {
      io::LasWriteOptions o;
      o.point_format = 7;
      o.scale = glm::dvec3(scale);
      o.offset = {offset[0], offset[1], offset[2]};
      o.compress = true;
      io::LasWriter w(dir / "ept-data" / (name(key) + ".laz"), o);
      io::PointBatch b;
      for (uint32_t i : list) {
        const EptPoint& p = pts[i];
        b.positions.push_back({p.x, p.y, p.z});
        b.intensity.push_back(p.intensity);
        b.classification.push_back(p.classification);
        b.return_number.push_back(p.return_number);
        b.number_of_returns.push_back(p.number_of_returns);
        b.gps_time.push_back(p.gps_time);
        b.rgb.push_back({p.red, p.green, p.blue});
      }
      w.write(b);
      w.close();
      continue;
    }
    std::vector<uint8_t> bin;
    auto put = [&](const auto& v) {
      const auto* b = reinterpret_cast<const uint8_t*>(&v);
      bin.insert(bin.end(), b, b + sizeof(v));
    };
    for (uint32_t i : list) {
      const EptPoint& p = pts[i];
      put(int32_t(std::lround((p.x - offset[0]) / scale)));
      put(int32_t(std::lround((p.y - offset[1]) / scale)));
      put(int32_t(std::lround((p.z - offset[2]) / scale)));
      put(p.intensity), put(p.classification), put(p.return_number), put(p.number_of_returns);
      put(p.gps_time), put(p.red), put(p.green), put(p.blue), put(p.i8), put(p.i16), put(p.i64);
      put(p.u32), put(p.u64), put(p.f32);
    }
    if (data_type == "zstandard") {
      std::vector<uint8_t> z(ZSTD_compressBound(bin.size()));
      z.resize(ZSTD_compress(z.data(), z.size(), bin.data(), bin.size(), 3));
      bin = std::move(z);
    }
    std::ofstream(dir / "ept-data" / (name(key) + (data_type == "binary" ? ".bin" : ".zst")),
                  std::ios::binary)
        .write(reinterpret_cast<const char*>(bin.data()), std::streamsize(bin.size()));
  }
  // Hierarchy files: one for the root and for every node at a depth multiple of `step`; a file
  // lists its root and the nodes below down to `step` levels, those at the last level with -1.
  std::map<Key, json> files;
  for (const auto& [key, list] : nodes) {
    const int d = std::get<0>(key);
    const int base = d / step * step;
    const int up = d - base;
    const Key root{base, std::get<1>(key) >> up, std::get<2>(key) >> up, std::get<3>(key) >> up};
    files[root][name(key)] = list.size();
    if (up == 0 && d > 0) {
      const Key parent{base - step, std::get<1>(key) >> step, std::get<2>(key) >> step,
                       std::get<3>(key) >> step};
      files[parent][name(key)] = -1;
    }
  }
  for (const auto& [root, j] : files)
    std::ofstream(dir / "ept-hierarchy" / (name(root) + ".json")) << j.dump();
  r.hierarchy_files = files.size();
  auto dim = [](const char* n, const char* type, int size) {
    return json{{"name", n}, {"type", type}, {"size", size}};
  };
  json schema = json::array();
  if (data_type == "laszip") {
    for (int k = 0; k < 3; ++k) {
      json d = dim(k == 0 ? "X" : k == 1 ? "Y" : "Z", "signed", 4);
      d["scale"] = scale, d["offset"] = offset[k];
      schema.push_back(d);
    }
    for (const auto& d :
         {dim("Intensity", "unsigned", 2), dim("ReturnNumber", "unsigned", 1),
          dim("NumberOfReturns", "unsigned", 1), dim("Classification", "unsigned", 1),
          dim("GpsTime", "float", 8), dim("Red", "unsigned", 2), dim("Green", "unsigned", 2),
          dim("Blue", "unsigned", 2)})
      schema.push_back(d);
  } else {
    for (int k = 0; k < 3; ++k) {
      json d = dim(k == 0 ? "X" : k == 1 ? "Y" : "Z", "signed", 4);
      d["scale"] = scale, d["offset"] = offset[k];
      schema.push_back(d);
    }
    for (const auto& d :
         {dim("Intensity", "unsigned", 2), dim("Classification", "unsigned", 1),
          dim("ReturnNumber", "unsigned", 1), dim("NumberOfReturns", "unsigned", 1),
          dim("GpsTime", "float", 8), dim("Red", "unsigned", 2), dim("Green", "unsigned", 2),
          dim("Blue", "unsigned", 2), dim("Int8", "signed", 1), dim("Int16", "signed", 2),
          dim("Int64", "signed", 8), dim("UInt32", "unsigned", 4), dim("UInt64", "unsigned", 8),
          dim("Float", "float", 4)})
      schema.push_back(d);
  }
  json ept = {{"version", "1.0.0"},
              {"dataType", data_type},
              {"hierarchyType", "json"},
              {"points", pts.size()},
              {"span", 128},
              {"bounds", {lo[0], lo[1], lo[2], lo[0] + size, lo[1] + size, lo[2] + size}},
              {"boundsConforming", {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]}},
              {"schema", schema},
              {"srs", json::object()}};
  std::ofstream(dir / "ept.json") << ept.dump(1);
  return r;
}

// Rewrites the "version" of the ept.json in `dir` (early Entwine wrote "0.0.0" over the 1.0
// layout); returns the new text.
inline std::string set_ept_version(const std::filesystem::path& dir, const std::string& version) {
  std::string text;
  {
    std::ifstream in(dir / "ept.json");
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const size_t at = text.find("\"1.0.0\"");
  if (at != std::string::npos) text.replace(at, 7, "\"" + version + "\"");
  std::ofstream(dir / "ept.json") << text;
  return text;
}

}  // namespace stipple::test
