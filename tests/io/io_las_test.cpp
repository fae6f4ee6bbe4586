// LAS/LAZ/COPC reading and LAS/LAZ writing: real files from ../shared/data (expected values were
// read with laspy 2.7 + lazrs, an independent implementation), full-field round trips of every
// point format, and corrupt-input handling.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include "las_bytes.hpp"
#include "stipple/core/error.hpp"
#include "stipple/io/las.hpp"

namespace fs = std::filesystem;
using stipple::Error;
using namespace stipple::io;

namespace {

fs::path data_dir() {
  if (const char* env = std::getenv("STIPPLE_DATA_DIR")) return env;
#ifdef STIPPLE_SOURCE_DIR
  return fs::path(STIPPLE_SOURCE_DIR "/../shared/data");
#else
  return {};
#endif
}

#define REQUIRE_DATA(rel)                                                        \
  const fs::path file = data_dir() / (rel);                                      \
  if (data_dir().empty() || !fs::exists(file)) {                                 \
    GTEST_SKIP() << "test data " << file << " not found (set STIPPLE_DATA_DIR)"; \
  }

PointBatch read_all(LasReader& reader, size_t chunk = 10000) {
  PointBatch all;
  while (reader.read(all, chunk) > 0) {
  }
  return all;
}

fs::path temp_dir() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("stipple_io_test_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

// Every array and every value equal.
void expect_same(const PointBatch& a, const PointBatch& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.intensity, b.intensity);
  EXPECT_EQ(a.return_number, b.return_number);
  EXPECT_EQ(a.number_of_returns, b.number_of_returns);
  EXPECT_EQ(a.classification, b.classification);
  EXPECT_EQ(a.flags, b.flags);
  EXPECT_EQ(a.scan_angle, b.scan_angle);
  EXPECT_EQ(a.user_data, b.user_data);
  EXPECT_EQ(a.point_source_id, b.point_source_id);
  EXPECT_EQ(a.gps_time, b.gps_time);
  EXPECT_EQ(a.rgb, b.rgb);
  EXPECT_EQ(a.nir, b.nir);
  ASSERT_EQ(a.wave_packets.size(), b.wave_packets.size());
  for (size_t i = 0; i < a.wave_packets.size(); ++i) {
    const auto &x = a.wave_packets[i], &y = b.wave_packets[i];
    ASSERT_EQ(std::memcmp(&x.descriptor_index, &y.descriptor_index, 1), 0);
    EXPECT_EQ(x.data_offset, y.data_offset);
    EXPECT_EQ(x.data_size, y.data_size);
    EXPECT_EQ(x.return_point_location, y.return_point_location);
    EXPECT_EQ(x.dx, y.dx);
    EXPECT_EQ(x.dy, y.dy);
    EXPECT_EQ(x.dz, y.dz);
  }
  EXPECT_EQ(a.extra_bytes_per_point, b.extra_bytes_per_point);
  EXPECT_EQ(a.extra_bytes, b.extra_bytes);
}

void expect_within_header_bounds(const PointBatch& b, const LasHeader& h) {
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const glm::dvec3& p : b.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  for (int a = 0; a < 3; ++a) {
    // Header bounds are rounded by some writers; allow half a scale step.
    EXPECT_NEAR(lo[a], h.min[a], h.scale[a]) << "axis " << a;
    EXPECT_NEAR(hi[a], h.max[a], h.scale[a]) << "axis " << a;
  }
}

}  // namespace

TEST(LasRead, AutzenLazMatchesLas) {
  REQUIRE_DATA("las/autzen_trim.las");
  const fs::path laz_file = data_dir() / "laz/autzen_trim.laz";
  if (!fs::exists(laz_file)) GTEST_SKIP() << laz_file << " not found";
  LasReader las(file), laz(laz_file);
  const LasHeader& h = las.header();
  EXPECT_EQ(h.version_major, 1);
  EXPECT_EQ(h.version_minor, 2);
  EXPECT_EQ(h.point_format, 3);
  EXPECT_EQ(h.point_count, 110000u);
  EXPECT_FALSE(h.compressed);
  EXPECT_TRUE(laz.header().compressed);
  EXPECT_FALSE(laz.header().copc);
  EXPECT_EQ(laz.header().laz_chunk_points, 50000u);  // LASzip's default chunk
  EXPECT_EQ(h.laz_chunk_points, 0u);
  EXPECT_EQ(laz.header().point_format, 3);
  EXPECT_EQ(laz.header().point_count, 110000u);
  EXPECT_TRUE(h.has_rgb && h.has_gps_time && !h.has_nir && !h.has_waveform);
  EXPECT_EQ(h.rgb_bits, 8);
  EXPECT_EQ(laz.header().rgb_bits, 8);
  EXPECT_EQ(h.scale, laz.header().scale);
  EXPECT_EQ(h.min, laz.header().min);
  EXPECT_EQ(h.max, laz.header().max);
  // CRS: a user-defined (no EPSG code) Lambert conformal conic in feet, as GeoTIFF keys
  // (ProjectedCSTypeGeoKey 32767) and WKT; the WKT's last AUTHORITY (the unit's) is no CRS code.
  EXPECT_FALSE(h.crs.wkt.empty());
  EXPECT_EQ(h.crs.epsg, 0);
  EXPECT_FALSE(h.crs.geographic);
  EXPECT_EQ(h.crs.name, "NAD_1983_HARN_Lambert_Conformal_Conic");
  EXPECT_EQ(h.crs.linear_unit, "foot");
  bool unit_key = false;
  for (const auto& k : h.crs.geokeys) unit_key |= k[0] == 3076 && k[3] == 9002;
  EXPECT_TRUE(unit_key);
  EXPECT_EQ(h.crs.geo_doubles.size(), 9u);

  const PointBatch a = read_all(las, 7777), b = read_all(laz, 4096);
  EXPECT_EQ(las.points_read(), 110000u);
  PointBatch more;
  EXPECT_EQ(las.read(more, 10), 0u) << "reads nothing past the end";
  expect_same(a, b);
  ASSERT_EQ(a.size(), 110000u);
  EXPECT_TRUE(a.nir.empty() && a.wave_packets.empty() && a.extra_bytes.empty());
  EXPECT_EQ(a.gps_time.size(), a.size());
  EXPECT_EQ(a.rgb.size(), a.size());
  // First and last points (laspy).
  EXPECT_DOUBLE_EQ(a.positions[0].x, 637177.98);
  EXPECT_DOUBLE_EQ(a.positions[0].y, 849393.95);
  EXPECT_DOUBLE_EQ(a.positions[0].z, 411.19);
  EXPECT_EQ(a.intensity[0], 4);
  EXPECT_EQ(a.return_number[0], 1);
  EXPECT_EQ(a.number_of_returns[0], 1);
  EXPECT_EQ(a.classification[0], 1);
  EXPECT_EQ(a.flags[0], 0);
  EXPECT_EQ(a.scan_angle[0], -17.0f);
  EXPECT_EQ(a.user_data[0], 128);
  EXPECT_EQ(a.point_source_id[0], 7326);
  EXPECT_DOUBLE_EQ(a.gps_time[0], 245379.39843682514);
  EXPECT_EQ(a.rgb[0], glm::u16vec3(84, 102, 93));
  const size_t l = a.size() - 1;
  EXPECT_DOUBLE_EQ(a.positions[l].x, 636037.88);
  EXPECT_DOUBLE_EQ(a.positions[l].y, 849336.94);
  EXPECT_DOUBLE_EQ(a.positions[l].z, 423.2);
  EXPECT_EQ(a.intensity[l], 100);
  EXPECT_EQ(a.scan_angle[l], -9.0f);
  EXPECT_EQ(a.user_data[l], 124);
  EXPECT_DOUBLE_EQ(a.gps_time[l], 245385.91112104454);
  EXPECT_EQ(a.rgb[l], glm::u16vec3(64, 74, 70));
  expect_within_header_bounds(a, h);
  uint64_t by_return[15] = {};
  for (uint8_t r : a.return_number) ++by_return[r - 1];
  for (int i = 0; i < 5; ++i) EXPECT_EQ(by_return[i], h.points_by_return[i]) << i;
}

TEST(LasRead, SimpleLazMatchesLasAndMemoryMatchesFile) {
  REQUIRE_DATA("las/simple.las");
  const fs::path laz_file = data_dir() / "laz/simple.laz";
  if (!fs::exists(laz_file)) GTEST_SKIP() << laz_file << " not found";
  LasReader las(file), laz(laz_file);
  EXPECT_EQ(las.header().point_count, 1065u);
  const PointBatch a = read_all(las, 100);
  expect_same(a, read_all(laz, 1));
  // In-memory readers (the fuzzer's entry point) give the same points, LAZ included.
  for (const fs::path& p : {file, laz_file}) {
    std::ifstream in(p, std::ios::binary);
    std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
    LasReader mem(bytes, p.filename().string());
    expect_same(a, read_all(mem, 333));
  }
}

TEST(LasRead, Las14Format6) {
  REQUIRE_DATA("las/test1_4.las");
  LasReader r(file);
  const LasHeader& h = r.header();
  EXPECT_EQ(h.version_minor, 4);
  EXPECT_EQ(h.point_format, 6);
  EXPECT_EQ(h.header_size, 375);
  EXPECT_EQ(h.point_count, 1000u);
  EXPECT_TRUE(h.has_gps_time);
  EXPECT_FALSE(h.has_rgb);
  EXPECT_FALSE(h.crs.wkt.empty());
  const PointBatch b = read_all(r, 300);
  ASSERT_EQ(b.size(), 1000u);
  EXPECT_NEAR(b.positions[0].x, 1694510.3869346841, 1e-9);
  EXPECT_NEAR(b.positions[0].y, 1816497.966263977, 1e-9);
  EXPECT_NEAR(b.positions[0].z, 5598.3596128149675, 1e-9);
  EXPECT_EQ(b.intensity[0], 41);
  EXPECT_EQ(b.return_number[0], 1);
  EXPECT_EQ(b.number_of_returns[0], 1);
  EXPECT_EQ(b.classification[0], 2);
  EXPECT_EQ(b.flags[0], 0x48);  // overlap + scan direction
  EXPECT_FLOAT_EQ(b.scan_angle[0], 3005 * 0.006f);
  EXPECT_EQ(b.point_source_id[0], 202);
  EXPECT_DOUBLE_EQ(b.gps_time[0], 83177420.53400505);
  EXPECT_NEAR(b.positions[999].x, 1694291.6363326558, 1e-9);
  EXPECT_FLOAT_EQ(b.scan_angle[999], 2504 * 0.006f);
  EXPECT_DOUBLE_EQ(b.gps_time[999], 83177420.60104504);
  expect_within_header_bounds(b, h);
}

TEST(LasRead, Copc) {
  REQUIRE_DATA("laz/lone-star.copc.laz");
  LasReader r(file);
  const LasHeader& h = r.header();
  EXPECT_TRUE(h.compressed);
  EXPECT_TRUE(h.copc);
  EXPECT_EQ(h.laz_chunk_points, 0u);  // COPC: variable chunks, one per octree node
  EXPECT_EQ(h.version_minor, 4);
  EXPECT_EQ(h.point_format, 6);
  EXPECT_EQ(h.point_count, 518862u);
  EXPECT_EQ(h.evlrs.size(), 1u);
  EXPECT_EQ(h.evlrs[0].user_id, "copc");
  EXPECT_FALSE(h.crs.wkt.empty());
  PointBatch b;
  size_t n = 0, calls = 0;
  while (size_t k = r.read(b, 65536)) {
    EXPECT_LE(k, 65536u);
    n += k;
    ++calls;
  }
  EXPECT_EQ(n, 518862u);
  EXPECT_EQ(calls, 8u);
  EXPECT_DOUBLE_EQ(b.positions[0].x, 515378.7675);
  EXPECT_DOUBLE_EQ(b.positions[0].y, 4918365.03475);
  EXPECT_DOUBLE_EQ(b.positions[0].z, 2324.30525);
  EXPECT_EQ(b.intensity[0], 956);
  EXPECT_EQ(b.flags[0], 0x40);  // scan direction
  EXPECT_EQ(b.return_number[0], 1);
  const size_t l = n - 1;
  EXPECT_DOUBLE_EQ(b.positions[l].x, 515398.052);
  EXPECT_DOUBLE_EQ(b.positions[l].y, 4918371.58875);
  EXPECT_DOUBLE_EQ(b.positions[l].z, 2325.831);
  EXPECT_EQ(b.intensity[l], 722);
  expect_within_header_bounds(b, h);
}

TEST(LasRead, GeographicEpsg4326) {
  REQUIRE_DATA("las/epsg_4326.las");
  LasReader r(file);
  const LasHeader& h = r.header();
  EXPECT_EQ(h.point_format, 0);
  EXPECT_TRUE(h.crs.geographic);
  EXPECT_EQ(h.crs.epsg, 4326);
  EXPECT_EQ(h.crs.name, "WGS 84");
  EXPECT_NE(h.crs.describe().find("EPSG:4326"), std::string::npos);
  const PointBatch b = read_all(r);
  ASSERT_EQ(b.size(), 5380u);
  EXPECT_TRUE(b.gps_time.empty() && b.rgb.empty());
  for (const glm::dvec3& p : b.positions) {
    ASSERT_TRUE(p.x >= -180 && p.x <= 180 && p.y >= -90 && p.y <= 90);
  }
  EXPECT_DOUBLE_EQ(b.positions[0].x, -94.6639387);
  EXPECT_DOUBLE_EQ(b.positions[0].y, 31.0367341);
  EXPECT_EQ(b.intensity[0], 65535);
}

namespace {

// Random values that every field of `format` can represent exactly.
PointBatch random_points(uint8_t format, size_t n, size_t extra, const glm::dvec3& scale,
                         const glm::dvec3& offset, uint32_t seed) {
  std::mt19937 rng(seed);
  auto u = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  const bool ext = format >= 6;
  PointBatch b;
  b.extra_bytes_per_point = extra;
  for (size_t i = 0; i < n; ++i) {
    b.positions.emplace_back(u(-2000000, 2000000) * scale.x + offset.x,
                             u(-2000000, 2000000) * scale.y + offset.y,
                             u(-100000, 100000) * scale.z + offset.z);
    b.intensity.push_back(static_cast<uint16_t>(u(0, 65535)));
    b.return_number.push_back(static_cast<uint8_t>(u(0, ext ? 15 : 7)));
    b.number_of_returns.push_back(static_cast<uint8_t>(u(0, ext ? 15 : 7)));
    const uint8_t cls = static_cast<uint8_t>(u(0, ext ? 255 : 31));
    b.classification.push_back(cls);
    if (ext) {
      b.flags.push_back(static_cast<uint8_t>(u(0, 255)));
      b.scan_angle.push_back(static_cast<float>(u(-30000, 30000) * 0.006));
    } else {
      uint8_t f = static_cast<uint8_t>(u(0, 255) & 0xc7);
      if (cls == 12) f |= 8;
      b.flags.push_back(f);
      b.scan_angle.push_back(static_cast<float>(u(-90, 90)));
    }
    b.user_data.push_back(static_cast<uint8_t>(u(0, 255)));
    b.point_source_id.push_back(static_cast<uint16_t>(u(0, 65535)));
    if (format == 1 || format >= 3)
      b.gps_time.push_back(std::uniform_real_distribution<>(0, 1e9)(rng));
    if (format == 2 || format == 3 || format == 5 || format == 7 || format == 8 || format == 10) {
      b.rgb.emplace_back(u(0, 65535), u(0, 65535), u(0, 65535));
    }
    if (format == 8 || format == 10) b.nir.push_back(static_cast<uint16_t>(u(0, 65535)));
    if (format == 4 || format == 5 || format == 9 || format == 10) {
      PointBatch::WavePacket w;
      w.descriptor_index = static_cast<uint8_t>(u(0, 255));
      w.data_offset = (uint64_t(u(0, 1 << 30)) << 20) | u(0, 1 << 20);
      w.data_size = static_cast<uint32_t>(u(0, 1 << 30));
      w.return_point_location = static_cast<float>(u(-1000, 1000)) * 0.25f;
      w.dx = 0.001f * u(-1000, 1000);
      w.dy = 0.002f * u(-1000, 1000);
      w.dz = 0.003f * u(-1000, 1000);
      b.wave_packets.push_back(w);
    }
    for (size_t k = 0; k < extra; ++k) b.extra_bytes.push_back(static_cast<uint8_t>(u(0, 255)));
  }
  return b;
}

std::vector<ExtraBytesDescriptor> two_attributes() {
  ExtraBytesDescriptor a, b;
  a.data_type = 3;  // uint16
  a.name = "amplitude";
  a.description = "test u16";
  a.options = 8;  // scale meaningful
  a.scale[0] = 0.5;
  b.data_type = 10;  // double
  b.name = "range";
  return {a, b};  // 2 + 8 = 10 bytes
}

void round_trip(uint8_t version_minor, uint8_t format, bool compress, bool extra) {
  SCOPED_TRACE(testing::Message() << "LAS 1." << int(version_minor) << " format " << int(format)
                                  << (compress ? " LAZ" : " LAS") << (extra ? " +extra" : ""));
  const fs::path path =
      temp_dir() / ("rt_" + std::to_string(version_minor) + "_" + std::to_string(format) +
                    (extra ? "_eb" : "") + (compress ? ".laz" : ".las"));
  LasWriteOptions o;
  o.version_minor = version_minor;
  o.point_format = format;
  o.scale = glm::dvec3(0.001, 0.002, 0.0005);
  o.offset = glm::dvec3(500000.0, 4000000.0, -50.0);
  o.compress = compress;
  o.wkt =
      "PROJCS[\"WGS 84 / UTM zone 32N\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS "
      "84\",6378137,298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]"
      "],PROJECTION[\"Transverse_Mercator\"],PARAMETER[\"latitude_of_origin\",0],PARAMETER["
      "\"central_meridian\",9],PARAMETER[\"scale_factor\",0.9996],PARAMETER[\"false_easting\","
      "500000],PARAMETER[\"false_northing\",0],UNIT[\"metre\",1],AUTHORITY[\"EPSG\",\"32632\"]]";
  if (extra) o.extra_bytes = two_attributes();
  const size_t eb = extra ? 10 : 0;
  const PointBatch in = random_points(format, 3000, eb, o.scale, o.offset, 1234 + format);
  {
    LasWriter w(path, o);
    w.write(in);
    EXPECT_EQ(w.points_written(), 3000u);
    w.close();
  }
  LasReader r(path);
  const LasHeader& h = r.header();
  EXPECT_EQ(h.version_minor, version_minor);
  EXPECT_EQ(h.point_format, format);
  EXPECT_EQ(h.compressed, compress);
  EXPECT_EQ(h.point_count, 3000u);
  EXPECT_EQ(h.extra_bytes_per_point, eb);
  EXPECT_EQ(h.crs.epsg, 32632);
  EXPECT_EQ(h.crs.linear_unit, "metre");
  if (version_minor >= 4) {
    EXPECT_TRUE(h.global_encoding & 16);
  }
  if (extra) {
    ASSERT_EQ(h.extra_bytes.size(), 2u);
    EXPECT_EQ(h.extra_bytes[0].name, "amplitude");
    EXPECT_EQ(h.extra_bytes[0].description, "test u16");
    EXPECT_EQ(h.extra_bytes[0].data_type, 3);
    EXPECT_EQ(h.extra_bytes[0].size, 2u);
    EXPECT_EQ(h.extra_bytes[0].scale[0], 0.5);
    EXPECT_EQ(h.extra_bytes[1].name, "range");
    EXPECT_EQ(h.extra_bytes[1].size, 8u);
  }
  const PointBatch out = read_all(r, 1000);
  expect_same(in, out);
  uint64_t by_return[15] = {};
  for (uint8_t rn : in.return_number) {
    if (rn) ++by_return[rn - 1];
  }
  for (int i = 0; i < (version_minor >= 4 ? 15 : 5); ++i) {
    EXPECT_EQ(h.points_by_return[i], by_return[i]) << i;
  }
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const glm::dvec3& p : in.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  EXPECT_EQ(h.min, lo);
  EXPECT_EQ(h.max, hi);
}

}  // namespace

TEST(LasWrite, RoundTripEveryFormatLas14) {
  for (uint8_t f = 0; f <= 10; ++f) {
    round_trip(4, f, false, false);
    round_trip(4, f, false, true);
  }
}

TEST(LasWrite, RoundTripLegacyFormats) {
  for (uint8_t f = 0; f <= 5; ++f) round_trip(2, f, false, f % 2 == 1);
  for (uint8_t f = 0; f <= 5; ++f) round_trip(3, f, false, false);
}

TEST(LasWrite, RoundTripLaz) {
  for (uint8_t f : {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10}) {
    round_trip(f >= 6 ? 4 : 2, f, true, false);
    round_trip(4, f, true, true);
  }
}

// LASzip reads an offset step after a wave packet of 2 GiB or more 4 GiB off (its encoder
// compares the step with the size as a signed 32-bit value), so LAZ refuses such a packet with
// an error naming the file and the point, and leaves no file; LAS stores it exactly.
TEST(LasWrite, LazRefusesWavePacketsItCannotStore) {
  for (uint8_t format : {4, 9}) {
    LasWriteOptions o;
    o.version_minor = 4;
    o.point_format = format;
    PointBatch b = random_points(format, 10, 0, o.scale, o.offset, 5);
    b.wave_packets[6].data_size = 0xfffffff0u;
    b.wave_packets[7].data_offset = b.wave_packets[6].data_offset - 16;
    const fs::path las = temp_dir() / "big_wave.las";
    {
      LasWriter w(las, o);
      w.write(b);
      w.close();
    }
    LasReader r(las);
    const PointBatch back = read_all(r, 100);
    ASSERT_EQ(back.wave_packets.size(), 10u);
    EXPECT_EQ(back.wave_packets[6].data_size, 0xfffffff0u);
    EXPECT_EQ(back.wave_packets[7].data_offset, b.wave_packets[7].data_offset);

    o.compress = true;
    const fs::path laz = temp_dir() / "big_wave.laz";
    fs::remove(laz);
    try {
      LasWriter w(laz, o);
      w.write(b);
      w.close();
      ADD_FAILURE() << "format " << int(format) << ": no error";
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("big_wave.laz"), std::string::npos) << what;
      EXPECT_NE(what.find("point 6"), std::string::npos) << what;
    }
    EXPECT_FALSE(fs::exists(laz));
  }
}

// Output appears only when complete: a writer unwound by an error leaves neither the file nor a
// temporary; until close() only the temporary exists.
TEST(LasWrite, AnErrorWhileWritingLeavesNoFile) {
  for (bool compress : {false, true}) {
    const fs::path dir = temp_dir() / (compress ? "interrupted-laz" : "interrupted-las");
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path path = dir / (compress ? "out.laz" : "out.las");
    LasWriteOptions o;
    o.point_format = 1;
    o.version_minor = 2;
    o.compress = compress;
    try {
      LasWriter w(path, o);
      w.write(random_points(1, 5000, 0, o.scale, o.offset, 11));
      EXPECT_FALSE(fs::exists(path)) << "visible before it is finished";
      throw std::runtime_error("the input failed");
    } catch (const std::runtime_error&) {
    }
    EXPECT_FALSE(fs::exists(path));
    EXPECT_TRUE(fs::is_empty(dir)) << "a temporary was left in " << dir;
    {
      LasWriter w(path, o);
      w.write(random_points(1, 5000, 0, o.scale, o.offset, 11));
    }
    EXPECT_EQ(LasReader(path).header().point_count, 5000u);
    fs::remove_all(dir);
  }
}

TEST(LasWrite, RejectsBadOptions) {
  LasWriteOptions o;
  o.version_minor = 2;
  o.point_format = 6;
  EXPECT_THROW(LasWriter(temp_dir() / "bad.las", o), Error);
  o.version_minor = 4;
  o.point_format = 11;
  EXPECT_THROW(LasWriter(temp_dir() / "bad.las", o), Error);
  // A coordinate that does not fit 32 bits at this scale.
  o.point_format = 0;
  LasWriter w(temp_dir() / "bad.las", o);
  PointBatch b;
  b.positions.push_back({1e12, 0, 0});
  try {
    w.write(b);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("does not fit"), std::string::npos) << e.what();
  }
}

// ---- corrupt input ----------------------------------------------------------------------

namespace {

std::vector<uint8_t> valid_file_bytes(uint8_t version_minor, uint8_t format,
                                      bool compress = false) {
  const fs::path path = temp_dir() / ("valid_" + std::to_string(version_minor) + "_" +
                                      std::to_string(format) + (compress ? ".laz" : ".las"));
  LasWriteOptions o;
  o.version_minor = version_minor;
  o.point_format = format;
  o.compress = compress;
  o.wkt =
      "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
      "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433],AUTHORITY[\"EPSG\",\"4326\"]]";
  {
    LasWriter w(path, o);
    w.write(random_points(format, compress ? 120000 : 100, 0, o.scale, o.offset, 7));
  }
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)), {});
}

template <typename T>
void put(std::vector<uint8_t>& b, size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof v);
}

// Writes bytes to a file named `name`, opens and reads it fully, and expects an Error naming
// the file and containing `phrase`. The same bytes must also fail in memory.
void expect_error(const std::string& name, const std::vector<uint8_t>& bytes,
                  const std::string& phrase) {
  SCOPED_TRACE(name);
  const fs::path path = temp_dir() / name;
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  }
  auto check = [&](auto&& open) {
    try {
      auto reader = open();
      PointBatch b;
      while (reader.read(b, 50000) > 0) b.clear();
      ADD_FAILURE() << "no error for " << name;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(name), std::string::npos) << what;
      EXPECT_NE(what.find(phrase), std::string::npos) << what;
    }
  };
  check([&] { return LasReader(path); });
  check([&] { return LasReader(bytes, name); });
}

}  // namespace

TEST(LasCorrupt, HeaderProblems) {
  const std::vector<uint8_t> good = valid_file_bytes(2, 3);
  std::vector<uint8_t> b;

  b = good;
  std::memcpy(b.data(), "LASX", 4);
  expect_error("signature.las", b, "not a LAS file");
  expect_error("empty.las", {}, "not a LAS file");

  b.assign(good.begin(), good.begin() + 100);
  expect_error("short.las", b, "truncated header");

  b = good;
  put<uint16_t>(b, 94, 200);
  expect_error("header_size.las", b, "header size 200 is smaller than LAS 1.2 needs");

  b = good;
  put<uint32_t>(b, 96, static_cast<uint32_t>(good.size() + 10));
  expect_error("offset_beyond.las", b, "beyond the end of the file");

  b = good;
  put<uint32_t>(b, 96, 100);
  expect_error("offset_inside.las", b, "lies inside the header");

  b = good;
  put<uint32_t>(b, 107, 1000000);
  expect_error("count.las", b, "the file holds only 100");

  b = good;
  put<uint16_t>(b, 105, 20);
  expect_error("record_length.las", b, "point record length 20 is smaller than point format 3");

  b = good;
  b[104] = 11;
  expect_error("format.las", b, "unknown point format 11");

  b = good;
  b[25] = 7;
  expect_error("version.las", b, "unsupported LAS version 1.7");

  b = good;
  put<double>(b, 131, 0.0);
  expect_error("scale.las", b, "invalid scale");

  b = good;
  b[104] = 0x83;  // compressed bit without a LASzip VLR
  expect_error("fake_laz.las", b, "no LASzip VLR");
}

TEST(LasCorrupt, VlrProblems) {
  const std::vector<uint8_t> good = valid_file_bytes(2, 3);
  std::vector<uint8_t> b = good;
  put<uint16_t>(b, 227 + 20, 60000);  // first VLR's record length
  expect_error("vlr_length.las", b, "runs past the offset to point data");

  b = good;
  put<uint32_t>(b, 100, 4000000000u);
  expect_error("vlr_count.las", b, "VLRs cannot fit");
}

TEST(LasCorrupt, Las14Problems) {
  const std::vector<uint8_t> good = valid_file_bytes(4, 6);
  std::vector<uint8_t> b = good;
  put<uint64_t>(b, 247, 1ull << 50);
  expect_error("absurd_count.las", b, "absurd point count");

  b = good;
  put<uint64_t>(b, 247, 5000);
  expect_error("count64.las", b, "the file holds only 100");

  b = good;
  put<uint64_t>(b, 235, good.size() + 1000);
  put<uint32_t>(b, 243, 1);
  expect_error("evlr_offset.las", b, "EVLR offset");

  b = good;
  put<uint64_t>(b, 235, good.size() - 70);
  put<uint32_t>(b, 243, 1);
  expect_error("evlr_length.las", b, "runs past the end of the file");

  b = good;
  put<uint64_t>(b, 235, good.size() - 600);
  put<uint32_t>(b, 243, 1000000);
  expect_error("evlr_count.las", b, "absurd EVLR count");

  b = good;
  put<uint16_t>(b, 94, 300);
  expect_error("header14.las", b, "smaller than LAS 1.4 needs (375)");
}

TEST(LasCorrupt, LazProblems) {
  const std::vector<uint8_t> good = valid_file_bytes(2, 3, true);
  const uint32_t offset = [&] {
    uint32_t v;
    std::memcpy(&v, good.data() + 96, 4);
    return v;
  }();
  // Truncated compressed data: the chunk table is gone.
  std::vector<uint8_t> b(good.begin(), good.begin() + good.size() / 2);
  expect_error("truncated.laz", b, "LAZ");

  // Chunk table offset pointing outside the file.
  b = good;
  put<int64_t>(b, offset, static_cast<int64_t>(good.size()) * 4);
  expect_error("chunk_table.laz", b, "corrupt LAZ chunk table");
}

TEST(LasCorrupt, FileShrinksWhileReading) {
  // Large enough that stdio buffering cannot hide the truncation.
  const fs::path path = temp_dir() / "shrinking.las";
  LasWriteOptions o;
  o.version_minor = 2;
  o.point_format = 1;
  {
    LasWriter w(path, o);
    w.write(random_points(1, 50000, 0, o.scale, o.offset, 3));
  }
  LasReader r(path);
  fs::resize_file(path, fs::file_size(path) / 2);
  PointBatch b;
  try {
    while (r.read(b, 3000) > 0) {
    }
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("shrinking.las: file ends early while reading points"),
              std::string::npos)
        << e.what();
  }
}

TEST(LasCorrupt, MissingFile) {
  try {
    LasReader r(temp_dir() / "nope.las");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nope.las: cannot open"), std::string::npos) << e.what();
  }
  EXPECT_THROW(read_las_header(temp_dir()), Error);
}

// seek(i) then read gives exactly the points a sequential read gives from i on, for LAS and LAZ
// (LASzip restarts at the chunk holding i), in any order of seeks; seeking past the end fails.
// read_positions (the tiler's counting pass) gives the same positions, appended to what the
// vector holds.
TEST(LasRead, SeekThenReadMatchesSequentialReading) {
  REQUIRE_DATA("las/autzen_trim.las");
  std::vector<fs::path> files = {file};
  if (fs::exists(data_dir() / "laz/autzen_trim.laz"))
    files.push_back(data_dir() / "laz/autzen_trim.laz");
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.string());
    LasReader all(f);
    const PointBatch whole = read_all(all, 1 << 16);
    LasReader r(f), positions_reader(f);
    for (uint64_t first : {uint64_t(70001), uint64_t(0), uint64_t(50000), uint64_t(109999),
                           uint64_t(123), uint64_t(110000)}) {
      r.seek(first);
      PointBatch b;
      const size_t got = r.read(b, 3000);
      ASSERT_EQ(got, std::min<uint64_t>(3000, 110000 - first));
      positions_reader.seek(first);
      std::vector<glm::dvec3> positions = {glm::dvec3(-1)};
      ASSERT_EQ(positions_reader.read_positions(positions, 3000), got);
      ASSERT_EQ(positions.size(), got + 1);
      EXPECT_EQ(positions[0], glm::dvec3(-1));
      EXPECT_EQ(positions_reader.points_read(), first + got);
      for (size_t i = 0; i < got; ++i) {
        ASSERT_EQ(b.positions[i], whole.positions[first + i]) << "point " << first + i;
        ASSERT_EQ(positions[i + 1], whole.positions[first + i]) << "point " << first + i;
        ASSERT_EQ(b.gps_time[i], whole.gps_time[first + i]);
        ASSERT_EQ(b.rgb[i], whole.rgb[first + i]);
        ASSERT_EQ(b.intensity[i], whole.intensity[first + i]);
      }
    }
    EXPECT_THROW(r.seek(110001), Error);
  }
}

// read_drawn (the pointlet cache's reader) gives the fields read() gives, field by field, for the
// legacy record layouts (returns and class in two bytes) and formats 6-10 (three), with and
// without RGB, LAS and LAZ, in pieces of any size.
TEST(LasRead, DrawnFieldsAreThoseOfTheFullRead) {
  stipple::test::LasFile legacy, extended;
  legacy.point_format = 1;  // no RGB
  extended.version_minor = 4;
  extended.point_format = 7;
  for (stipple::test::LasFile* f : {&legacy, &extended}) {
    f->points = stipple::test::grid_points(300, 100.0, 200.0, 50.0);
    for (size_t i = 0; i < f->points.size(); ++i) {
      auto& p = f->points[i];
      p.intensity = uint16_t(i * 211);
      p.classification = uint8_t(i % 19);
      p.r = uint16_t(i * 97), p.g = uint16_t(65535 - i), p.b = uint16_t(i * 13);
    }
  }
  struct Input {
    std::string name;
    std::vector<uint8_t> bytes;
  };
  std::vector<Input> inputs = {{"legacy.las", stipple::test::las_bytes(legacy)},
                               {"extended.las", stipple::test::las_bytes(extended)}};
  for (const char* rel : {"las/autzen_trim.las", "las/test1_4.las", "las/1.2-with-color.las",
                          "laz/autzen_trim.laz", "laz/simple.laz"}) {
    const fs::path f = data_dir() / rel;
    if (data_dir().empty() || !fs::exists(f)) continue;  // the generated layouts still run
    std::ifstream in(f, std::ios::binary);
    inputs.push_back({f.string(), std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {})});
  }
  for (const Input& input : inputs) {
    SCOPED_TRACE(input.name);
    LasReader full(input.bytes, input.name), drawn_reader(input.bytes, input.name);
    const PointBatch all = read_all(full, 1000);
    ASSERT_GT(all.size(), 0u);
    std::vector<DrawnPoint> drawn(777);
    size_t at = 0;
    for (size_t n; (n = drawn_reader.read_drawn(drawn)) > 0; at += n) {
      for (size_t i = 0; i < n; ++i) {
        const DrawnPoint& d = drawn[i];
        const size_t k = at + i;
        ASSERT_LT(k, all.size());
        ASSERT_EQ(d.position, all.positions[k]) << "point " << k;
        ASSERT_EQ(d.intensity, all.intensity[k]) << "point " << k;
        ASSERT_EQ(d.classification, all.classification[k]) << "point " << k;
        ASSERT_EQ(d.return_number, all.return_number[k]) << "point " << k;
        ASSERT_EQ(d.number_of_returns, all.number_of_returns[k]) << "point " << k;
        ASSERT_EQ(d.rgb, all.rgb.empty() ? glm::u16vec3(0) : all.rgb[k]) << "point " << k;
      }
    }
    EXPECT_EQ(at, all.size());
  }
}

// Writers that add attributes one at a time write one Extra Bytes VLR per attribute: all of
// them together describe the record (a uint16, then a uint8: 3 bytes).
TEST(LasRead, SeveralExtraBytesVlrsDescribeTheRecordTogether) {
  stipple::test::LasFile f;
  f.version_minor = 4;
  f.point_format = 6;
  f.extra_bytes_per_point = 3;
  f.vlrs.push_back({"LASF_Spec", 4, stipple::test::extra_bytes_descriptor(3, "amplitude"), ""});
  f.vlrs.push_back({"LASF_Spec", 4, stipple::test::extra_bytes_descriptor(1, "flags"), ""});
  f.points = stipple::test::grid_points(10, 0.0, 0.0, 1.0);
  for (size_t i = 0; i < f.points.size(); ++i) f.points[i].extra = {uint8_t(i), 1, uint8_t(7 * i)};
  const std::vector<uint8_t> bytes = stipple::test::las_bytes(f);
  LasReader reader(bytes, "two-extra-bytes-vlrs.las");
  const LasHeader& h = reader.header();
  ASSERT_EQ(h.extra_bytes.size(), 2u);
  EXPECT_EQ(h.extra_bytes[0].name, "amplitude");
  EXPECT_EQ(h.extra_bytes[0].size, 2u);
  EXPECT_EQ(h.extra_bytes[1].name, "flags");
  EXPECT_EQ(h.extra_bytes[1].size, 1u);
  EXPECT_EQ(h.extra_bytes_per_point, 3u);
  const PointBatch b = read_all(reader);
  ASSERT_EQ(b.extra_bytes.size(), 30u);
  for (size_t i = 0; i < 10; ++i) {
    EXPECT_EQ(b.extra_bytes[i * 3] | (b.extra_bytes[i * 3 + 1] << 8), int(i) + 256);
    EXPECT_EQ(b.extra_bytes[i * 3 + 2], uint8_t(7 * i));
  }
}

// WKT from the file is untrusted text: broken brackets, unterminated quotes and deep nesting
// leave the CRS without a code, never crash or hang; a readable one still names its code.
TEST(LasRead, CrsFromMalformedWktIsBestEffort) {
  const std::vector<std::string> texts = {
      "PROJCS[\"x\",AUTHORITY[\"EPSG\",\"32633\"]",        // unclosed
      "PROJCS[\"unterminated,AUTHORITY[\"EPSG\",\"1\"]]",  // a quote never closed
      std::string(100000, '[') + std::string(100000, ']'),
      "PROJCS(\"paren style\",UNIT(\"metre\",1),AUTHORITY(\"EPSG\",\"32633\"))",
      "]]]]",
      "PROJCS[\"x\",UNIT[\"metre\",1)]",  // a bracket closed by the wrong kind (fuzz_las OOM)
  };
  for (size_t i = 0; i < texts.size(); ++i) {
    SCOPED_TRACE(i);
    stipple::test::LasFile f;
    f.version_minor = 4;
    f.point_format = 6;
    f.global_encoding = 16;
    std::vector<uint8_t> wkt(texts[i].begin(), texts[i].end());
    wkt.resize(std::min<size_t>(wkt.size(), 65000));
    f.vlrs.push_back({"LASF_Projection", 2112, wkt, ""});
    f.points = stipple::test::grid_points(4, 0.0, 0.0, 1.0);
    const std::vector<uint8_t> bytes = stipple::test::las_bytes(f);
    LasReader reader(bytes, "wkt.las");
    if (i == 3) {
      EXPECT_EQ(reader.header().crs.epsg, 32633);
      EXPECT_EQ(reader.header().crs.linear_unit, "metre");
    }
    EXPECT_EQ(reader.header().crs.source, Crs::Source::Wkt);
  }
}

// drawn_fields_only (the pointlet cache's reads): LAZ of formats 6-10 gives the drawn fields
// exactly and the undecoded layers' fields as zeros; other formats decode whole.
TEST(LasRead, DrawnFieldsOnlySkipsTheOtherLayers) {
  for (uint8_t format : {3, 7}) {
    SCOPED_TRACE(testing::Message() << "format " << int(format));
    const glm::dvec3 scale(0.01), offset(1000.0, 2000.0, 0.0);
    const PointBatch in = random_points(format, 5000, 0, scale, offset, 7u + format);
    LasWriteOptions o;
    o.version_minor = 4;
    o.point_format = format;
    o.scale = scale;
    o.offset = offset;
    o.compress = true;
    const fs::path path = temp_dir() / ("drawn_" + std::to_string(format) + ".laz");
    {
      LasWriter w(path, o);
      w.write(in);
      w.close();
    }
    LasReader reader(path, true);
    const PointBatch out = read_all(reader, 777);
    ASSERT_EQ(out.size(), in.size());
    bool zeros = true, same_extras = true;
    for (size_t i = 0; i < in.size(); ++i) {
      ASSERT_EQ(out.positions[i], in.positions[i]) << i;
      ASSERT_EQ(out.intensity[i], in.intensity[i]) << i;
      ASSERT_EQ(out.classification[i], in.classification[i]) << i;
      ASSERT_EQ(out.return_number[i], in.return_number[i]) << i;
      ASSERT_EQ(out.number_of_returns[i], in.number_of_returns[i]) << i;
      ASSERT_EQ(out.rgb[i], in.rgb[i]) << i;
      zeros =
          zeros && out.gps_time[i] == 0.0 && out.point_source_id[i] == 0 && out.user_data[i] == 0;
      same_extras = same_extras && out.gps_time[i] == in.gps_time[i] &&
                    out.point_source_id[i] == in.point_source_id[i];
    }
    if (format >= 6)
      EXPECT_TRUE(zeros) << "GPS time, point source and user data are not decoded";
    else
      EXPECT_TRUE(same_extras) << "formats without layers decode whole";
  }
}
