#include "stipple/tiler/pnts_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <nlohmann/json.hpp>

#include "stipple/tiler/glb_writer.hpp"

namespace stipple::tiler {
namespace {

using nlohmann::json;

template <typename T>
void append(std::vector<uint8_t>& out, const T& v) {
  const auto* p = reinterpret_cast<const uint8_t*>(&v);
  out.insert(out.end(), p, p + sizeof(T));
}

void pad(std::vector<uint8_t>& bytes, size_t to, uint8_t with) {
  bytes.resize((bytes.size() + to - 1) / to * to, with);
}

// JSON padded with spaces so that what follows it starts 8-byte aligned in the file.
std::vector<uint8_t> json_chunk(const json& j, size_t file_offset) {
  std::string s = j.dump();
  std::vector<uint8_t> out(s.begin(), s.end());
  while ((file_offset + out.size()) % 8) out.push_back(' ');
  return out;
}

}  // namespace

std::vector<uint8_t> write_pnts(std::span<const TilePoint> points, const ContentOptions& options) {
  const size_t n = points.size();
  Box box = bounds_of(points);
  glm::dvec3 centre = (box.min + box.max) * 0.5, extent = box.max - box.min;
  json ft = {{"POINTS_LENGTH", n}, {"RTC_CENTER", {centre.x, centre.y, centre.z}}};
  std::vector<uint8_t> ftb;
  if (quantization_keeps(std::max({extent.x, extent.y, extent.z}), options.precision)) {
    glm::dvec3 scale = glm::max(extent, glm::dvec3(1e-9)), lo = box.min - centre;
    ft["POSITION_QUANTIZED"] = {{"byteOffset", 0}};
    ft["QUANTIZED_VOLUME_OFFSET"] = {lo.x, lo.y, lo.z};
    ft["QUANTIZED_VOLUME_SCALE"] = {scale.x, scale.y, scale.z};
    for (const TilePoint& p : points) {
      glm::dvec3 t = (glm::dvec3(p.x, p.y, p.z) - box.min) / scale * 65535.0;
      for (int k = 0; k < 3; ++k) append(ftb, uint16_t(std::clamp(std::lround(t[k]), 0L, 65535L)));
    }
  } else {
    ft["POSITION"] = {{"byteOffset", 0}};
    for (const TilePoint& p : points) {
      float f[3] = {float(p.x - centre.x), float(p.y - centre.y), float(p.z - centre.z)};
      append(ftb, f);
    }
  }
  if (options.rgb) {
    pad(ftb, 4, 0);
    ft["RGB"] = {{"byteOffset", ftb.size()}};
    for (const TilePoint& p : points) ftb.insert(ftb.end(), {p.r, p.g, p.b});
  }
  pad(ftb, 8, 0);

  // Batch table binary: the 4-byte property first, then the narrower ones, each aligned.
  json bt = json::object();
  std::vector<uint8_t> btb;
  if (options.gps_time && n > 0) {
    // Float seconds after the tile's earliest time, which extras.offsets holds: DOUBLE is valid
    // 3D Tiles 1.0 but has no glTF equivalent, so converters to 1.1 refuse it.
    double t0 = points[0].gps_time;
    for (const TilePoint& p : points) t0 = std::min(t0, p.gps_time);
    bt["GPS_TIME"] = {{"byteOffset", 0}, {"componentType", "FLOAT"}, {"type", "SCALAR"}};
    bt["extras"] = {{"offsets", {{"GPS_TIME", t0}}}};
    for (const TilePoint& p : points) append(btb, float(p.gps_time - t0));
  }
  bt["INTENSITY"] = {
      {"byteOffset", btb.size()}, {"componentType", "UNSIGNED_SHORT"}, {"type", "SCALAR"}};
  for (const TilePoint& p : points) append(btb, p.intensity);
  bt["CLASSIFICATION"] = {
      {"byteOffset", btb.size()}, {"componentType", "UNSIGNED_BYTE"}, {"type", "SCALAR"}};
  for (const TilePoint& p : points) btb.push_back(p.classification);
  bt["RETURN_NUMBER"] = {
      {"byteOffset", btb.size()}, {"componentType", "UNSIGNED_BYTE"}, {"type", "SCALAR"}};
  for (const TilePoint& p : points) btb.push_back(p.return_number);
  pad(btb, 8, 0);

  const size_t header = 28;
  std::vector<uint8_t> ftj = json_chunk(ft, header);
  std::vector<uint8_t> btj = json_chunk(bt, header + ftj.size() + ftb.size());
  std::vector<uint8_t> out;
  out.reserve(header + ftj.size() + ftb.size() + btj.size() + btb.size());
  out.insert(out.end(), {'p', 'n', 't', 's'});
  append(out, uint32_t(1));
  append(out, uint32_t(header + ftj.size() + ftb.size() + btj.size() + btb.size()));
  append(out, uint32_t(ftj.size()));
  append(out, uint32_t(ftb.size()));
  append(out, uint32_t(btj.size()));
  append(out, uint32_t(btb.size()));
  out.insert(out.end(), ftj.begin(), ftj.end());
  out.insert(out.end(), ftb.begin(), ftb.end());
  out.insert(out.end(), btj.begin(), btj.end());
  out.insert(out.end(), btb.begin(), btb.end());
  return out;
}

}  // namespace stipple::tiler
