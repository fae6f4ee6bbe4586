// stipple.read: LAS/LAZ/COPC points into one packed numpy structured array whose fields are
// named as laspy names them (laspy 2.x point dimensions and sub-fields), plus x, y, z: the scaled
// coordinates as doubles.
#include "read.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>

#include <fmt/format.h>

#include "stipple/core/error.hpp"

namespace stipple::python {
namespace {

template <typename T>
void put(uint8_t* dst, T value) {
  std::memcpy(dst, &value, sizeof(T));
}

// Column writers: `base` is the record of the batch's first point, `stride` the record size.
using Fill = std::function<void(const io::PointBatch&, uint8_t* base, size_t stride)>;

template <typename T, typename Get>
Fill column(Get get) {
  return [get](const io::PointBatch& b, uint8_t* base, size_t stride) {
    for (size_t i = 0; i < b.size(); ++i) put<T>(base + i * stride, static_cast<T>(get(b, i)));
  };
}

// numpy scalar type codes of the Extra Bytes data types 1-10 (table 25), little endian.
constexpr const char* kExtraTypes[10] = {"u1",  "i1",  "<u2", "<i2", "<u4",
                                         "<i4", "<u8", "<i8", "<f4", "<f8"};
constexpr size_t kExtraSizes[10] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};

// The value of an extra-bytes scalar of data type 1-10 at p, as a double.
double extra_value(uint8_t type, const uint8_t* p) {
  auto get = [p]<typename T>(T) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return static_cast<double>(v);
  };
  switch (type) {
    case 1:
      return get(uint8_t());
    case 2:
      return get(int8_t());
    case 3:
      return get(uint16_t());
    case 4:
      return get(int16_t());
    case 5:
      return get(uint32_t());
    case 6:
      return get(int32_t());
    case 7:
      return get(uint64_t());
    case 8:
      return get(int64_t());
    case 9:
      return get(float());
    default:
      return get(double());
  }
}

}  // namespace

std::vector<FieldSpec> point_fields(const io::LasHeader& h) {
  std::vector<FieldSpec> f;
  const bool legacy = h.point_format <= 5;
  const glm::dvec3 scale = h.scale, offset = h.offset;
  // laspy's X, Y, Z are the stored integers; x, y, z the scaled coordinates.
  for (int a = 0; a < 3; ++a) {
    f.push_back({std::string(1, char('X' + a)), "<i4", 4,
                 column<int32_t>([a, scale, offset](const io::PointBatch& b, size_t i) {
                   return std::llround((b.positions[i][a] - offset[a]) / scale[a]);
                 })});
  }
  for (int a = 0; a < 3; ++a)
    f.push_back(
        {std::string(1, char('x' + a)), "<f8", 8,
         column<double>([a](const io::PointBatch& b, size_t i) { return b.positions[i][a]; })});
  f.push_back({"intensity", "<u2", 2,
               column<uint16_t>([](const io::PointBatch& b, size_t i) { return b.intensity[i]; })});
  f.push_back({"return_number", "u1", 1, column<uint8_t>([](const io::PointBatch& b, size_t i) {
                 return b.return_number[i];
               })});
  f.push_back({"number_of_returns", "u1", 1, column<uint8_t>([](const io::PointBatch& b, size_t i) {
                 return b.number_of_returns[i];
               })});
  auto flag = [](int bit) {
    return column<uint8_t>(
        [bit](const io::PointBatch& b, size_t i) { return (b.flags[i] >> bit) & 1; });
  };
  f.push_back({"synthetic", "u1", 1, flag(0)});
  f.push_back({"key_point", "u1", 1, flag(1)});
  f.push_back({"withheld", "u1", 1, flag(2)});
  if (!legacy) {
    f.push_back({"overlap", "u1", 1, flag(3)});
    f.push_back({"scanner_channel", "u1", 1, column<uint8_t>([](const io::PointBatch& b, size_t i) {
                   return (b.flags[i] >> 4) & 3;
                 })});
  }
  f.push_back({"scan_direction_flag", "u1", 1, flag(6)});
  f.push_back({"edge_of_flight_line", "u1", 1, flag(7)});
  f.push_back({"classification", "u1", 1, column<uint8_t>([](const io::PointBatch& b, size_t i) {
                 return b.classification[i];
               })});
  f.push_back({"user_data", "u1", 1,
               column<uint8_t>([](const io::PointBatch& b, size_t i) { return b.user_data[i]; })});
  if (legacy)
    f.push_back({"scan_angle_rank", "i1", 1, column<int8_t>([](const io::PointBatch& b, size_t i) {
                   return std::lround(b.scan_angle[i]);
                 })});
  else  // stored in steps of 0.006 degrees
    f.push_back({"scan_angle", "<i2", 2, column<int16_t>([](const io::PointBatch& b, size_t i) {
                   return std::lround(double(b.scan_angle[i]) / 0.006);
                 })});
  f.push_back({"point_source_id", "<u2", 2, column<uint16_t>([](const io::PointBatch& b, size_t i) {
                 return b.point_source_id[i];
               })});
  if (h.has_gps_time)
    f.push_back({"gps_time", "<f8", 8,
                 column<double>([](const io::PointBatch& b, size_t i) { return b.gps_time[i]; })});
  if (h.has_rgb)
    for (int c = 0; c < 3; ++c)
      f.push_back({c == 0   ? "red"
                   : c == 1 ? "green"
                            : "blue",
                   "<u2", 2, column<uint16_t>([c](const io::PointBatch& b, size_t i) {
                     return b.rgb[i][c];
                   })});
  if (h.has_nir)
    f.push_back({"nir", "<u2", 2,
                 column<uint16_t>([](const io::PointBatch& b, size_t i) { return b.nir[i]; })});
  if (h.has_waveform) {
    using W = io::PointBatch::WavePacket;
    auto wave = [](auto member, const char* name, const char* type, size_t size) {
      return FieldSpec{name, type, size,
                       [member, size](const io::PointBatch& b, uint8_t* base, size_t stride) {
                         for (size_t i = 0; i < b.size(); ++i)
                           std::memcpy(base + i * stride, &(b.wave_packets[i].*member), size);
                       }};
    };
    f.push_back(wave(&W::descriptor_index, "wavepacket_index", "u1", 1));
    f.push_back(wave(&W::data_offset, "wavepacket_offset", "<u8", 8));
    f.push_back(wave(&W::data_size, "wavepacket_size", "<u4", 4));
    f.push_back(wave(&W::return_point_location, "return_point_wave_location", "<f4", 4));
    f.push_back(wave(&W::dx, "x_t", "<f4", 4));
    f.push_back(wave(&W::dy, "y_t", "<f4", 4));
    f.push_back(wave(&W::dz, "z_t", "<f4", 4));
  }
  // Extra bytes, in the order of their descriptors. Scaled ones (options bits 3, 4), as laspy
  // gives them, are doubles; the others keep their type; arrays (deprecated types 11-30) and
  // undocumented bytes (type 0) are sub-arrays.
  size_t at = 0;
  std::set<std::string> names;
  for (const auto& d : f) names.insert(d.name);
  for (const auto& e : h.extra_bytes) {
    const size_t here = at;
    at += e.size;
    if (e.size == 0 || at > h.extra_bytes_per_point) break;
    std::string name = e.name.empty() ? fmt::format("extra_{}", here) : e.name;
    if (!names.insert(name).second) name = fmt::format("{}_{}", name, here);
    if (e.data_type == 0 || e.data_type > 30) {
      f.push_back({name, fmt::format("({},)u1", e.size), e.size,
                   [here, n = e.size](const io::PointBatch& b, uint8_t* base, size_t stride) {
                     const size_t per = b.extra_bytes_per_point;
                     for (size_t i = 0; i < b.size(); ++i)
                       std::memcpy(base + i * stride, b.extra_bytes.data() + i * per + here, n);
                   }});
      continue;
    }
    const uint8_t type = uint8_t((e.data_type - 1) % 10 + 1);
    const int count = (e.data_type - 1) / 10 + 1;
    const bool scaled = (e.options & (8 | 16)) != 0;
    const std::string shape = count == 1 ? "" : fmt::format("({},)", count);
    if (!scaled) {
      f.push_back({name, shape + kExtraTypes[type - 1], e.size,
                   [here, n = e.size](const io::PointBatch& b, uint8_t* base, size_t stride) {
                     const size_t per = b.extra_bytes_per_point;
                     for (size_t i = 0; i < b.size(); ++i)
                       std::memcpy(base + i * stride, b.extra_bytes.data() + i * per + here, n);
                   }});
      continue;
    }
    std::array<double, 3> s{1, 1, 1}, o{0, 0, 0};
    for (int c = 0; c < count; ++c) {
      if (e.options & 8) s[c] = e.scale[c];
      if (e.options & 16) o[c] = e.offset[c];
    }
    f.push_back({name, shape + "<f8", size_t(8 * count),
                 [here, type, count, s, o](const io::PointBatch& b, uint8_t* base, size_t stride) {
                   const size_t per = b.extra_bytes_per_point, step = kExtraSizes[type - 1];
                   for (size_t i = 0; i < b.size(); ++i)
                     for (int c = 0; c < count; ++c) {
                       const double v =
                           extra_value(type, b.extra_bytes.data() + i * per + here + c * step);
                       put<double>(base + i * stride + 8 * c, v * s[c] + o[c]);
                     }
                 }});
  }
  return f;
}

ReadResult read_points(const std::string& path,
                       const std::optional<std::vector<std::string>>& wanted,
                       const std::function<void()>& before_read) {
  ReadResult r;
  io::LasReader reader{std::filesystem::path(path)};
  const io::LasHeader& h = reader.header();
  std::vector<FieldSpec> all = point_fields(h);
  if (wanted) {
    for (const auto& name : *wanted) {
      auto it =
          std::find_if(all.begin(), all.end(), [&](const FieldSpec& s) { return s.name == name; });
      if (it == all.end()) {
        std::string known;
        for (const auto& s : all) known += (known.empty() ? "" : ", ") + s.name;
        fail("{}: no field '{}' in point format {} (fields: {})", path, name, h.point_format,
             known);
      }
      r.fields.push_back(*it);
    }
  } else {
    r.fields = std::move(all);
  }
  for (auto& s : r.fields) {
    s.offset = r.itemsize;
    r.itemsize += s.size;
  }
  if (before_read) before_read();
  const uint64_t n = h.point_count;
  // A crafted header must not make this allocate terabytes: LasReader has already checked an
  // uncompressed file's count against its size; LASzip records vary in size, so for LAZ the
  // array is allocated up front for at most kUpFront points and grows as points are decoded
  // (a count the data does not hold ends in a decoding error naming the file).
  constexpr uint64_t kUpFront = 1 << 20;
  const uint64_t up_front = h.compressed ? std::min(n, kUpFront) : n;
  if (r.itemsize > 0 && n > std::numeric_limits<size_t>::max() / r.itemsize)
    fail("{}: the header declares {} points, more than this machine can address", path, n);
  r.data.reserve(size_t(up_front) * r.itemsize);
  io::PointBatch batch;
  uint64_t done = 0;
  constexpr size_t kChunk = 1 << 16;
  while (done < n) {
    batch.clear();
    const size_t got = reader.read(batch, size_t(std::min<uint64_t>(kChunk, n - done)));
    if (got == 0) fail("{}: ended after {} of the {} points its header declares", path, done, n);
    r.data.resize(size_t(done + got) * r.itemsize);
    uint8_t* base = r.data.data() + done * r.itemsize;
    for (const auto& s : r.fields) s.fill(batch, base + s.offset, r.itemsize);
    done += got;
  }
  r.points = n;
  return r;
}

}  // namespace stipple::python
