#include "stipple/tiler/pnts_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <draco/compression/encode.h>
#include <draco/point_cloud/point_cloud_builder.h>
#include <nlohmann/json.hpp>

#include "stipple/core/error.hpp"

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

// The tile as one pnts file: header, feature table (JSON, binary), batch table (JSON, binary).
std::vector<uint8_t> assemble(const json& ft, const std::vector<uint8_t>& ftb, const json& bt,
                              const std::vector<uint8_t>& btb) {
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

// 3DTILES_draco_point_compression: positions (float relative to RTC_CENTER, quantized by Draco
// finely enough for the input precision), RGB and the batch-table properties in one Draco
// point cloud; the other attributes are lossless (GPS time as float seconds after the tile's
// earliest: quantizing it made the tiles larger, not smaller).
std::vector<uint8_t> write_pnts_draco(std::span<const TilePoint> points,
                                      const ContentOptions& options) {
  const size_t n = points.size();
  Box box = bounds_of(points);
  const glm::dvec3 centre = (box.min + box.max) * 0.5, extent = box.max - box.min;
  double t0 = n ? points[0].gps_time : 0;
  for (const TilePoint& p : points) t0 = std::min(t0, p.gps_time);
  draco::PointCloudBuilder builder;
  builder.Start(uint32_t(n));
  const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int rgb =
      options.rgb ? builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8) : -1;
  const int inten = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT16);
  const int cls = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT8);
  const int ret = builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT8);
  const int gps = options.gps_time ? builder.AddAttribute(draco::GeometryAttribute::GENERIC, 1,
                                                          draco::DT_FLOAT32)
                                   : -1;
  for (size_t i = 0; i < n; ++i) {
    const TilePoint& p = points[i];
    const draco::PointIndex at{uint32_t(i)};
    const float f[3] = {float(p.x - centre.x), float(p.y - centre.y), float(p.z - centre.z)};
    builder.SetAttributeValueForPoint(pos, at, f);
    if (rgb >= 0) {
      const uint8_t c[3] = {p.r, p.g, p.b};
      builder.SetAttributeValueForPoint(rgb, at, c);
    }
    builder.SetAttributeValueForPoint(inten, at, &p.intensity);
    builder.SetAttributeValueForPoint(cls, at, &p.classification);
    builder.SetAttributeValueForPoint(ret, at, &p.return_number);
    if (gps >= 0) {
      const float t = float(p.gps_time - t0);
      builder.SetAttributeValueForPoint(gps, at, &t);
    }
  }
  std::unique_ptr<draco::PointCloud> cloud = builder.Finalize(false);
  if (!cloud) fail("Draco could not build the tile's point cloud");
  // Quantization: the step over the tile's largest extent at most the input precision.
  const double largest = std::max({extent.x, extent.y, extent.z, 1e-9});
  const int bits = std::clamp(int(std::ceil(std::log2(largest / options.precision + 1))), 8, 30);
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, bits);
  encoder.SetSpeedOptions(5, 5);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodePointCloudToBuffer(*cloud, &buffer);
  if (!status.ok()) fail("Draco could not encode the tile: {}", status.error_msg_string());
  auto id = [&](int a) { return cloud->attribute(a)->unique_id(); };

  json ft = {{"POINTS_LENGTH", n},
             {"RTC_CENTER", {centre.x, centre.y, centre.z}},
             {"POSITION", {{"byteOffset", 0}}}};
  json draco_ft = {{"POSITION", id(pos)}};
  if (rgb >= 0) {
    ft["RGB"] = {{"byteOffset", 0}};
    draco_ft["RGB"] = id(rgb);
  }
  ft["extensions"] = {
      {"3DTILES_draco_point_compression",
       {{"properties", draco_ft}, {"byteOffset", 0}, {"byteLength", buffer.size()}}}};
  std::vector<uint8_t> ftb(buffer.data(), buffer.data() + buffer.size());
  pad(ftb, 8, 0);
  json bt = {
      {"INTENSITY", {{"byteOffset", 0}, {"componentType", "UNSIGNED_SHORT"}, {"type", "SCALAR"}}},
      {"CLASSIFICATION",
       {{"byteOffset", 0}, {"componentType", "UNSIGNED_BYTE"}, {"type", "SCALAR"}}},
      {"RETURN_NUMBER",
       {{"byteOffset", 0}, {"componentType", "UNSIGNED_BYTE"}, {"type", "SCALAR"}}}};
  json draco_bt = {
      {"INTENSITY", id(inten)}, {"CLASSIFICATION", id(cls)}, {"RETURN_NUMBER", id(ret)}};
  if (gps >= 0) {
    bt["GPS_TIME"] = {{"byteOffset", 0}, {"componentType", "FLOAT"}, {"type", "SCALAR"}};
    bt["extras"] = {{"offsets", {{"GPS_TIME", t0}}}};
    draco_bt["GPS_TIME"] = id(gps);
  }
  bt["extensions"] = {{"3DTILES_draco_point_compression", {{"properties", draco_bt}}}};
  return assemble(ft, ftb, bt, {});
}

}  // namespace

std::vector<uint8_t> write_pnts(std::span<const TilePoint> points, const ContentOptions& options) {
  if (options.compression == Compression::Draco) return write_pnts_draco(points, options);
  if (options.compression != Compression::None)
    fail("pnts content is compressed with Draco only (--compress draco)");
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

  return assemble(ft, ftb, bt, btb);
}

}  // namespace stipple::tiler
