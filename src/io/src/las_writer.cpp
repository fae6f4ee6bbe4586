// LAS/LAZ writing. Uncompressed files are written directly; LAZ goes through LASzip. Either way
// the header's counts, bounds and return histogram are patched in at close().
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <exception>
#include <fstream>
#include <limits>

#include "las_detail.hpp"
#include "stipple/core/atomic_file.hpp"
#include "stipple/core/error.hpp"
#include "stipple/core/log.hpp"
#include "stipple/io/las.hpp"

namespace stipple::io {

using detail::store;

namespace {

void put_fixed(uint8_t* dst, const std::string& s, size_t n) {
  std::memset(dst, 0, n);
  std::memcpy(dst, s.data(), std::min(s.size(), n));
}

// The public header block of h, header_size bytes long.
std::vector<uint8_t> encode_header(const LasHeader& h, uint32_t vlr_count, uint64_t evlr_start = 0,
                                   uint32_t evlr_count = 0) {
  std::vector<uint8_t> b(375, 0);
  uint8_t* p = b.data();
  std::memcpy(p, "LASF", 4);
  store<uint16_t>(p + 4, h.file_source_id);
  store<uint16_t>(p + 6, h.global_encoding);
  std::memcpy(p + 8, h.guid.data(), 16);
  p[24] = 1;
  p[25] = h.version_minor;
  put_fixed(p + 26, h.system_identifier, 32);
  put_fixed(p + 58, h.generating_software, 32);
  store<uint16_t>(p + 90, h.creation_day);
  store<uint16_t>(p + 92, h.creation_year);
  store<uint16_t>(p + 94, h.header_size);
  store<uint32_t>(p + 96, h.offset_to_points);
  store<uint32_t>(p + 100, vlr_count);
  p[104] = static_cast<uint8_t>(h.point_format | (h.compressed ? 0x80 : 0));
  store<uint16_t>(p + 105, h.point_record_length);
  // Legacy counts: zero where they cannot hold the value or (1.4) for formats 6-10.
  const bool legacy_ok = h.point_format < 6 && h.point_count <= 0xffffffffu;
  store<uint32_t>(p + 107, legacy_ok ? static_cast<uint32_t>(h.point_count) : 0);
  for (int i = 0; i < 5; ++i) {
    const uint64_t n = h.points_by_return[i];
    store<uint32_t>(p + 111 + 4 * i, legacy_ok && n <= 0xffffffffu ? static_cast<uint32_t>(n) : 0);
  }
  for (int i = 0; i < 3; ++i) {
    store<double>(p + 131 + 8 * i, h.scale[i]);
    store<double>(p + 155 + 8 * i, h.offset[i]);
    store<double>(p + 179 + 16 * i, h.max[i]);
    store<double>(p + 187 + 16 * i, h.min[i]);
  }
  if (h.version_minor >= 3) store<uint64_t>(p + 227, h.start_of_waveform_data);
  if (h.version_minor >= 4) {
    store<uint64_t>(p + 235, evlr_count ? evlr_start : 0);
    store<uint32_t>(p + 243, evlr_count);
    store<uint64_t>(p + 247, h.point_count);
    for (int i = 0; i < 15; ++i) store<uint64_t>(p + 255 + 8 * i, h.points_by_return[i]);
  }
  b.resize(h.header_size);
  return b;
}

std::vector<uint8_t> encode_extra_bytes_vlr(const std::vector<ExtraBytesDescriptor>& list) {
  std::vector<uint8_t> out(list.size() * 192, 0);
  for (size_t i = 0; i < list.size(); ++i) {
    const ExtraBytesDescriptor& e = list[i];
    uint8_t* d = out.data() + i * 192;
    d[2] = e.data_type;
    d[3] = e.options;
    put_fixed(d + 4, e.name, 32);
    std::memcpy(d + 40, e.no_data.data(), 24);
    std::memcpy(d + 64, e.min.data(), 24);
    std::memcpy(d + 88, e.max.data(), 24);
    for (int k = 0; k < 3; ++k) {
      store<double>(d + 112 + 8 * k, e.scale[k]);
      store<double>(d + 136 + 8 * k, e.offset[k]);
    }
    put_fixed(d + 160, e.description, 32);
  }
  return out;
}

}  // namespace

struct LasWriter::Impl {
  std::filesystem::path path;  // the temporary of `file` until close()
  std::unique_ptr<AtomicFile> file;
  int exceptions_at_open = 0;  // std::uncaught_exceptions() when the writer was made
  std::string name;
  LasWriteOptions options;
  LasHeader h;
  detail::RecordLayout layout;
  std::vector<Vlr> vlrs, evlrs;
  std::ofstream out;                        // uncompressed
  std::unique_ptr<detail::LazEncoder> laz;  // compressed
  std::vector<uint8_t> buffer;
  glm::dvec3 lo{std::numeric_limits<double>::infinity()};
  glm::dvec3 hi{-std::numeric_limits<double>::infinity()};
  bool closed = false;

  void open() {
    const LasWriteOptions& o = options;
    if (o.version_minor < 2 || o.version_minor > 4) {
      fail("{}: cannot write LAS 1.{} (1.2, 1.3 or 1.4 only)", name, o.version_minor);
    }
    if (o.point_format > 10) fail("{}: unknown point format {}", name, o.point_format);
    if (o.point_format >= 6 && o.version_minor < 4) {
      fail("{}: point format {} needs LAS 1.4", name, o.point_format);
    }
    for (int i = 0; i < 3; ++i) {
      if (!(std::isfinite(o.scale[i]) && o.scale[i] > 0) || !std::isfinite(o.offset[i])) {
        fail("{}: invalid scale {} / offset {}", name, o.scale[i], o.offset[i]);
      }
    }
    size_t eb = 0;
    h.extra_bytes = o.extra_bytes;
    for (ExtraBytesDescriptor& e : h.extra_bytes) {
      const size_t size = extra_bytes_type_size(e.data_type, e.options);
      if (size == 0) fail("{}: extra bytes attribute '{}' has no size", name, e.name);
      e.size = size;
      eb += size;
    }
    const size_t record = las_format_record_size(o.point_format) + eb;
    if (record > 65535) fail("{}: point records of {} bytes are too large", name, record);

    h.path = name;
    h.version_major = 1;
    h.version_minor = o.version_minor;
    h.point_format = o.point_format;
    h.point_record_length = static_cast<uint16_t>(record);
    h.extra_bytes_per_point = static_cast<uint16_t>(eb);
    h.compressed = o.compress;
    h.header_size = o.version_minor >= 4 ? 375 : o.version_minor == 3 ? 235 : 227;
    h.scale = o.scale;
    h.offset = o.offset;
    h.system_identifier = o.system_identifier;
    h.generating_software = o.generating_software;
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    h.creation_day = static_cast<uint16_t>(tm.tm_yday + 1);
    h.creation_year = static_cast<uint16_t>(tm.tm_year + 1900);
    if (!h.extra_bytes.empty()) {
      vlrs.push_back({"LASF_Spec", 4, "Extra Bytes", encode_extra_bytes_vlr(h.extra_bytes)});
    }
    h.global_encoding = o.global_encoding & 0x1d;        // see LasWriteOptions::global_encoding
    if (o.version_minor < 4) h.global_encoding &= 0x0f;  // bit 4 (WKT) is 1.4's
    h.file_source_id = o.file_source_id;
    h.guid = o.guid;
    if (!o.wkt.empty()) {
      std::vector<uint8_t> wkt(o.wkt.begin(), o.wkt.end());
      wkt.push_back(0);  // the spec asks for a null-terminated string
      if (wkt.size() > 65535) fail("{}: WKT of {} bytes is too long for a VLR", name, wkt.size());
      vlrs.push_back({"LASF_Projection", 2112, "OGC WKT", std::move(wkt)});
      if (o.version_minor >= 4) h.global_encoding |= 1 << 4;  // CRS is WKT
    }
    for (const Vlr& v : o.vlrs) {
      if (v.data.size() != v.data_size)
        fail("{}: VLR {} {} has no loaded payload to copy", name, v.user_id, v.record_id);
      Vlr copy = v;
      copy.extended = false;
      (v.data.size() > 65535 ? evlrs : vlrs).push_back(std::move(copy));
    }
    for (const Vlr& v : o.evlrs) {
      if (v.data.size() != v.data_size)
        fail("{}: EVLR {} {} has no loaded payload to copy", name, v.user_id, v.record_id);
      evlrs.push_back(v);
    }
    if (!evlrs.empty() && o.version_minor < 4)
      fail("{}: {} extended VLRs need LAS 1.4", name, evlrs.size());
    for (Vlr& v : evlrs) v.extended = true;
    for (Vlr& v : vlrs) v.data_size = v.data.size();
    layout = detail::record_layout(h.point_format, h.point_record_length);

    if (o.compress) {
      laz = detail::open_laz_encoder(path, h, vlrs, layout);
      return;
    }
    uint64_t offset = h.header_size;
    for (const Vlr& v : vlrs) offset += 54 + v.data.size();
    h.offset_to_points = static_cast<uint32_t>(offset);
    out.open(path, std::ios::binary | std::ios::trunc);
    if (!out) fail("{}: cannot create file: {}", name, std::strerror(errno));
    const std::vector<uint8_t> header = encode_header(h, static_cast<uint32_t>(vlrs.size()));
    out.write(reinterpret_cast<const char*>(header.data()), header.size());
    for (const Vlr& v : vlrs) {
      uint8_t vh[54] = {};
      put_fixed(vh + 2, v.user_id, 16);
      store<uint16_t>(vh + 18, v.record_id);
      store<uint16_t>(vh + 20, static_cast<uint16_t>(v.data.size()));
      put_fixed(vh + 22, v.description, 32);
      out.write(reinterpret_cast<const char*>(vh), 54);
      out.write(reinterpret_cast<const char*>(v.data.data()), v.data.size());
    }
    if (!out) fail("{}: write failed", name);
  }

  void write(const PointBatch& b) {
    if (closed) fail("{}: write after close", name);
    const size_t n = b.size();
    if (n == 0) return;
    const size_t eb = layout.extra_bytes();
    if (eb && (b.extra_bytes_per_point != eb || b.extra_bytes.size() < n * eb)) {
      fail("{}: batch has {} extra bytes per point, the file's layout needs {}", name,
           b.extra_bytes_per_point, eb);
    }
    constexpr size_t kStep = 8192;  // bounded staging buffer
    for (size_t start = 0; start < n; start += kStep) {
      const size_t k = std::min(kStep, n - start);
      buffer.resize(k * layout.record_length);
      for (size_t i = 0; i < k; ++i) {
        uint8_t* r = buffer.data() + i * layout.record_length;
        detail::encode_record(b, start + i, layout, h.scale, h.offset, r);
        // Bounds and return counts of what is stored, so they match what a reader decodes.
        for (int a = 0; a < 3; ++a) {
          const double v = detail::load<int32_t>(r + 4 * a) * h.scale[a] + h.offset[a];
          lo[a] = std::min(lo[a], v);
          hi[a] = std::max(hi[a], v);
        }
        const int rn = layout.extended() ? (r[14] & 15) : (r[14] & 7);
        if (rn >= 1 && rn <= 15) ++h.points_by_return[rn - 1];
        if (laz) {
          // LASzip's wave packet encoders (v1 and v3) test whether the offset step equals the
          // previous packet's size after casting that size to a signed 32-bit integer, while the
          // decoders add it unsigned: after a packet of 2 GiB or more, an offset step of
          // size - 4 GiB is stored as "step = size" and read back 4 GiB off. Refused, not
          // written wrong; such sizes only ever come from damaged input.
          if (layout.wave >= 0) {
            const uint32_t wave_size = detail::load<uint32_t>(r + layout.wave + 9);
            if (wave_size >= 0x80000000u) {
              fail(
                  "{}: point {} has a wave packet of {} bytes, which LAZ (LASzip) cannot store "
                  "exactly; write LAS instead",
                  name, h.point_count + i, wave_size);
            }
          }
          laz->write(r);
        }
      }
      if (!laz) {
        out.write(reinterpret_cast<const char*>(buffer.data()), buffer.size());
        if (!out) fail("{}: write failed", name);
      }
      h.point_count += k;
    }
  }

  // Finishes the file under its temporary name, then renames it into place.
  void close() {
    if (closed) return;
    closed = true;
    finish();
    file->commit();
  }

  // Appends the EVLRs at the stream's end; returns where they start.
  uint64_t write_evlrs(std::ostream& f) {
    f.seekp(0, std::ios::end);
    const uint64_t start = static_cast<uint64_t>(f.tellp());
    for (const Vlr& v : evlrs) {
      uint8_t vh[60] = {};
      put_fixed(vh + 2, v.user_id, 16);
      store<uint16_t>(vh + 18, v.record_id);
      store<uint64_t>(vh + 20, v.data.size());
      put_fixed(vh + 28, v.description, 32);
      f.write(reinterpret_cast<const char*>(vh), 60);
      f.write(reinterpret_cast<const char*>(v.data.data()), std::streamsize(v.data.size()));
    }
    if (!f) fail("{}: cannot write the extended VLRs", name);
    return start;
  }

  void finish() {
    if (h.point_count > 0) {
      h.min = lo;
      h.max = hi;
    }
    if (h.version_minor < 4 && h.point_count > 0xffffffffu) {
      fail("{}: {} points need LAS 1.4", name, h.point_count);
    }
    std::vector<uint8_t> header;
    const uint32_t evlr_count = static_cast<uint32_t>(evlrs.size());
    if (laz) {
      laz->close();
      laz.reset();
      // LASzip wrote its own header (with its VLR); patch counts and bounds in place. EVLRs go
      // after its chunk table, where LASzip-based readers expect them.
      std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
      uint8_t existing[375] = {};
      f.read(reinterpret_cast<char*>(existing), h.header_size);
      if (!f) fail("{}: cannot reopen to finish the header", name);
      const uint64_t evlr_start = evlr_count ? write_evlrs(f) : 0;
      h.offset_to_points = detail::load<uint32_t>(existing + 96);
      header = encode_header(h, detail::load<uint32_t>(existing + 100), evlr_start, evlr_count);
      // Keep LASzip's format byte (compression bits) and everything before the counts.
      header[104] = existing[104];
      f.seekp(0);
      f.write(reinterpret_cast<const char*>(header.data()), header.size());
      if (!f) fail("{}: cannot finish the header", name);
      return;
    }
    const uint64_t evlr_start = evlr_count ? write_evlrs(out) : 0;
    header = encode_header(h, static_cast<uint32_t>(vlrs.size()), evlr_start, evlr_count);
    out.seekp(0);
    out.write(reinterpret_cast<const char*>(header.data()), header.size());
    out.close();
    if (!out) fail("{}: write failed", name);
  }
};

LasWriter::LasWriter(const std::filesystem::path& path, LasWriteOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->file = std::make_unique<AtomicFile>(path);
  impl_->exceptions_at_open = std::uncaught_exceptions();
  impl_->path = impl_->file->temp_path();
  impl_->name = path.string();
  impl_->options = std::move(options);
  impl_->open();
}

LasWriter::~LasWriter() {
  // Unwinding from an error after the writer was made: the output is incomplete, so it never
  // appears (the temporary goes with the AtomicFile). Otherwise the file is finished here.
  if (std::uncaught_exceptions() > impl_->exceptions_at_open) return;
  try {
    impl_->close();
  } catch (const Error& e) {
    STIPPLE_ERROR("{}", e.what());
  }
}

void LasWriter::write(const PointBatch& batch) {
  impl_->write(batch);
}
void LasWriter::close() {
  impl_->close();
}
uint64_t LasWriter::points_written() const {
  return impl_->h.point_count;
}

}  // namespace stipple::io
