#include "stipple/tools/records.hpp"

#include <algorithm>
#include <cstring>

#include <fmt/format.h>

#include "stipple/core/error.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/math/geo.hpp"
#include "stipple/pointcloud/filters.hpp"

namespace stipple::tools {
namespace {

template <typename T>
double load_as_double(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return double(v);
}

double load_scalar(uint8_t base_type, const uint8_t* p) {
  switch (base_type) {
    case 1:
      return load_as_double<uint8_t>(p);
    case 2:
      return load_as_double<int8_t>(p);
    case 3:
      return load_as_double<uint16_t>(p);
    case 4:
      return load_as_double<int16_t>(p);
    case 5:
      return load_as_double<uint32_t>(p);
    case 6:
      return load_as_double<int32_t>(p);
    case 7:
      return load_as_double<uint64_t>(p);
    case 8:
      return load_as_double<int64_t>(p);
    case 9:
      return load_as_double<float>(p);
    default:
      return load_as_double<double>(p);
  }
}

void add_point_fields(PointRecord& r, const io::PointBatch& b, size_t i) {
  auto add = [&](const char* name, io::GeoValue v) { r.fields.emplace_back(name, std::move(v)); };
  if (!b.classification.empty()) {
    add("classification", double(b.classification[i]));
    add("classification_name", pc::classification_name(b.classification[i]));
  }
  if (!b.intensity.empty()) add("intensity", double(b.intensity[i]));
  if (!b.return_number.empty()) add("return_number", double(b.return_number[i]));
  if (!b.number_of_returns.empty()) add("number_of_returns", double(b.number_of_returns[i]));
  if (!b.gps_time.empty()) add("gps_time", b.gps_time[i]);
  if (!b.point_source_id.empty()) add("point_source_id", double(b.point_source_id[i]));
  if (!b.scan_angle.empty()) add("scan_angle", double(b.scan_angle[i]));
  if (!b.user_data.empty()) add("user_data", double(b.user_data[i]));
  if (!b.flags.empty()) {
    const uint8_t f = b.flags[i];
    add("synthetic", double(f & 1));
    add("key_point", double((f >> 1) & 1));
    add("withheld", double((f >> 2) & 1));
    add("overlap", double((f >> 3) & 1));
    add("scanner_channel", double((f >> 4) & 3));
    add("scan_direction", double((f >> 6) & 1));
    add("edge_of_flight_line", double((f >> 7) & 1));
  }
  if (!b.rgb.empty()) {
    add("red", double(b.rgb[i].r));
    add("green", double(b.rgb[i].g));
    add("blue", double(b.rgb[i].b));
  }
  if (!b.nir.empty()) add("nir", double(b.nir[i]));
  if (!b.wave_packets.empty()) {
    const auto& w = b.wave_packets[i];
    add("wave_descriptor", double(w.descriptor_index));
    add("wave_offset", double(w.data_offset));
    add("wave_size", double(w.data_size));
    add("wave_return_location", double(w.return_point_location));
  }
}

}  // namespace

std::vector<std::pair<std::string, io::GeoValue>> decode_extra_bytes(
    const std::vector<io::ExtraBytesDescriptor>& descriptors, const uint8_t* bytes, size_t size) {
  std::vector<std::pair<std::string, io::GeoValue>> out;
  size_t at = 0;
  for (const io::ExtraBytesDescriptor& d : descriptors) {
    if (d.size == 0 || at + d.size > size) break;
    const uint8_t* p = bytes + at;
    at += d.size;
    if (d.data_type == 0 || d.data_type > 30) {
      std::string hex;
      for (size_t k = 0; k < d.size; ++k) hex += fmt::format("{:02x}", p[k]);
      out.emplace_back(d.name, hex);
      continue;
    }
    const uint8_t base = uint8_t((d.data_type - 1) % 10 + 1);
    const size_t count = size_t((d.data_type - 1) / 10 + 1);
    const size_t width = d.size / count;
    std::vector<double> values;
    for (size_t k = 0; k < count; ++k) {
      double v = load_scalar(base, p + k * width);
      if (d.options & 8) v *= d.scale[k];
      if (d.options & 16) v += d.offset[k];
      values.push_back(v);
    }
    if (count == 1)
      out.emplace_back(d.name, values[0]);
    else
      out.emplace_back(d.name, values);
  }
  if (at < size) {
    std::string hex;
    for (size_t k = at; k < size; ++k) hex += fmt::format("{:02x}", bytes[k]);
    out.emplace_back("extra_bytes", hex);
  }
  return out;
}

PointRecord read_point_record(const RecordSource& source, const pc::PickHit& hit) {
  PointRecord r;
  const pc::PointCloud* cloud = source.cloud;
  r.local = y_up_to_z_up(hit.point);
  io::PointBatch batch;
  if (cloud && hit.source_point != pc::PickHit::kNoSourcePoint) {
    if (source.scene) {
      io::generate_scene(*source.scene, hit.source_point, 1, batch);
      r.source = "procedural scene";
      r.index = hit.source_point;
    } else if (!cloud->files.empty()) {
      const auto& starts = cloud->file_first_point;
      const size_t f = size_t(std::upper_bound(starts.begin(), starts.end(), hit.source_point) -
                              starts.begin()) -
                       1;
      r.source = cloud->files[f].string();
      r.index = hit.source_point - starts[f];
      io::LasReader reader(cloud->files[f]);
      if (r.index >= reader.header().point_count)
        fail("{}: point {} is beyond the file's {} points", r.source, r.index,
             reader.header().point_count);
      reader.seek(r.index);
      if (reader.read(batch, 1) != 1) fail("{}: cannot read point {} again", r.source, r.index);
      add_point_fields(r, batch, 0);
      r.from_source = true;
      r.position = batch.positions[0];
      if (batch.extra_bytes_per_point > 0)
        for (auto& field : decode_extra_bytes(reader.header().extra_bytes, batch.extra_bytes.data(),
                                              batch.extra_bytes_per_point))
          r.fields.push_back(std::move(field));
    }
    if (source.scene && batch.size() == 1) {
      add_point_fields(r, batch, 0);
      r.from_source = true;
      r.position = batch.positions[0];
    }
  }
  if (!r.from_source) {
    // A streamed tile: the packed copy (float position, the attribute word and extras).
    r.source = cloud ? "loaded points" : "streamed tile";
    const uint32_t a = hit.vertex.attributes;
    r.position = r.local;
    r.fields.emplace_back("classification", double((a >> 16) & 0xffu));
    r.fields.emplace_back("classification_name", pc::classification_name((a >> 16) & 0xffu));
    r.fields.emplace_back("intensity", double(a & 0xffffu));
    r.fields.emplace_back("return_number", double((a >> 24) & 0xfu));
    r.fields.emplace_back("number_of_returns", double(a >> 28));
    if (hit.has_extra) {
      r.fields.emplace_back("gps_time", hit.gps_origin + double(hit.extra.gps));
      r.fields.emplace_back("point_source_id", double(hit.extra.word & 0xffffu));
    }
    r.fields.emplace_back("red", double(hit.vertex.rgba & 0xffu));
    r.fields.emplace_back("green", double((hit.vertex.rgba >> 8) & 0xffu));
    r.fields.emplace_back("blue", double((hit.vertex.rgba >> 16) & 0xffu));
  } else if (cloud && cloud->enu_origin) {
    // Lon/lat sources: the file holds degrees; the local frame is ENU metres.
    r.local = geo::LocalEnu(*cloud->enu_origin).from_geodetic(r.position);
  } else {
    r.local = r.position;
  }
  if (cloud && cloud->enu_origin && !r.from_source)
    r.position = geo::LocalEnu(*cloud->enu_origin).to_geodetic(r.local);
  const io::LonLatTransform to_lon_lat(source.crs);
  r.lon_lat = to_lon_lat(r.position);
  return r;
}

}  // namespace stipple::tools
