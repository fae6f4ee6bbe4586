#include "stipple/io/point_batch.hpp"

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

}  // namespace stipple::io
