// LASzip glue: converts between laszip_point and raw LAS point records so LAS and LAZ share one
// record decoder/encoder. Kept in its own file because laszip_api.h (C++ mode) says
// `using namespace std;` at global scope.
#include <laszip/laszip_api.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <istream>
#include <streambuf>

#include "las_detail.hpp"
#include "stipple/core/error.hpp"

namespace stipple::io::detail {
namespace {

std::string laszip_message(laszip_POINTER zip) {
  laszip_CHAR* msg = nullptr;
  if (zip && laszip_get_error(zip, &msg) == 0 && msg && *msg) return msg;
  return "unknown LASzip error";
}

// A read-only, seekable streambuf over memory, for laszip_open_reader_stream.
class MemoryBuf : public std::streambuf {
 public:
  explicit MemoryBuf(std::span<const uint8_t> bytes) {
    char* p = const_cast<char*>(reinterpret_cast<const char*>(bytes.data()));
    setg(p, p, p + bytes.size());
  }

 protected:
  pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override {
    off_type base = dir == std::ios_base::beg   ? 0
                    : dir == std::ios_base::cur ? gptr() - eback()
                                                : egptr() - eback();
    return seekpos(pos_type(base + off), std::ios_base::in);
  }
  pos_type seekpos(pos_type pos, std::ios_base::openmode) override {
    if (pos < 0 || pos > egptr() - eback()) return pos_type(off_type(-1));
    setg(eback(), eback() + static_cast<off_type>(pos), egptr());
    return pos;
  }
};

// Owns a LASzip object, so it is released even when a constructor below throws.
struct ZipHandle {
  laszip_POINTER zip = nullptr;
  bool reader = false, writer = false;
  ZipHandle() = default;
  ZipHandle(const ZipHandle&) = delete;
  ZipHandle& operator=(const ZipHandle&) = delete;
  ~ZipHandle() {
    if (!zip) return;
    if (reader) laszip_close_reader(zip);
    if (writer) laszip_close_writer(zip);
    laszip_destroy(zip);
  }
};

class LaszipDecoder : public LazDecoder {
 public:
  LaszipDecoder(const std::string& name, const std::filesystem::path* path,
                std::span<const uint8_t> memory, const RecordLayout& layout, bool drawn_fields_only)
      : name_(name), layout_(layout), buf_(memory), stream_(&buf_) {
    if (laszip_create(&handle_.zip) != 0 || !handle_.zip) {
      fail("{}: cannot create a LASzip reader", name_);
    }
    zip_ = handle_.zip;
    // Layers of formats 6-10 left compressed: LASzip skips their bytes in each chunk (and
    // leaves the chunk's first point's values there, so read() writes zeros instead). Other
    // formats have no layers and decode whole.
    drawn_only_ = drawn_fields_only && layout.extended();
    if (drawn_only_ &&
        laszip_decompress_selective(
            zip_, laszip_DECOMPRESS_SELECTIVE_CHANNEL_RETURNS_XY | laszip_DECOMPRESS_SELECTIVE_Z |
                      laszip_DECOMPRESS_SELECTIVE_CLASSIFICATION |
                      laszip_DECOMPRESS_SELECTIVE_INTENSITY | laszip_DECOMPRESS_SELECTIVE_RGB) != 0)
      fail("{}: LASzip: {}", name_, laszip_message(zip_));
    laszip_BOOL compressed = 0;
    const laszip_I32 rc = path ? laszip_open_reader(zip_, path->c_str(), &compressed)
                               : laszip_open_reader_stream(zip_, stream_, &compressed);
    if (rc != 0) fail("{}: LASzip cannot open the file: {}", name_, laszip_message(zip_));
    handle_.reader = true;
    laszip_header* h = nullptr;
    if (laszip_get_header_pointer(zip_, &h) != 0 || !h) {
      fail("{}: LASzip: {}", name_, laszip_message(zip_));
    }
    // LASzip must agree with our own header parse, or the repacked records would be wrong.
    const uint8_t format = h->point_data_format & 0x3f;
    if (format != layout.format || h->point_data_record_length != layout.record_length) {
      fail("{}: LASzip sees point format {} / record length {}, header says {} / {}", name_, format,
           h->point_data_record_length, layout.format, layout.record_length);
    }
    if (laszip_get_point_pointer(zip_, &point_) != 0 || !point_) {
      fail("{}: LASzip: {}", name_, laszip_message(zip_));
    }
  }

  void seek(uint64_t index) override {
    if (laszip_seek_point(zip_, static_cast<laszip_I64>(index)) != 0)
      fail("{}: cannot seek to point {}: {}", name_, index, laszip_message(zip_));
    count_ = index;
  }

  void read(uint8_t* out, size_t n) override {
    const size_t eb = layout_.extra_bytes();
    for (size_t i = 0; i < n; ++i, ++count_) {
      if (laszip_read_point(zip_) != 0) {
        fail("{}: corrupt LAZ data at point {}: {}", name_, count_, laszip_message(zip_));
      }
      uint8_t* r = out + i * layout_.record_length;
      std::memset(r, 0, layout_.record_length);
      const laszip_point& p = *point_;
      if (drawn_only_) {  // the decoded layers' fields; the rest stay zero
        store<int32_t>(r, p.X);
        store<int32_t>(r + 4, p.Y);
        store<int32_t>(r + 8, p.Z);
        store<uint16_t>(r + 12, p.intensity);
        r[14] =
            static_cast<uint8_t>(p.extended_return_number | (p.extended_number_of_returns << 4));
        r[16] = p.extended_classification;
        if (layout_.rgb >= 0) std::memcpy(r + layout_.rgb, p.rgb, 6);
        continue;
      }
      if (!layout_.extended()) {
        // laszip_point begins with the 20-byte legacy record, bit fields included.
        std::memcpy(r, &p.X, 20);
      } else {
        store<int32_t>(r, p.X);
        store<int32_t>(r + 4, p.Y);
        store<int32_t>(r + 8, p.Z);
        store<uint16_t>(r + 12, p.intensity);
        r[14] =
            static_cast<uint8_t>(p.extended_return_number | (p.extended_number_of_returns << 4));
        r[15] = static_cast<uint8_t>(p.extended_classification_flags |
                                     (p.extended_scanner_channel << 4) |
                                     (p.scan_direction_flag << 6) | (p.edge_of_flight_line << 7));
        r[16] = p.extended_classification;
        r[17] = p.user_data;
        store<int16_t>(r + 18, p.extended_scan_angle);
        store<uint16_t>(r + 20, p.point_source_ID);
      }
      if (layout_.gps >= 0) store<double>(r + layout_.gps, p.gps_time);
      if (layout_.rgb >= 0) std::memcpy(r + layout_.rgb, p.rgb, 6);
      if (layout_.nir >= 0) store<uint16_t>(r + layout_.nir, p.rgb[3]);
      if (layout_.wave >= 0) std::memcpy(r + layout_.wave, p.wave_packet, 29);
      if (eb) {
        if (static_cast<size_t>(p.num_extra_bytes) != eb || !p.extra_bytes) {
          fail("{}: LASzip reports {} extra bytes per point, header says {}", name_,
               p.num_extra_bytes, eb);
        }
        std::memcpy(r + layout_.base_size, p.extra_bytes, eb);
      }
    }
  }

 private:
  std::string name_;
  RecordLayout layout_;
  bool drawn_only_ = false;
  MemoryBuf buf_;
  std::istream stream_;
  ZipHandle handle_;
  laszip_POINTER zip_ = nullptr;
  laszip_point* point_ = nullptr;
  uint64_t count_ = 0;
};

void copy_fixed(char* dst, const std::string& s, size_t n) {
  std::memset(dst, 0, n);
  std::memcpy(dst, s.data(), std::min(s.size(), n));
}

class LaszipEncoder : public LazEncoder {
 public:
  LaszipEncoder(const std::filesystem::path& path, const LasHeader& hdr,
                const std::vector<Vlr>& vlrs, const RecordLayout& layout)
      : name_(path.string()), layout_(layout) {
    if (laszip_create(&handle_.zip) != 0 || !handle_.zip) {
      fail("{}: cannot create a LASzip writer", name_);
    }
    zip_ = handle_.zip;
    laszip_header* h = nullptr;
    check(laszip_get_header_pointer(zip_, &h));
    h->file_source_ID = hdr.file_source_id;
    h->global_encoding = hdr.global_encoding;
    // The GUID's 16 bytes as stored in the header (the struct fields are laid out the same way).
    std::memcpy(&h->project_ID_GUID_data_1, hdr.guid.data(), 4);
    std::memcpy(&h->project_ID_GUID_data_2, hdr.guid.data() + 4, 2);
    std::memcpy(&h->project_ID_GUID_data_3, hdr.guid.data() + 6, 2);
    std::memcpy(h->project_ID_GUID_data_4, hdr.guid.data() + 8, 8);
    h->version_major = 1;
    h->version_minor = hdr.version_minor;
    copy_fixed(h->system_identifier, hdr.system_identifier, 32);
    copy_fixed(h->generating_software, hdr.generating_software, 32);
    h->file_creation_day = hdr.creation_day;
    h->file_creation_year = hdr.creation_year;
    h->header_size = hdr.header_size;
    h->offset_to_point_data = hdr.header_size;
    h->number_of_variable_length_records = 0;
    h->point_data_format = layout.format;
    h->point_data_record_length = layout.record_length;
    h->x_scale_factor = hdr.scale.x;
    h->y_scale_factor = hdr.scale.y;
    h->z_scale_factor = hdr.scale.z;
    h->x_offset = hdr.offset.x;
    h->y_offset = hdr.offset.y;
    h->z_offset = hdr.offset.z;
    check(laszip_preserve_generating_software(zip_, 1));
    // LAS 1.4 point formats are compressed natively (the layered LAZ 1.4 coder).
    check(laszip_request_native_extension(zip_, 1));
    for (const Vlr& v : vlrs) {
      if (v.data.size() > 65535) fail("{}: VLR {} too large for LAZ", name_, v.user_id);
      check(laszip_add_vlr(zip_, v.user_id.c_str(), v.record_id,
                           static_cast<laszip_U16>(v.data.size()), v.description.c_str(),
                           v.data.data()));
    }
    check(laszip_open_writer(zip_, path.c_str(), 1));
    handle_.writer = true;
    check(laszip_get_point_pointer(zip_, &point_));
  }

  void write(const uint8_t* r) override {
    laszip_point& p = *point_;
    if (!layout_.extended()) {
      std::memcpy(&p.X, r, 20);
    } else {
      p.X = load<int32_t>(r);
      p.Y = load<int32_t>(r + 4);
      p.Z = load<int32_t>(r + 8);
      p.intensity = load<uint16_t>(r + 12);
      const uint8_t rn = r[14] & 15, nr = r[14] >> 4, flags = r[15], cls = r[16];
      p.extended_point_type = 1;
      p.extended_return_number = rn;
      p.extended_number_of_returns = nr;
      p.extended_classification_flags = flags & 15;
      p.extended_scanner_channel = (flags >> 4) & 3;
      p.scan_direction_flag = (flags >> 6) & 1;
      p.edge_of_flight_line = flags >> 7;
      p.extended_classification = cls;
      p.user_data = r[17];
      p.extended_scan_angle = load<int16_t>(r + 18);
      p.point_source_ID = load<uint16_t>(r + 20);
      // LASzip insists the legacy fields agree with the extended ones.
      p.return_number = std::min<uint8_t>(rn, 7);
      p.number_of_returns = std::min<uint8_t>(nr, 7);
      p.classification = cls < 32 ? cls : 0;
      p.synthetic_flag = flags & 1;
      p.keypoint_flag = (flags >> 1) & 1;
      p.withheld_flag = (flags >> 2) & 1;
      p.scan_angle_rank = static_cast<laszip_I8>(
          std::clamp(std::round(0.006 * p.extended_scan_angle), -90.0, 90.0));
    }
    if (layout_.gps >= 0) p.gps_time = load<double>(r + layout_.gps);
    if (layout_.rgb >= 0) std::memcpy(p.rgb, r + layout_.rgb, 6);
    if (layout_.nir >= 0) p.rgb[3] = load<uint16_t>(r + layout_.nir);
    if (layout_.wave >= 0) std::memcpy(p.wave_packet, r + layout_.wave, 29);
    const size_t eb = layout_.extra_bytes();
    if (eb) {
      if (static_cast<size_t>(p.num_extra_bytes) != eb || !p.extra_bytes) {
        fail("{}: LASzip expects {} extra bytes per point, not {}", name_, p.num_extra_bytes, eb);
      }
      std::memcpy(p.extra_bytes, r + layout_.base_size, eb);
    }
    check(laszip_write_point(zip_));
  }

  void close() override {
    if (!handle_.writer) return;
    handle_.writer = false;
    check(laszip_close_writer(zip_));
  }

 private:
  void check(laszip_I32 rc) {
    if (rc != 0) fail("{}: LASzip: {}", name_, laszip_message(zip_));
  }

  std::string name_;
  RecordLayout layout_;
  ZipHandle handle_;
  laszip_POINTER zip_ = nullptr;
  laszip_point* point_ = nullptr;
};

}  // namespace

std::unique_ptr<LazDecoder> open_laz_decoder(const std::string& name,
                                             const std::filesystem::path* path,
                                             std::span<const uint8_t> memory,
                                             const RecordLayout& layout, bool drawn_fields_only) {
  return std::make_unique<LaszipDecoder>(name, path, memory, layout, drawn_fields_only);
}

std::unique_ptr<LazEncoder> open_laz_encoder(const std::filesystem::path& path,
                                             const LasHeader& header, const std::vector<Vlr>& vlrs,
                                             const RecordLayout& layout) {
  return std::make_unique<LaszipEncoder>(path, header, vlrs, layout);
}

}  // namespace stipple::io::detail
