#include "stipple/io/point_batch.hpp"

#include <cstring>

#include "stipple/core/error.hpp"

namespace stipple::io {

void PointBatch::clear() {
  positions.clear();
  intensity.clear();
  return_number.clear();
  number_of_returns.clear();
  classification.clear();
  flags.clear();
  scan_angle.clear();
  user_data.clear();
  point_source_id.clear();
  gps_time.clear();
  rgb.clear();
  nir.clear();
  wave_packets.clear();
  extra_bytes.clear();
}

void PointBatch::reserve(size_t n) {
  positions.reserve(n);
  intensity.reserve(n);
  return_number.reserve(n);
  number_of_returns.reserve(n);
  classification.reserve(n);
  flags.reserve(n);
  scan_angle.reserve(n);
  user_data.reserve(n);
  point_source_id.reserve(n);
  // Optional attributes are reserved only when already in use, so absent ones stay free.
  if (!gps_time.empty()) gps_time.reserve(n);
  if (!rgb.empty()) rgb.reserve(n);
  if (!nir.empty()) nir.reserve(n);
  if (!wave_packets.empty()) wave_packets.reserve(n);
  if (extra_bytes_per_point) extra_bytes.reserve(n * extra_bytes_per_point);
}

namespace {

template <typename T>
void compact_array(std::vector<T>& values, std::span<const uint8_t> keep) {
  if (values.empty()) return;
  size_t out = 0;
  for (size_t i = 0; i < keep.size(); ++i)
    if (keep[i]) values[out++] = values[i];
  values.resize(out);
}

}  // namespace

void PointBatch::compact(std::span<const uint8_t> keep) {
  if (keep.size() != size())
    fail("PointBatch::compact: {} flags for {} points", keep.size(), size());
  compact_array(positions, keep);
  compact_array(intensity, keep);
  compact_array(return_number, keep);
  compact_array(number_of_returns, keep);
  compact_array(classification, keep);
  compact_array(flags, keep);
  compact_array(scan_angle, keep);
  compact_array(user_data, keep);
  compact_array(point_source_id, keep);
  compact_array(gps_time, keep);
  compact_array(rgb, keep);
  compact_array(nir, keep);
  compact_array(wave_packets, keep);
  if (extra_bytes_per_point && !extra_bytes.empty()) {
    const size_t eb = extra_bytes_per_point;
    size_t out = 0;
    for (size_t i = 0; i < keep.size(); ++i)
      if (keep[i]) {
        if (out != i) std::memmove(extra_bytes.data() + out * eb, extra_bytes.data() + i * eb, eb);
        ++out;
      }
    extra_bytes.resize(out * eb);
  }
}

}  // namespace stipple::io
