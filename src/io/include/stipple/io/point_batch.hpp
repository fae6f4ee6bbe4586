#pragma once
// A structure-of-arrays batch of decoded points. Every array holds either size() entries or,
// for attributes the source does not have, none.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/gtc/type_precision.hpp>
#include <glm/vec3.hpp>

namespace stipple::io {

struct PointBatch {
  std::vector<glm::dvec3> positions;  // scale and offset applied, in the source CRS units
  std::vector<uint16_t> intensity;
  std::vector<uint8_t> return_number;      // 1-based; up to 15 for formats 6-10
  std::vector<uint8_t> number_of_returns;  // up to 15 for formats 6-10
  std::vector<uint8_t> classification;     // full 8-bit class for formats 6-10, 5-bit for 0-5
  // Bits 0-3: synthetic, key-point, withheld, overlap (overlap also from class 12 in 0-5);
  // bits 4-5: scanner channel; bit 6: scan direction; bit 7: edge of flight line.
  std::vector<uint8_t> flags;
  std::vector<float> scan_angle;  // degrees (rank in 0-5, 0.006 degree steps in 6-10)
  std::vector<uint8_t> user_data;
  std::vector<uint16_t> point_source_id;
  std::vector<double> gps_time;   // formats 1, 3-10
  std::vector<glm::u16vec3> rgb;  // formats 2, 3, 5, 7, 8, 10; as stored (see rgb_bits)
  std::vector<uint16_t> nir;      // formats 8, 10
  struct WavePacket {
    uint8_t descriptor_index;
    uint64_t data_offset;
    uint32_t data_size;
    float return_point_location;
    float dx, dy, dz;
  };
  std::vector<WavePacket> wave_packets;  // formats 4, 5, 9, 10
  size_t extra_bytes_per_point = 0;
  std::vector<uint8_t> extra_bytes;  // size() * extra_bytes_per_point, raw as in the file

  size_t size() const { return positions.size(); }
  void clear();
  void reserve(size_t n);
  // Keeps point i where keep[i] is non-zero (keep.size() == size()), in order, in place.
  void compact(std::span<const uint8_t> keep);
};

}  // namespace stipple::io
