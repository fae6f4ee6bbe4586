#pragma once
// Minimal encoders for the 3D Tiles test corpus (pnts, glb, subtree, tileset.json), written
// from the specifications so the readers are checked against independently built bytes.
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace stipple::test {

using Bytes = std::vector<uint8_t>;

// An empty directory of its own for this process: <tmp>/stipple-<name>-<pid>.
inline std::filesystem::path fresh_temp_dir(const std::string& name) {
  std::filesystem::path p = std::filesystem::temp_directory_path() /
                            ("stipple-" + name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

inline void put_u32(Bytes& b, uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(uint8_t(v >> (8 * i)));
}
inline void put_u64(Bytes& b, uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(uint8_t(v >> (8 * i)));
}
template <typename T>
void append(Bytes& b, const std::vector<T>& values) {
  size_t at = b.size();
  b.resize(at + values.size() * sizeof(T));
  std::memcpy(b.data() + at, values.data(), values.size() * sizeof(T));
}
inline void pad(Bytes& b, size_t to, uint8_t with) {
  while (b.size() % to) b.push_back(with);
}
inline Bytes json_bytes(const nlohmann::json& j, size_t align = 8) {
  std::string s = j.dump();
  Bytes b(s.begin(), s.end());
  pad(b, align, ' ');
  return b;
}

inline Bytes make_pnts(const nlohmann::json& ft, Bytes ft_bin, const nlohmann::json& bt = nullptr,
                       Bytes bt_bin = {}) {
  Bytes ftj = json_bytes(ft);
  // The header is 28 bytes: pad the JSON so that the binary body starts 8-byte aligned.
  while ((28 + ftj.size()) % 8) ftj.push_back(' ');
  pad(ft_bin, 8, 0);
  Bytes btj = bt.is_null() ? Bytes() : json_bytes(bt);
  pad(bt_bin, 8, 0);
  Bytes out = {'p', 'n', 't', 's'};
  put_u32(out, 1);
  put_u32(out, uint32_t(28 + ftj.size() + ft_bin.size() + btj.size() + bt_bin.size()));
  put_u32(out, uint32_t(ftj.size()));
  put_u32(out, uint32_t(ft_bin.size()));
  put_u32(out, uint32_t(btj.size()));
  put_u32(out, uint32_t(bt_bin.size()));
  out.insert(out.end(), ftj.begin(), ftj.end());
  out.insert(out.end(), ft_bin.begin(), ft_bin.end());
  out.insert(out.end(), btj.begin(), btj.end());
  out.insert(out.end(), bt_bin.begin(), bt_bin.end());
  return out;
}

inline Bytes make_glb(const nlohmann::json& j, Bytes bin) {
  Bytes js = json_bytes(j, 4);
  pad(bin, 4, 0);
  Bytes out = {'g', 'l', 'T', 'F'};
  put_u32(out, 2);
  put_u32(out, uint32_t(12 + 8 + js.size() + (bin.empty() ? 0 : 8 + bin.size())));
  put_u32(out, uint32_t(js.size()));
  put_u32(out, 0x4E4F534A);
  out.insert(out.end(), js.begin(), js.end());
  if (!bin.empty()) {
    put_u32(out, uint32_t(bin.size()));
    put_u32(out, 0x004E4942);
    out.insert(out.end(), bin.begin(), bin.end());
  }
  return out;
}

inline Bytes make_subtree(const nlohmann::json& j, Bytes bin) {
  Bytes js = json_bytes(j);
  pad(bin, 8, 0);
  Bytes out = {'s', 'u', 'b', 't'};
  put_u32(out, 1);
  put_u64(out, js.size());
  put_u64(out, bin.size());
  out.insert(out.end(), js.begin(), js.end());
  out.insert(out.end(), bin.begin(), bin.end());
  return out;
}

inline void write_file(const std::filesystem::path& path, const Bytes& b) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}
inline void write_json(const std::filesystem::path& path, const nlohmann::json& j) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path) << j.dump(1);
}

// A simple pnts tile: n points on a grid inside [0, size]^3 around `rtc`, RGB colours.
inline Bytes grid_pnts(uint32_t n, float size, const double rtc[3], uint8_t shade) {
  std::vector<float> pos;
  Bytes rgb;
  for (uint32_t i = 0; i < n; ++i) {
    pos.push_back(size * float(i % 17) / 17.0f);
    pos.push_back(size * float((i / 17) % 17) / 17.0f);
    pos.push_back(size * float(i / 289 % 17) / 17.0f);
    rgb.insert(rgb.end(), {shade, uint8_t(i), uint8_t(255 - shade)});
  }
  Bytes bin;
  append(bin, pos);
  size_t rgb_offset = bin.size();
  bin.insert(bin.end(), rgb.begin(), rgb.end());
  nlohmann::json ft = {{"POINTS_LENGTH", n},
                       {"RTC_CENTER", {rtc[0], rtc[1], rtc[2]}},
                       {"POSITION", {{"byteOffset", 0}}},
                       {"RGB", {{"byteOffset", rgb_offset}}}};
  return make_pnts(ft, bin);
}

// An octree-like explicit tileset written to `dir`: `levels` levels of 2x2 children under a
// root (quadtree in x/y), each tile a pnts of `points` points; REPLACE refinement.
inline int write_grid_tileset(const std::filesystem::path& dir, int levels, uint32_t points,
                              double extent = 1000.0) {
  int count = 0;
  std::function<nlohmann::json(int, double, double, double)> tile = [&](int level, double x0,
                                                                        double y0, double size) {
    std::string name = "t" + std::to_string(count++) + ".pnts";
    double rtc[3] = {x0, y0, 0.0};
    write_file(dir / name, grid_pnts(points, float(size), rtc, uint8_t(40 * level)));
    nlohmann::json t = {{"boundingVolume",
                         {{"box",
                           {x0 + size / 2, y0 + size / 2, size / 2, size / 2, 0, 0, 0, size / 2, 0,
                            0, 0, size / 2}}}},
                        {"geometricError", size / 16.0},
                        {"content", {{"uri", name}}}};
    if (level + 1 < levels) {
      t["children"] = nlohmann::json::array();
      for (int c = 0; c < 4; ++c)
        t["children"].push_back(
            tile(level + 1, x0 + (c & 1) * size / 2, y0 + (c >> 1) * size / 2, size / 2));
    }
    return t;
  };
  nlohmann::json root = tile(0, 0, 0, extent);
  root["refine"] = "REPLACE";
  write_json(dir / "tileset.json",
             {{"asset", {{"version", "1.1"}}}, {"geometricError", extent / 8}, {"root", root}});
  return count;
}

}  // namespace stipple::test
