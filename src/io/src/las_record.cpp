// Point record decoding/encoding for formats 0-10 (LAS 1.4 R15 section 2.6), shared by LAS and
// LAZ reading and by the writer.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "las_detail.hpp"
#include "stipple/core/error.hpp"

namespace stipple::io {

uint16_t las_format_record_size(uint8_t point_format) {
  static constexpr uint16_t kSizes[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  return point_format <= 10 ? kSizes[point_format] : 0;
}

size_t extra_bytes_type_size(uint8_t data_type, uint8_t options) {
  if (data_type == 0) return options;
  if (data_type > 30) return 0;
  // Types 11-30 are the deprecated 2- and 3-component arrays of types 1-10.
  static constexpr size_t kScalar[10] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  const int base = (data_type - 1) % 10;
  const int count = (data_type - 1) / 10 + 1;
  return kScalar[base] * count;
}

namespace detail {

RecordLayout record_layout(uint8_t format, uint16_t record_length) {
  RecordLayout l;
  l.format = format;
  l.record_length = record_length;
  l.base_size = las_format_record_size(format);
  switch (format) {
    case 1:
      l.gps = 20;
      break;
    case 2:
      l.rgb = 20;
      break;
    case 3:
      l.gps = 20, l.rgb = 28;
      break;
    case 4:
      l.gps = 20, l.wave = 28;
      break;
    case 5:
      l.gps = 20, l.rgb = 28, l.wave = 34;
      break;
    case 6:
      l.gps = 22;
      break;
    case 7:
      l.gps = 22, l.rgb = 30;
      break;
    case 8:
      l.gps = 22, l.rgb = 30, l.nir = 36;
      break;
    case 9:
      l.gps = 22, l.wave = 30;
      break;
    case 10:
      l.gps = 22, l.rgb = 30, l.nir = 36, l.wave = 38;
      break;
    default:
      break;
  }
  return l;
}

// One record's position, shared by decode_records and decode_positions so that both give the
// same doubles. Scale and offset in double: coordinates of e.g. UTM at mm precision need it.
namespace {
glm::dvec3 decode_position(const uint8_t* r, const glm::dvec3& scale, const glm::dvec3& offset) {
  return glm::dvec3(load<int32_t>(r) * scale.x + offset.x,
                    load<int32_t>(r + 4) * scale.y + offset.y,
                    load<int32_t>(r + 8) * scale.z + offset.z);
}

// The three 16-bit channels at `at` (a record's RGB field).
glm::u16vec3 decode_rgb(const uint8_t* at) {
  return {load<uint16_t>(at), load<uint16_t>(at + 2), load<uint16_t>(at + 4)};
}

// Return number, number of returns and class of one record, shared by decode_records and
// decode_drawn: the legacy formats pack them in two bytes, formats 6-10 in three.
struct Returns {
  uint8_t return_number, number_of_returns, classification;
};
Returns decode_returns(const uint8_t* r, bool extended) {
  if (!extended) return {uint8_t(r[14] & 7), uint8_t((r[14] >> 3) & 7), uint8_t(r[15] & 0x1f)};
  return {uint8_t(r[14] & 15), uint8_t(r[14] >> 4), r[16]};
}
}  // namespace

void decode_records(const uint8_t* records, size_t n, const RecordLayout& l,
                    const glm::dvec3& scale, const glm::dvec3& offset, PointBatch& b) {
  const size_t eb = l.extra_bytes();
  // Every array is sized once and filled by index: a push_back per field and point (a capacity
  // check and a size update each, a dozen a point) cost more than the decoding itself. Each
  // array grows from its own size, as appending did.
  auto grow = [n](auto& v) {
    const size_t at = v.size();
    v.resize(at + n);
    return v.data() + at;
  };
  glm::dvec3* pos = grow(b.positions);
  uint16_t* intensity = grow(b.intensity);
  uint8_t* ret = grow(b.return_number);
  uint8_t* nret = grow(b.number_of_returns);
  uint8_t* cls_out = grow(b.classification);
  uint8_t* flags_out = grow(b.flags);
  float* angle = grow(b.scan_angle);
  uint8_t* user = grow(b.user_data);
  uint16_t* source = grow(b.point_source_id);
  double* gps = l.gps >= 0 ? grow(b.gps_time) : nullptr;
  glm::u16vec3* rgb = l.rgb >= 0 ? grow(b.rgb) : nullptr;
  uint16_t* nir = l.nir >= 0 ? grow(b.nir) : nullptr;
  PointBatch::WavePacket* wave = l.wave >= 0 ? grow(b.wave_packets) : nullptr;
  uint8_t* extra = nullptr;
  if (eb) {
    const size_t at = b.extra_bytes.size();
    b.extra_bytes.resize(at + n * eb);
    extra = b.extra_bytes.data() + at;
  }
  const bool extended = l.extended();
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* r = records + i * l.record_length;
    pos[i] = decode_position(r, scale, offset);
    intensity[i] = load<uint16_t>(r + 12);
    const uint8_t b14 = r[14], b15 = r[15];
    const Returns returns = decode_returns(r, extended);
    ret[i] = returns.return_number;
    nret[i] = returns.number_of_returns;
    cls_out[i] = returns.classification;
    if (!extended) {
      // Legacy formats have no overlap flag; class 12 ("overlap") is its stand-in.
      uint8_t flags = (b15 >> 5) & 7;
      if (returns.classification == 12) flags |= 8;
      flags |= (b14 & 0xc0);  // scan direction, edge of flight line
      flags_out[i] = flags;
      angle[i] = static_cast<float>(static_cast<int8_t>(r[16]));
      user[i] = r[17];
      source[i] = load<uint16_t>(r + 18);
    } else {
      flags_out[i] = b15;  // same bit layout as PointBatch::flags
      user[i] = r[17];
      angle[i] = static_cast<float>(load<int16_t>(r + 18) * 0.006);
      source[i] = load<uint16_t>(r + 20);
    }
    if (gps) gps[i] = load<double>(r + l.gps);
    if (rgb) {
      rgb[i] = decode_rgb(r + l.rgb);
    }
    if (nir) nir[i] = load<uint16_t>(r + l.nir);
    if (wave) {
      const uint8_t* w = r + l.wave;
      PointBatch::WavePacket& p = wave[i];
      p.descriptor_index = w[0];
      p.data_offset = load<uint64_t>(w + 1);
      p.data_size = load<uint32_t>(w + 9);
      p.return_point_location = load<float>(w + 13);
      p.dx = load<float>(w + 17);
      p.dy = load<float>(w + 21);
      p.dz = load<float>(w + 25);
    }
    if (eb) std::memcpy(extra + i * eb, r + l.base_size, eb);
  }
}

void decode_drawn(const uint8_t* records, size_t n, const RecordLayout& l, const glm::dvec3& scale,
                  const glm::dvec3& offset, DrawnPoint* out) {
  const bool extended = l.extended();
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* r = records + i * l.record_length;
    DrawnPoint& p = out[i];
    p.position = decode_position(r, scale, offset);
    p.intensity = load<uint16_t>(r + 12);
    const Returns returns = decode_returns(r, extended);
    p.return_number = returns.return_number;
    p.number_of_returns = returns.number_of_returns;
    p.classification = returns.classification;
    p.rgb = l.rgb >= 0 ? decode_rgb(r + l.rgb) : glm::u16vec3(0);
  }
}

void decode_positions(const uint8_t* records, size_t n, const RecordLayout& l,
                      const glm::dvec3& scale, const glm::dvec3& offset,
                      std::vector<glm::dvec3>& positions) {
  const size_t at = positions.size();
  positions.resize(at + n);
  glm::dvec3* pos = positions.data() + at;
  for (size_t i = 0; i < n; ++i)
    pos[i] = decode_position(records + i * l.record_length, scale, offset);
}

namespace {

int32_t quantize(double v, double scale, double offset, char axis) {
  const double q = std::round((v - offset) / scale);
  if (!(q >= std::numeric_limits<int32_t>::min() && q <= std::numeric_limits<int32_t>::max())) {
    fail("coordinate {} = {} does not fit a 32-bit integer with scale {} and offset {}", axis, v,
         scale, offset);
  }
  return static_cast<int32_t>(q);
}

template <typename T>
T get_or(const std::vector<T>& v, size_t i, T fallback) {
  return i < v.size() ? v[i] : fallback;
}

}  // namespace

void encode_record(const PointBatch& b, size_t i, const RecordLayout& l, const glm::dvec3& scale,
                   const glm::dvec3& offset, uint8_t* r) {
  std::memset(r, 0, l.record_length);
  const glm::dvec3 p = b.positions[i];
  store<int32_t>(r, quantize(p.x, scale.x, offset.x, 'x'));
  store<int32_t>(r + 4, quantize(p.y, scale.y, offset.y, 'y'));
  store<int32_t>(r + 8, quantize(p.z, scale.z, offset.z, 'z'));
  store<uint16_t>(r + 12, get_or<uint16_t>(b.intensity, i, 0));
  const uint8_t rn = get_or<uint8_t>(b.return_number, i, 0);
  const uint8_t nr = get_or<uint8_t>(b.number_of_returns, i, 0);
  const uint8_t cls = get_or<uint8_t>(b.classification, i, 0);
  const uint8_t flags = get_or<uint8_t>(b.flags, i, 0);
  const float angle = get_or<float>(b.scan_angle, i, 0.0f);
  r[17] = get_or<uint8_t>(b.user_data, i, 0);
  if (!l.extended()) {
    r[14] = static_cast<uint8_t>((rn & 7) | ((nr & 7) << 3) | (flags & 0xc0));
    r[15] = static_cast<uint8_t>((cls & 0x1f) | ((flags & 7) << 5));
    r[16] =
        static_cast<uint8_t>(static_cast<int8_t>(std::clamp(std::round(angle), -128.0f, 127.0f)));
    store<uint16_t>(r + 18, get_or<uint16_t>(b.point_source_id, i, 0));
  } else {
    r[14] = static_cast<uint8_t>((rn & 15) | ((nr & 15) << 4));
    r[15] = flags;
    r[16] = cls;
    const double steps = std::clamp(std::round(angle / 0.006), -32768.0, 32767.0);
    store<int16_t>(r + 18, static_cast<int16_t>(steps));
    store<uint16_t>(r + 20, get_or<uint16_t>(b.point_source_id, i, 0));
  }
  if (l.gps >= 0) store<double>(r + l.gps, get_or<double>(b.gps_time, i, 0.0));
  if (l.rgb >= 0) {
    const glm::u16vec3 c = get_or<glm::u16vec3>(b.rgb, i, glm::u16vec3(0));
    store<uint16_t>(r + l.rgb, c.r);
    store<uint16_t>(r + l.rgb + 2, c.g);
    store<uint16_t>(r + l.rgb + 4, c.b);
  }
  if (l.nir >= 0) store<uint16_t>(r + l.nir, get_or<uint16_t>(b.nir, i, 0));
  if (l.wave >= 0 && i < b.wave_packets.size()) {
    const PointBatch::WavePacket& w = b.wave_packets[i];
    uint8_t* o = r + l.wave;
    o[0] = w.descriptor_index;
    store<uint64_t>(o + 1, w.data_offset);
    store<uint32_t>(o + 9, w.data_size);
    store<float>(o + 13, w.return_point_location);
    store<float>(o + 17, w.dx);
    store<float>(o + 21, w.dy);
    store<float>(o + 25, w.dz);
  }
  const size_t eb = l.extra_bytes();
  if (eb && b.extra_bytes_per_point == eb && (i + 1) * eb <= b.extra_bytes.size()) {
    std::memcpy(r + l.base_size, b.extra_bytes.data() + i * eb, eb);
  }
}

}  // namespace detail
}  // namespace stipple::io
