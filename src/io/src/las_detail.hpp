#pragma once
// Internals shared by the LAS reader, writer, LAZ glue and CRS code. Not part of the public API.
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "stipple/io/las.hpp"

namespace stipple::io::detail {

// VLR payloads larger than this are not loaded (e.g. waveform data packet EVLRs).
constexpr uint64_t kMaxVlrDataBytes = 64ull << 20;

// Byte offsets of the optional fields of a point record; -1 where the format lacks them.
struct RecordLayout {
  uint8_t format = 0;
  uint16_t record_length = 0;
  uint16_t base_size = 0;  // the format's own size; extra bytes follow
  int gps = -1, rgb = -1, nir = -1, wave = -1;
  bool extended() const { return format >= 6; }
  size_t extra_bytes() const { return record_length - base_size; }
};
RecordLayout record_layout(uint8_t format, uint16_t record_length);

// Appends n raw records to batch.
void decode_records(const uint8_t* records, size_t n, const RecordLayout& layout,
                    const glm::dvec3& scale, const glm::dvec3& offset, PointBatch& batch);
// Appends the positions of n raw records (scale and offset applied) to `positions`.
void decode_positions(const uint8_t* records, size_t n, const RecordLayout& layout,
                      const glm::dvec3& scale, const glm::dvec3& offset,
                      std::vector<glm::dvec3>& positions);
// Writes the drawn fields of n raw records to out[0..n).
void decode_drawn(const uint8_t* records, size_t n, const RecordLayout& layout,
                  const glm::dvec3& scale, const glm::dvec3& offset, DrawnPoint* out);
// Encodes batch point i into one raw record (record_length bytes). Integer coordinates are
// returned so the writer can track bounds of what is actually stored.
void encode_record(const PointBatch& batch, size_t i, const RecordLayout& layout,
                   const glm::dvec3& scale, const glm::dvec3& offset, uint8_t* out);

// Little-endian helpers (the project only targets little-endian hosts, but stay explicit).
template <typename T>
T load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}
template <typename T>
void store(uint8_t* p, T v) {
  std::memcpy(p, &v, sizeof(T));
}

// LAZ decoding via LASzip: writes raw LAS records of `layout` into out.
class LazDecoder {
 public:
  virtual ~LazDecoder() = default;
  virtual void read(uint8_t* out, size_t n) = 0;  // throws Error "<name>: ..." on failure
  // Positions before point `index` (LASzip jumps to its chunk through the chunk table).
  virtual void seek(uint64_t index) = 0;
};
// Exactly one of path / memory is used (path when non-null). drawn_fields_only: see LasReader.
std::unique_ptr<LazDecoder> open_laz_decoder(const std::string& name,
                                             const std::filesystem::path* path,
                                             std::span<const uint8_t> memory,
                                             const RecordLayout& layout,
                                             bool drawn_fields_only = false);

class LazEncoder {
 public:
  virtual ~LazEncoder() = default;
  virtual void write(const uint8_t* record) = 0;
  virtual void close() = 0;
};
// Writes a LAZ file whose header is `header_bytes` (an encoded public header block, counts may
// be zero) followed by `vlrs`; the caller patches counts and bounds after close().
std::unique_ptr<LazEncoder> open_laz_encoder(const std::filesystem::path& path,
                                             const LasHeader& header, const std::vector<Vlr>& vlrs,
                                             const RecordLayout& layout);

// CRS from the (E)VLRs: WKT, GeoTIFF keys, EPSG codes, then names and units via PROJ (PROJ
// failures leave them empty, never throw).
// `global_encoding` is the header's: its WKT bit says which source decides (see Crs).
Crs parse_crs(const std::vector<Vlr>& vlrs, const std::vector<Vlr>& evlrs, uint16_t global_encoding,
              bool resolve_names);

}  // namespace stipple::io::detail
