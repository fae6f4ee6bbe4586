// libFuzzer target: the LAS writer's round trip. The input chooses the options (LAS 1.2-1.4,
// point formats 0-10, scale and offset, LAZ compression, undocumented extra bytes, a WKT) and the
// points, with every attribute in the range its format stores; the file is written with
// LasWriter, read back with LasReader, and every attribute must come back as written (positions
// to the quantum), with the header's count and bounds matching. A mismatch aborts (a finding);
// a writer's stipple::Error (a coordinate that does not fit 32 bits) is a correct rejection.
#include <fuzzer/FuzzedDataProvider.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <spdlog/spdlog.h>

#include "stipple/core/error.hpp"
#include "stipple/io/las.hpp"

namespace io = stipple::io;

namespace {

std::filesystem::path g_path;

[[noreturn]] void mismatch(const char* what, size_t i) {
  std::fprintf(stderr, "round trip mismatch: %s of point %zu\n", what, i);
  std::abort();
}

void check(bool ok, const char* what, size_t i = 0) {
  if (!ok) mismatch(what, i);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  // In memory where the machine has /dev/shm: a file is written, read and removed per input.
  const std::filesystem::path base = std::filesystem::is_directory("/dev/shm")
                                         ? std::filesystem::path("/dev/shm")
                                         : std::filesystem::temp_directory_path();
  g_path = base / ("stipple_fuzz_roundtrip_" + std::to_string(::getpid()) + ".las");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider in(data, size);
  io::LasWriteOptions o;
  o.version_minor = in.ConsumeIntegralInRange<uint8_t>(2, 4);
  o.point_format = in.ConsumeIntegralInRange<uint8_t>(0, o.version_minor == 4 ? 10 : 5);
  o.compress = in.ConsumeIntegralInRange(0, 3) == 0;
  for (int a = 0; a < 3; ++a) {
    static constexpr double kScales[] = {0.001, 0.01, 1.0, 1e-7, 0.25, 100.0};
    o.scale[a] = kScales[in.ConsumeIntegralInRange<size_t>(0, std::size(kScales) - 1)];
    o.offset[a] = double(in.ConsumeIntegralInRange<int32_t>(-1'000'000, 1'000'000)) *
                  (in.ConsumeBool() ? 1.0 : 10.0);
  }
  const uint8_t extra =
      in.ConsumeIntegralInRange<uint8_t>(0, 3) == 0 ? in.ConsumeIntegralInRange<uint8_t>(1, 12) : 0;
  if (extra) {
    io::ExtraBytesDescriptor e;
    e.data_type = 0;  // undocumented: `options` bytes, copied raw
    e.options = extra;
    e.name = "raw";
    o.extra_bytes.push_back(e);
  }
  // A WKT is rare: reading one back goes through PROJ (its database), 100 times slower than the
  // rest of a round trip.
  if (in.ConsumeIntegralInRange(0, 31) == 0) o.wkt = in.ConsumeRandomLengthString(200);
  const bool extended = o.point_format >= 6;
  const bool gps = o.point_format != 0 && o.point_format != 2;
  const bool rgb = o.point_format == 2 || o.point_format == 3 || o.point_format == 5 ||
                   o.point_format == 7 || o.point_format == 8 || o.point_format == 10;
  const bool nir = o.point_format == 8 || o.point_format == 10;
  const bool wave =
      o.point_format == 4 || o.point_format == 5 || o.point_format == 9 || o.point_format == 10;

  io::PointBatch b;
  std::vector<glm::i64vec3> q;  // the quantised coordinates written
  const size_t n = in.ConsumeIntegralInRange<size_t>(0, 300);
  for (size_t i = 0; i < n && in.remaining_bytes() > 0; ++i) {
    glm::i64vec3 k;
    for (int a = 0; a < 3; ++a) k[a] = in.ConsumeIntegral<int32_t>();
    q.push_back(k);
    b.positions.push_back(glm::dvec3(k) * o.scale + o.offset);
    b.intensity.push_back(in.ConsumeIntegral<uint16_t>());
    const uint8_t max_return = extended ? 15 : 7;
    b.return_number.push_back(in.ConsumeIntegralInRange<uint8_t>(0, max_return));
    b.number_of_returns.push_back(in.ConsumeIntegralInRange<uint8_t>(0, max_return));
    const uint8_t cls =
        extended ? in.ConsumeIntegral<uint8_t>() : in.ConsumeIntegralInRange<uint8_t>(0, 31);
    b.classification.push_back(cls);
    uint8_t flags = in.ConsumeIntegral<uint8_t>();
    // Formats 0-5 store synthetic, key-point, withheld, scan direction and edge; overlap is
    // class 12 there.
    if (!extended) flags = static_cast<uint8_t>((flags & 0xc7) | (cls == 12 ? 8 : 0));
    b.flags.push_back(flags);
    b.scan_angle.push_back(extended ? float(in.ConsumeIntegral<int16_t>() * 0.006)
                                    : float(in.ConsumeIntegral<int8_t>()));
    b.user_data.push_back(in.ConsumeIntegral<uint8_t>());
    b.point_source_id.push_back(in.ConsumeIntegral<uint16_t>());
    if (gps) b.gps_time.push_back(in.ConsumeFloatingPoint<double>());
    if (rgb) {
      b.rgb.push_back({in.ConsumeIntegral<uint16_t>(), in.ConsumeIntegral<uint16_t>(),
                       in.ConsumeIntegral<uint16_t>()});
    }
    if (nir) b.nir.push_back(in.ConsumeIntegral<uint16_t>());
    if (wave) {
      b.wave_packets.push_back({in.ConsumeIntegral<uint8_t>(), in.ConsumeIntegral<uint64_t>(),
                                in.ConsumeIntegral<uint32_t>(), in.ConsumeFloatingPoint<float>(),
                                in.ConsumeFloatingPoint<float>(), in.ConsumeFloatingPoint<float>(),
                                in.ConsumeFloatingPoint<float>()});
    }
    for (uint8_t e = 0; e < extra; ++e) b.extra_bytes.push_back(in.ConsumeIntegral<uint8_t>());
  }
  b.extra_bytes_per_point = extra;
  const size_t count = b.size();  // every attribute was pushed for each point

  try {
    io::LasWriter w(g_path, o);
    w.write(b);
    w.close();
  } catch (const stipple::Error&) {
    std::filesystem::remove(g_path);
    return 0;  // e.g. a WKT the writer refuses
  }
  try {
    io::LasReader r(g_path);
    const io::LasHeader& h = r.header();
    check(h.point_count == count, "point count");
    check(h.point_format == o.point_format, "point format");
    check(h.compressed == o.compress, "compression");
    check(h.extra_bytes_per_point == extra, "extra bytes per point");
    io::PointBatch got;
    while (r.read(got, 97) > 0) {
    }
    check(got.size() == count, "points read");
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (size_t i = 0; i < count; ++i) {
      for (int a = 0; a < 3; ++a) {
        const double back = std::round((got.positions[i][a] - o.offset[a]) / o.scale[a]);
        check(back == double(q[i][a]), "position", i);
        lo[a] = std::min(lo[a], got.positions[i][a]);
        hi[a] = std::max(hi[a], got.positions[i][a]);
      }
      check(got.intensity[i] == b.intensity[i], "intensity", i);
      check(got.return_number[i] == b.return_number[i], "return number", i);
      check(got.number_of_returns[i] == b.number_of_returns[i], "number of returns", i);
      check(got.classification[i] == b.classification[i], "classification", i);
      check(got.flags[i] == b.flags[i], "flags", i);
      check(got.scan_angle[i] == b.scan_angle[i], "scan angle", i);
      check(got.user_data[i] == b.user_data[i], "user data", i);
      check(got.point_source_id[i] == b.point_source_id[i], "point source id", i);
      if (gps) {
        const double a = got.gps_time[i], e = b.gps_time[i];
        check(a == e || (std::isnan(a) && std::isnan(e)), "gps time", i);
      }
      if (rgb) check(got.rgb[i] == b.rgb[i], "rgb", i);
      if (nir) check(got.nir[i] == b.nir[i], "nir", i);
      if (wave) {
        const auto &a = got.wave_packets[i], &e = b.wave_packets[i];
        check(a.descriptor_index == e.descriptor_index && a.data_offset == e.data_offset &&
                  a.data_size == e.data_size,
              "wave packet", i);
      }
    }
    check(got.extra_bytes == b.extra_bytes, "extra bytes");
    if (count > 0) {
      for (int a = 0; a < 3; ++a) {
        check(std::abs(h.min[a] - lo[a]) <= o.scale[a] && std::abs(h.max[a] - hi[a]) <= o.scale[a],
              "header bounds");
      }
    }
  } catch (const stipple::Error& e) {
    std::fprintf(stderr, "a file the writer made is unreadable: %s\n", e.what());
    std::abort();
  }
  std::filesystem::remove(g_path);
  return 0;
}
