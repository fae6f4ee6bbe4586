#pragma once
// Reading LAS 1.0-1.4 / LAZ / COPC files (point formats 0-10) and writing LAS/LAZ.
// Headers and VLRs are parsed from the file bytes for every variant, so LAS and LAZ give the
// same header; LAZ point records are decompressed by LASzip and then go through the same record
// decoder as LAS. Points stream in chunks: a reader never holds the whole file in memory.
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "stipple/io/point_batch.hpp"

namespace stipple::io {

// A variable length record (VLR) or, with extended set, an extended VLR (EVLR).
struct Vlr {
  std::string user_id;
  uint16_t record_id = 0;
  std::string description;
  std::vector<uint8_t> data;  // empty when data_size is over kMaxVlrDataBytes (not loaded)
  bool extended = false;
  uint64_t data_offset = 0;  // where the payload starts in the file
  uint64_t data_size = 0;    // payload size as declared
};

// One entry of the Extra Bytes VLR (LASF_Spec, record 4), LAS 1.4 R15 table 24.
struct ExtraBytesDescriptor {
  uint8_t data_type = 0;  // 0: undocumented (options holds the byte count); 1-10 scalars
  uint8_t options = 0;    // bit 0 no_data, 1 min, 2 max, 3 scale, 4 offset are meaningful
  std::string name;
  std::string description;
  // "anytype" fields kept raw (8 bytes per component, little endian) so they round trip exactly.
  std::array<uint8_t, 24> no_data{}, min{}, max{};
  double scale[3] = {1, 1, 1};
  double offset[3] = {0, 0, 0};
  size_t size = 0;  // bytes per point this attribute takes
};

// Byte size of one attribute of the given data type (for type 0: options); 0 if unknown.
size_t extra_bytes_type_size(uint8_t data_type, uint8_t options);

// The CRS of a LAS file. A file may carry both an OGC WKT and GeoTIFF keys; one of them
// decides every field below (`source`): the WKT when the header's WKT bit (global encoding bit
// 4) is set, as LAS 1.4 says, or when the keys name no CRS code; the GeoTIFF keys otherwise.
struct Crs {
  enum class Source : uint8_t { None, Wkt, GeoTiff };
  std::string wkt;         // OGC WKT from LASF_Projection 2112 (VLR or EVLR), trimmed
  bool blank_wkt = false;  // a WKT VLR is there but holds no text
  // GeoTIFF: GeoKeyDirectoryTag entries (34735, without its header row), doubles (34736) and
  // ASCII params (34737).
  std::vector<std::array<uint16_t, 4>> geokeys;
  std::vector<double> geo_doubles;
  std::string geo_ascii;
  Source source = Source::None;
  int epsg = 0;  // horizontal: ProjectedCSTypeGeoKey (3072) or GeographicTypeGeoKey (2048), or
                 // the WKT's id (from PROJ, else its top-level AUTHORITY)
  int vertical_epsg = 0;      // VerticalCSTypeGeoKey (4096) or the WKT's vertical part
  bool geographic = false;    // coordinates are degrees lon/lat
  std::string name;           // e.g. "NAD83 / Oregon GIC Lambert (ft)" (PROJ); may be empty
  std::string linear_unit;    // e.g. "metre", "foot", "US survey foot"; empty if unknown
  bool wkt_readable = false;  // PROJ reads the WKT as a whole (else its AUTHORITY was used)
  // Both sources present and naming different CRSs: what each says and which one is used.
  std::string conflict;

  bool empty() const { return wkt.empty() && geokeys.empty() && epsg == 0; }
  std::string describe() const;  // one line for logs and `stipple info` ("none" when empty)
};

// Longitude and latitude (degrees, WGS 84) of coordinates in a CRS, through PROJ; invalid
// when the CRS is unknown or PROJ cannot make the transformation (never throws).
class LonLatTransform {
 public:
  explicit LonLatTransform(const Crs& crs);
  ~LonLatTransform();
  LonLatTransform(const LonLatTransform&) = delete;
  LonLatTransform& operator=(const LonLatTransform&) = delete;
  bool valid() const { return transform_ != nullptr; }
  // lon, lat, height; nullopt where PROJ fails for that point.
  std::optional<glm::dvec3> operator()(const glm::dvec3& p) const;

 private:
  void* context_ = nullptr;
  void* transform_ = nullptr;
};

struct LasHeader {
  std::string path;  // file name used in messages
  uint8_t version_major = 1, version_minor = 2;
  uint8_t point_format = 0;  // 0-10 (LAZ compression bits masked off)
  uint16_t point_record_length = 0;
  bool compressed = false;  // LAZ
  bool copc = false;        // LAZ 1.4 with a "copc" info VLR
  // Points per LASzip chunk, from its VLR: readers that seek to whole chunks decode nothing
  // twice. 0 when unknown or variable (COPC).
  uint32_t laz_chunk_points = 0;
  uint64_t point_count = 0;
  std::array<uint64_t, 15> points_by_return{};
  glm::dvec3 scale{0.01}, offset{0}, min{0}, max{0};
  uint32_t offset_to_points = 0;
  uint16_t header_size = 0;
  uint16_t global_encoding = 0;
  uint16_t file_source_id = 0;
  std::array<uint8_t, 16> guid{};
  std::string system_identifier, generating_software;
  uint16_t creation_day = 0, creation_year = 0;
  uint64_t start_of_waveform_data = 0;  // LAS 1.3+
  std::vector<Vlr> vlrs, evlrs;
  Crs crs;
  std::vector<ExtraBytesDescriptor> extra_bytes;  // from the Extra Bytes VLR
  uint16_t extra_bytes_per_point = 0;             // record length minus the format's size
  bool has_rgb = false, has_nir = false, has_gps_time = false, has_waveform = false;
  // 8 when the 16-bit RGB fields hold 8-bit values (as autzen_trim does). Detected at open time:
  // if every R, G and B of the first chunk (up to 65536 points) is <= 255, the file is taken to
  // store 8-bit colour. read_las_header() does not look at points and leaves it at 16.
  int rgb_bits = 16;
  // The same probe: how many points it looked at, and their one colour when every one of them
  // had the same RGB (some writers fill the fields with 0: such RGB says nothing).
  uint64_t rgb_probed = 0;
  std::optional<std::array<uint16_t, 3>> rgb_uniform;
};

// Bytes of a point record of the given format (0-10) without extra bytes; 0 if unknown.
uint16_t las_format_record_size(uint8_t point_format);

// One point's fields that drawing keeps (LasReader::read_drawn): the position with the header's
// scale and offset applied (the same doubles read() gives), intensity, classification and returns
// as PointBatch holds them, and RGB as stored (zeros where the format has none).
struct DrawnPoint {
  glm::dvec3 position;
  glm::u16vec3 rgb;
  uint16_t intensity;
  uint8_t classification, return_number, number_of_returns;
};

class LasReader {
 public:
  // Throws stipple::Error "<path>: <problem>" for anything that is not a valid LAS/LAZ file.
  explicit LasReader(const std::filesystem::path& path);
  // With drawn_fields_only, LAZ of formats 6-10 (layered compression) decodes only positions,
  // returns, classification, intensity and RGB, what drawing needs; the other fields (GPS time,
  // scan angle, user data, point source, flags, NIR, wave packets, extra bytes) read as zeros.
  // Their layers are most of the decoding (the pointlet cache's builder reads this way).
  LasReader(const std::filesystem::path& path, bool drawn_fields_only);
  // Reads from memory (e.g. a fuzzer's input); `bytes` must outlive the reader. `name` is used
  // in error messages. LAZ is decoded too unless decode_laz is false, in which case compressed
  // input is rejected after the header and VLRs have been parsed.
  LasReader(std::span<const uint8_t> bytes, std::string name, bool decode_laz = true);
  ~LasReader();
  LasReader(LasReader&&) noexcept;
  LasReader& operator=(LasReader&&) noexcept;
  LasReader(const LasReader&) = delete;
  LasReader& operator=(const LasReader&) = delete;

  const LasHeader& header() const;
  // Appends up to max_points points to batch; returns how many, 0 at the end.
  size_t read(PointBatch& batch, size_t max_points);
  // As read(), but decodes the positions only (appended to `positions`, scale and offset
  // applied): a pass that needs nothing else (the tiler's counting pass) skips the other fields.
  size_t read_positions(std::vector<glm::dvec3>& positions, size_t max_points);
  // As read(), but only the drawn fields, into `out` (up to out.size() points): a builder that
  // converts every point at once (the pointlet cache) skips the batch's other arrays and keeps
  // its working set in cache.
  size_t read_drawn(std::span<DrawnPoint> out);
  // The next read() starts at point `index` (<= the point count). LAZ decoding restarts at the
  // chunk holding it, so readers seeking to chunk-aligned ranges can decode a file in parallel.
  void seek(uint64_t index);
  uint64_t points_read() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// An Extra Bytes descriptor's type (LAS 1.4 R15 table 25), e.g. "uint16", "float64[3]".
std::string extra_bytes_type_name(const ExtraBytesDescriptor& e);

// The header as a JSON object (file, version, point_format, point_count, scale, offset, min, max,
// crs, vlrs, extra_bytes, ...): what `stipple info --json` prints for a LAS/LAZ/COPC file.
std::string las_header_json(const LasHeader& header);

// Header, VLRs, EVLRs and CRS only; no points are decoded.
LasHeader read_las_header(const std::filesystem::path& path);

// A geographic CRS (degrees) whose bounds go past latitude +-90 or longitude +-360: the
// coordinates are not longitude/latitude (a projected file labelled with the wrong CRS). The
// problem as a sentence naming the file, or empty: what converts degrees to metres (render,
// tile, pointlets) refuses such a file, and info shows it.
std::string geographic_bounds_problem(const LasHeader& header);

struct LasWriteOptions {
  uint8_t version_minor = 4;  // 2, 3 or 4; formats 6-10 need 4
  uint8_t point_format = 7;
  glm::dvec3 scale{0.001}, offset{0};
  bool compress = false;                          // LAZ via LASzip
  std::string wkt;                                // written as a LASF_Projection 2112 VLR when set
  std::vector<ExtraBytesDescriptor> extra_bytes;  // per-point layout of PointBatch::extra_bytes
  std::string system_identifier = "stipple";
  std::string generating_software = "stipple";
  // Carried over from a source file (stipple clip): VLRs written after the writer's own (Extra
  // Bytes from `extra_bytes`, WKT from `wkt`), EVLRs after the points (LAS 1.4 only). A VLR whose
  // payload exceeds 65535 bytes becomes an EVLR. Payloads must be loaded (Vlr::data).
  std::vector<Vlr> vlrs, evlrs;
  // Global encoding bits kept from the source: 0 (adjusted standard GPS time), 2 (external
  // waveform data), 3 (synthetic return numbers), 4 (WKT CRS). Bit 1 (internal waveform data) is
  // never written: waveform packets are not copied.
  uint16_t global_encoding = 0;
  uint16_t file_source_id = 0;
  std::array<uint8_t, 16> guid{};
};

// Writes points; close() (or the destructor) finalises header counts, bounds and
// points_by_return. Attributes a batch lacks are written as zeros. The file is written under a
// temporary name and appears at `path` only once finished (AtomicFile): a writer destroyed while
// an exception unwinds, or a killed process, leaves no partial LAS behind.
class LasWriter {
 public:
  LasWriter(const std::filesystem::path& path, LasWriteOptions options);
  ~LasWriter();
  LasWriter(const LasWriter&) = delete;
  LasWriter& operator=(const LasWriter&) = delete;

  void write(const PointBatch& batch);
  void close();
  uint64_t points_written() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stipple::io
