// LAS/LAZ/COPC reading: the header, VLRs and EVLRs are parsed here from the raw bytes for every
// variant; points come from the file directly (LAS) or from LASzip (LAZ) as raw records.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "las_detail.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/io/las.hpp"

namespace stipple::io {

using detail::load;

namespace {

// Largest raw read per step of read(): bounds memory whatever max_points is, and small enough
// that the records the kernel just copied, and the arrays decoded from them (whose growth
// zero-fills them first), are still in the core's L2 cache when touched again (4 MiB reads
// went out to the shared cache or memory).
constexpr size_t kChunkBytes = 256u << 10;
// Points inspected at open time to detect 8-bit RGB.
constexpr size_t kRgbProbePoints = 65536;
// No real file comes near this; larger counts are corrupt headers.
constexpr uint64_t kMaxPointCount = 1ull << 40;

// Random-access bytes: a file or a memory buffer. read() throws on a short read.
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  virtual uint64_t size() const = 0;
  // Returns how many bytes could be read (fewer only at the end).
  virtual size_t read_some(uint64_t offset, uint8_t* dst, size_t n) = 0;
};

// Positioned reads (pread) straight into the caller's buffer: no stdio buffer and no seek
// call between the many small reads of read().
class FileSource : public ByteSource {
 public:
  FileSource(const std::filesystem::path& path, const std::string& name) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) fail("{}: is a directory, not a LAS file", name);
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) fail("{}: cannot open: {}", name, std::strerror(errno));
    struct stat st {};
    if (::fstat(fd_, &st) != 0) {
      const int e = errno;
      ::close(fd_);
      fail("{}: cannot determine the file size: {}", name, std::strerror(e));
    }
    if (st.st_size < 0) {
      ::close(fd_);
      fail("{}: cannot determine the file size", name);
    }
    size_ = static_cast<uint64_t>(st.st_size);
  }
  ~FileSource() override {
    if (fd_ >= 0) ::close(fd_);
  }
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;
  uint64_t size() const override { return size_; }
  size_t read_some(uint64_t offset, uint8_t* dst, size_t n) override {
    size_t got = 0;
    while (got < n && offset + got < size_) {
      const ssize_t r = ::pread(fd_, dst + got, n - got, static_cast<off_t>(offset + got));
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) break;  // an error or the end: the caller reports the short read
      got += static_cast<size_t>(r);
    }
    return got;
  }

 private:
  int fd_ = -1;
  uint64_t size_ = 0;
};

class MemorySource : public ByteSource {
 public:
  explicit MemorySource(std::span<const uint8_t> bytes) : bytes_(bytes) {}
  uint64_t size() const override { return bytes_.size(); }
  size_t read_some(uint64_t offset, uint8_t* dst, size_t n) override {
    if (offset >= bytes_.size()) return 0;
    const size_t k = static_cast<size_t>(std::min<uint64_t>(n, bytes_.size() - offset));
    std::memcpy(dst, bytes_.data() + offset, k);
    return k;
  }

 private:
  std::span<const uint8_t> bytes_;
};

// A NUL-padded char[n] field. Some writers pad with spaces instead: trailing spaces are not
// part of the value either (a user ID "LASF_Projection " is LASF_Projection).
std::string fixed_string(const uint8_t* p, size_t n) {
  size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  while (len > 0 && p[len - 1] == ' ') --len;
  return std::string(reinterpret_cast<const char*>(p), len);
}

// What the CRS fields cannot say: the WKT and GeoTIFF keys disagree. (Geographic bounds that
// are not degrees are refused by what converts them, and shown by info.)
void warn_about_crs(const LasHeader& h) {
  if (!h.crs.conflict.empty()) STIPPLE_WARN_ONCE("{}: {}", h.path, h.crs.conflict);
}

struct Parser {
  ByteSource& src;
  const std::string& name;

  std::vector<uint8_t> read(uint64_t offset, uint64_t n, const char* what) {
    if (offset > src.size() || n > src.size() - offset) {
      fail("{}: {} ({} bytes at offset {}) runs past the end of the file ({} bytes)", name, what, n,
           offset, src.size());
    }
    std::vector<uint8_t> out(static_cast<size_t>(n));
    if (n && src.read_some(offset, out.data(), out.size()) != out.size()) {
      fail("{}: cannot read {} at offset {}", name, what, offset);
    }
    return out;
  }

  std::vector<ExtraBytesDescriptor> parse_extra_bytes(const Vlr& vlr) {
    std::vector<ExtraBytesDescriptor> out;
    if (vlr.data.size() % 192 != 0) {
      STIPPLE_WARN_ONCE("{}: Extra Bytes VLR size {} is not a multiple of 192", name,
                        vlr.data.size());
    }
    for (size_t at = 0; at + 192 <= vlr.data.size(); at += 192) {
      const uint8_t* d = vlr.data.data() + at;
      ExtraBytesDescriptor e;
      e.data_type = d[2];
      e.options = d[3];
      e.name = fixed_string(d + 4, 32);
      std::memcpy(e.no_data.data(), d + 40, 24);
      std::memcpy(e.min.data(), d + 64, 24);
      std::memcpy(e.max.data(), d + 88, 24);
      for (int k = 0; k < 3; ++k) {
        e.scale[k] = load<double>(d + 112 + 8 * k);
        e.offset[k] = load<double>(d + 136 + 8 * k);
      }
      e.description = fixed_string(d + 160, 32);
      e.size = extra_bytes_type_size(e.data_type, e.options);
      out.push_back(std::move(e));
    }
    return out;
  }

  LasHeader parse() {
    LasHeader h;
    h.path = name;
    const uint64_t file_size = src.size();
    if (file_size < 4) fail("{}: not a LAS file (only {} bytes)", name, file_size);
    uint8_t sig[4];
    src.read_some(0, sig, 4);
    if (std::memcmp(sig, "LASF", 4) != 0) fail("{}: not a LAS file (no LASF signature)", name);
    if (file_size < 227)
      fail("{}: truncated header ({} bytes, need at least 227)", name, file_size);
    const std::vector<uint8_t> hb = read(0, std::min<uint64_t>(file_size, 375), "header");
    const uint8_t* p = hb.data();
    h.file_source_id = load<uint16_t>(p + 4);
    h.global_encoding = load<uint16_t>(p + 6);
    std::memcpy(h.guid.data(), p + 8, 16);
    h.version_major = p[24];
    h.version_minor = p[25];
    if (h.version_major != 1 || h.version_minor > 4) {
      fail("{}: unsupported LAS version {}.{}", name, h.version_major, h.version_minor);
    }
    h.system_identifier = fixed_string(p + 26, 32);
    h.generating_software = fixed_string(p + 58, 32);
    h.creation_day = load<uint16_t>(p + 90);
    h.creation_year = load<uint16_t>(p + 92);
    h.header_size = load<uint16_t>(p + 94);
    h.offset_to_points = load<uint32_t>(p + 96);
    const uint32_t vlr_count = load<uint32_t>(p + 100);
    const uint8_t format_byte = p[104];
    h.point_record_length = load<uint16_t>(p + 105);
    const uint32_t legacy_count = load<uint32_t>(p + 107);
    for (int i = 0; i < 5; ++i) h.points_by_return[i] = load<uint32_t>(p + 111 + 4 * i);
    for (int i = 0; i < 3; ++i) {
      h.scale[i] = load<double>(p + 131 + 8 * i);
      h.offset[i] = load<double>(p + 155 + 8 * i);
      h.max[i] = load<double>(p + 179 + 16 * i);
      h.min[i] = load<double>(p + 187 + 16 * i);
    }

    const uint16_t needed = h.version_minor >= 4 ? 375 : h.version_minor == 3 ? 235 : 227;
    if (h.header_size < needed) {
      fail("{}: header size {} is smaller than LAS 1.{} needs ({})", name, h.header_size,
           h.version_minor, needed);
    }
    if (h.header_size > file_size) {
      fail("{}: truncated header ({} bytes, header size says {})", name, file_size, h.header_size);
    }
    if (h.offset_to_points < h.header_size) {
      fail("{}: offset to point data {} lies inside the header ({} bytes)", name,
           h.offset_to_points, h.header_size);
    }
    if (h.offset_to_points > file_size) {
      fail("{}: offset to point data {} is beyond the end of the file ({} bytes)", name,
           h.offset_to_points, file_size);
    }

    uint64_t evlr_start = 0;
    uint32_t evlr_count = 0;
    h.point_count = legacy_count;
    if (h.version_minor >= 3) h.start_of_waveform_data = load<uint64_t>(p + 227);
    if (h.version_minor >= 4) {
      evlr_start = load<uint64_t>(p + 235);
      evlr_count = load<uint32_t>(p + 243);
      const uint64_t count64 = load<uint64_t>(p + 247);
      // The 64-bit fields are authoritative in 1.4; the legacy ones may be zero (formats 6-10).
      if (count64 != 0 || legacy_count == 0) {
        if (legacy_count != 0 && count64 != legacy_count) {
          STIPPLE_WARN_ONCE("{}: legacy point count {} differs from the 64-bit count {}", name,
                            legacy_count, count64);
        }
        h.point_count = count64;
        for (int i = 0; i < 15; ++i) h.points_by_return[i] = load<uint64_t>(p + 255 + 8 * i);
      }
    }
    if (h.point_count > kMaxPointCount) fail("{}: absurd point count {}", name, h.point_count);

    // Compressed files set bit 7 (and bit 6 in some LASzip versions) of the format byte.
    h.compressed = (format_byte & 0xc0) != 0;
    h.point_format = format_byte & 0x3f;
    const uint16_t base = las_format_record_size(h.point_format);
    if (h.point_format > 10) fail("{}: unknown point format {}", name, h.point_format);
    if (h.point_record_length < base) {
      fail("{}: point record length {} is smaller than point format {} needs ({})", name,
           h.point_record_length, h.point_format, base);
    }
    h.extra_bytes_per_point = static_cast<uint16_t>(h.point_record_length - base);
    const detail::RecordLayout layout =
        detail::record_layout(h.point_format, h.point_record_length);
    h.has_gps_time = layout.gps >= 0;
    h.has_rgb = layout.rgb >= 0;
    h.has_nir = layout.nir >= 0;
    h.has_waveform = layout.wave >= 0;

    // VLRs: between the header and the point data. Each has a 54-byte header.
    const uint64_t vlr_space = h.offset_to_points - h.header_size;
    if (uint64_t{vlr_count} * 54 > vlr_space) {
      fail("{}: {} VLRs cannot fit in the {} bytes before the point data", name, vlr_count,
           vlr_space);
    }
    uint64_t at = h.header_size;
    for (uint32_t i = 0; i < vlr_count; ++i) {
      if (at + 54 > h.offset_to_points) {
        fail("{}: VLR {} header runs past the offset to point data", name, i);
      }
      const std::vector<uint8_t> vh = read(at, 54, "VLR header");
      Vlr v;
      v.user_id = fixed_string(vh.data() + 2, 16);
      v.record_id = load<uint16_t>(vh.data() + 18);
      v.data_size = load<uint16_t>(vh.data() + 20);
      v.description = fixed_string(vh.data() + 22, 32);
      v.data_offset = at + 54;
      if (v.data_offset + v.data_size > h.offset_to_points) {
        fail("{}: VLR {} ({} {}) length {} runs past the offset to point data", name, i, v.user_id,
             v.record_id, v.data_size);
      }
      v.data = read(v.data_offset, v.data_size, "VLR data");
      at = v.data_offset + v.data_size;
      h.vlrs.push_back(std::move(v));
    }

    // EVLRs (1.4): after the point data; each has a 60-byte header.
    if (evlr_count > 0) {
      if (evlr_start < h.offset_to_points || evlr_start > file_size) {
        fail("{}: EVLR offset {} is beyond the file ({} bytes) or before the point data", name,
             evlr_start, file_size);
      }
      if (uint64_t{evlr_count} * 60 > file_size - evlr_start) {
        fail("{}: absurd EVLR count {} for the {} bytes after offset {}", name, evlr_count,
             file_size - evlr_start, evlr_start);
      }
      at = evlr_start;
      for (uint32_t i = 0; i < evlr_count; ++i) {
        const std::vector<uint8_t> vh = read(at, 60, "EVLR header");
        Vlr v;
        v.extended = true;
        v.user_id = fixed_string(vh.data() + 2, 16);
        v.record_id = load<uint16_t>(vh.data() + 18);
        v.data_size = load<uint64_t>(vh.data() + 20);
        v.description = fixed_string(vh.data() + 28, 32);
        v.data_offset = at + 60;
        if (v.data_size > file_size - v.data_offset) {
          fail("{}: EVLR {} ({} {}) length {} runs past the end of the file", name, i, v.user_id,
               v.record_id, v.data_size);
        }
        if (v.data_size <= detail::kMaxVlrDataBytes) {
          v.data = read(v.data_offset, v.data_size, "EVLR data");
        }
        at = v.data_offset + v.data_size;
        h.evlrs.push_back(std::move(v));
      }
    }

    bool laszip_vlr = false;
    for (const Vlr& v : h.vlrs) {
      if (v.user_id == "laszip encoded" && v.record_id == 22204) {
        laszip_vlr = true;
        // compressor, coder (u16 each), version (u8, u8, u16), options (u32), chunk size (u32).
        if (v.data.size() >= 16) {
          const uint32_t chunk = load<uint32_t>(v.data.data() + 12);
          h.laz_chunk_points = chunk == 0xffffffffu ? 0 : chunk;
        }
      }
      if (v.user_id == "copc" && v.record_id == 1) h.copc = true;
    }
    // Writers that add attributes one at a time write one Extra Bytes VLR each (a uint16, then
    // a uint8): the descriptors of all of them, in file order, describe the record together.
    for (const auto* list : {&h.vlrs, &h.evlrs})
      for (const Vlr& v : *list)
        if (v.user_id == "LASF_Spec" && v.record_id == 4)
          for (auto& e : parse_extra_bytes(v)) h.extra_bytes.push_back(std::move(e));
    if (h.compressed && !laszip_vlr) {
      fail("{}: point format byte {} marks the file compressed but it has no LASzip VLR", name,
           format_byte);
    }
    if (!h.compressed && laszip_vlr) h.compressed = true;  // some writers leave the bits clear
    if (h.copc && !h.compressed) h.copc = false;
    size_t described = 0;
    for (const ExtraBytesDescriptor& e : h.extra_bytes) described += e.size;
    if (!h.extra_bytes.empty() && described != h.extra_bytes_per_point) {
      STIPPLE_WARN_ONCE("{}: the Extra Bytes VLRs describe {} bytes but records carry {}", name,
                        described, h.extra_bytes_per_point);
    }

    if (!h.compressed) {
      const uint64_t available = file_size - h.offset_to_points;
      const uint64_t fit = available / h.point_record_length;
      if (h.point_count > fit) {
        fail(
            "{}: header says {} points but the file holds only {} (point data runs past the "
            "end of the file)",
            name, h.point_count, fit);
      }
    } else {
      // The LAZ chunk table offset sits at the start of the point data; check what LASzip will
      // trust (its chunk count sizes an allocation).
      if (h.point_count > 0) {
        const std::vector<uint8_t> t = read(h.offset_to_points, 8, "LAZ chunk table offset");
        const int64_t table = load<int64_t>(t.data());
        // -1: written at the end; the offset of the pointer itself: no table, which LASzip
        // accepts for fixed-size chunks (an interrupted writer, or one COPC node on its own).
        const bool no_table =
            table == static_cast<int64_t>(h.offset_to_points) && h.laz_chunk_points > 0;
        if (table != -1 && !no_table) {
          if (table < static_cast<int64_t>(h.offset_to_points) + 8 ||
              static_cast<uint64_t>(table) + 8 > file_size) {
            fail("{}: corrupt LAZ chunk table offset {} (file has {} bytes)", name, table,
                 file_size);
          }
          const std::vector<uint8_t> ct = read(static_cast<uint64_t>(table), 8, "LAZ chunk table");
          const uint32_t chunks = load<uint32_t>(ct.data() + 4);
          if (chunks > file_size) fail("{}: corrupt LAZ chunk table ({} chunks)", name, chunks);
        }
      }
    }
    return h;
  }
};

void check_scale(const LasHeader& h) {
  for (int i = 0; i < 3; ++i) {
    if (!(std::isfinite(h.scale[i]) && h.scale[i] != 0.0) || !std::isfinite(h.offset[i])) {
      fail("{}: invalid scale {} / offset {} for axis {}", h.path, h.scale[i], h.offset[i],
           "xyz"[i]);
    }
  }
}

}  // namespace

struct LasReader::Impl {
  LasHeader header;
  std::unique_ptr<ByteSource> src;
  std::unique_ptr<detail::LazDecoder> laz;
  detail::RecordLayout layout;
  uint64_t next = 0;  // index of the next point to hand out
  std::vector<uint8_t> buffer;
  // Raw records decoded at open time for RGB detection, handed out first by read().
  std::vector<uint8_t> prefix;
  size_t prefix_points = 0, prefix_used = 0;
  uint64_t fetched = 0;  // records taken from the source so far

  void open(const std::filesystem::path* path, std::span<const uint8_t> memory, bool decode_laz,
            bool drawn_fields_only = false) {
    const std::string name = header.path;
    Parser parser{*src, name};
    header = parser.parse();
    check_scale(header);
    header.crs = detail::parse_crs(header.vlrs, header.evlrs, header.global_encoding, true);
    warn_about_crs(header);
    layout = detail::record_layout(header.point_format, header.point_record_length);
    if (header.compressed) {
      if (!decode_laz) fail("{}: LAZ decoding is disabled for this reader", header.path);
      laz = detail::open_laz_decoder(header.path, path, memory, layout, drawn_fields_only);
    }
    if (header.has_rgb && header.point_count > 0) {
      const size_t n = static_cast<size_t>(
          std::min<uint64_t>({header.point_count, kRgbProbePoints,
                              std::max<uint64_t>(1, (64u << 20) / layout.record_length)}));
      // A file shorter than its header says fails here as fetch() would, but before the buffer
      // for up to 64K records is allocated and zeroed (a cut file's header still counts all of
      // its points: megabytes for nothing).
      const uint64_t available =
          src->size() > header.offset_to_points
              ? (src->size() - header.offset_to_points) / layout.record_length
              : 0;
      if (!laz && available < n)
        fail("{}: file ends early while reading points (point {} of {})", header.path, available,
             header.point_count);
      prefix.resize(n * layout.record_length);
      fetch(prefix.data(), n);
      prefix_points = n;
      bool eight = true, uniform = true;
      const uint8_t* first = prefix.data() + layout.rgb;
      for (size_t i = 0; i < n && (eight || uniform); ++i) {
        const uint8_t* c = prefix.data() + i * layout.record_length + layout.rgb;
        eight = eight && load<uint16_t>(c) <= 255 && load<uint16_t>(c + 2) <= 255 &&
                load<uint16_t>(c + 4) <= 255;
        uniform = uniform && std::memcmp(c, first, 6) == 0;
      }
      header.rgb_bits = eight ? 8 : 16;
      header.rgb_probed = n;
      if (uniform)
        header.rgb_uniform = {load<uint16_t>(first), load<uint16_t>(first + 2),
                              load<uint16_t>(first + 4)};
    }
  }

  // Reads the next n raw records from the file or LASzip.
  void fetch(uint8_t* out, size_t n) {
    if (laz) {
      laz->read(out, n);
    } else {
      const uint64_t offset = header.offset_to_points + fetched * layout.record_length;
      const size_t bytes = n * layout.record_length;
      const size_t got = src->read_some(offset, out, bytes);
      if (got != bytes) {
        fail("{}: file ends early while reading points (point {} of {})", header.path,
             fetched + got / layout.record_length, header.point_count);
      }
    }
    fetched += n;
  }

  void seek(uint64_t index) {
    if (index > header.point_count)
      fail("{}: cannot seek to point {} of {}", header.path, index, header.point_count);
    if (index == next) return;
    // The RGB probe's records only serve sequential reading from the start.
    std::vector<uint8_t>().swap(prefix);
    prefix_points = prefix_used = 0;
    if (laz) laz->seek(index);
    next = fetched = index;
  }

  size_t read(PointBatch& batch, size_t max_points) {
    if (max_points == 0 || next >= header.point_count) return 0;
    const size_t eb = header.extra_bytes_per_point;
    if (batch.size() > 0 && batch.extra_bytes_per_point != eb) {
      fail("{}: batch holds {} extra bytes per point, file has {}", header.path,
           batch.extra_bytes_per_point, eb);
    }
    batch.extra_bytes_per_point = eb;
    return read_records(max_points, [&](const uint8_t* records, size_t k) {
      detail::decode_records(records, k, layout, header.scale, header.offset, batch);
    });
  }

  // Hands the next records (at most max_points) to decode(records, count) in pieces.
  template <typename Decode>
  size_t read_records(size_t max_points, Decode decode) {
    const uint64_t left = header.point_count - next;
    size_t want = static_cast<size_t>(std::min<uint64_t>(max_points, left));
    if (want == 0) return 0;
    size_t done = 0;
    if (prefix_used < prefix_points) {
      const size_t k = std::min(want, prefix_points - prefix_used);
      decode(prefix.data() + prefix_used * layout.record_length, k);
      prefix_used += k;
      done += k;
      if (prefix_used == prefix_points) std::vector<uint8_t>().swap(prefix);
    }
    const size_t per_chunk = std::max<size_t>(1, kChunkBytes / layout.record_length);
    while (done < want) {
      const size_t k = std::min(want - done, per_chunk);
      buffer.resize(k * layout.record_length);
      fetch(buffer.data(), k);
      decode(buffer.data(), k);
      done += k;
    }
    next += done;
    return done;
  }
};

LasReader::LasReader(const std::filesystem::path& path) : LasReader(path, false) {}

LasReader::LasReader(const std::filesystem::path& path, bool drawn_fields_only)
    : impl_(std::make_unique<Impl>()) {
  impl_->header.path = path.string();
  impl_->src = std::make_unique<FileSource>(path, impl_->header.path);
  impl_->open(&path, {}, true, drawn_fields_only);
}

LasReader::LasReader(std::span<const uint8_t> bytes, std::string name, bool decode_laz)
    : impl_(std::make_unique<Impl>()) {
  impl_->header.path = std::move(name);
  impl_->src = std::make_unique<MemorySource>(bytes);
  impl_->open(nullptr, bytes, decode_laz);
}

LasReader::~LasReader() = default;
LasReader::LasReader(LasReader&&) noexcept = default;
LasReader& LasReader::operator=(LasReader&&) noexcept = default;

const LasHeader& LasReader::header() const {
  return impl_->header;
}
size_t LasReader::read(PointBatch& batch, size_t max_points) {
  return impl_->read(batch, max_points);
}
size_t LasReader::read_positions(std::vector<glm::dvec3>& positions, size_t max_points) {
  Impl& r = *impl_;
  return r.read_records(max_points, [&](const uint8_t* records, size_t k) {
    detail::decode_positions(records, k, r.layout, r.header.scale, r.header.offset, positions);
  });
}
size_t LasReader::read_drawn(std::span<DrawnPoint> out) {
  Impl& r = *impl_;
  DrawnPoint* at = out.data();
  return r.read_records(out.size(), [&](const uint8_t* records, size_t k) {
    detail::decode_drawn(records, k, r.layout, r.header.scale, r.header.offset, at);
    at += k;
  });
}
void LasReader::seek(uint64_t index) {
  impl_->seek(index);
}
uint64_t LasReader::points_read() const {
  return impl_->next;
}

LasHeader read_las_header(const std::filesystem::path& path) {
  const std::string name = path.string();
  FileSource src(path, name);
  Parser parser{src, name};
  LasHeader h = parser.parse();
  check_scale(h);
  h.crs = detail::parse_crs(h.vlrs, h.evlrs, h.global_encoding, true);
  warn_about_crs(h);
  return h;
}

}  // namespace stipple::io
