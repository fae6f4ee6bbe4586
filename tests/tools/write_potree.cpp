// Writes a Potree 2.0 cloud with the tests' writer (tests/common/potree_writer.hpp), for the
// potree-core test that proves that writer against Potree's own reader, for the web viewer's
// BROTLI nodes (web/compressed.test.mjs), and for bench/web_vs_potree.mjs, which has stipple's
// page and potree-core draw the same real cloud:
//   stipple_write_potree DIR POINTS [NODE_CAP STEP [no-int64|int64 [brotli]]]
//       the tests' synthetic points, every attribute type
//   stipple_write_potree DIR INPUT.las|laz [NODE_CAP STEP [brotli]]
//       a LAS/LAZ file's points (read with stipple's io module) with the attributes
//       PotreeConverter writes for LAS: position, intensity, returns, classification, scan
//       angle, user data, point source id, GPS time and RGB where the file has them (colour as
//       stored: Potree's readers take 8-bit values as they are); NODE_CAP 10000, STEP 3 unless
//       given
// Prints {"nodes", "chunks", "depth", "points", "min", "max"} (the points' bounds) as JSON.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "potree_brotli.hpp"
#include "potree_writer.hpp"
#include "stipple/io/las.hpp"
#include "stipple/io/point_batch.hpp"

namespace {

using stipple::test::PotreePoint;

bool all_digits(const std::string& s) {
  return !s.empty() &&
         std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

// Every point of a LAS/LAZ file, with the fields potree_las_attributes writes.
std::vector<PotreePoint> las_points(const std::string& path, stipple::io::LasHeader& header) {
  stipple::io::LasReader reader(path);
  header = reader.header();
  std::vector<PotreePoint> points;
  points.reserve(header.point_count);
  const bool extended = header.point_format >= 6;
  stipple::io::PointBatch b;
  for (;;) {
    b.clear();
    const size_t n = reader.read(b, 1 << 16);
    if (n == 0) break;
    for (size_t i = 0; i < n; ++i) {
      PotreePoint p{};
      p.x = b.positions[i].x, p.y = b.positions[i].y, p.z = b.positions[i].z;
      if (!b.rgb.empty()) p.r = b.rgb[i].x, p.g = b.rgb[i].y, p.b = b.rgb[i].z;
      if (!b.intensity.empty()) p.intensity = b.intensity[i];
      if (!b.classification.empty()) p.classification = b.classification[i];
      if (!b.return_number.empty()) p.return_number = b.return_number[i];
      if (!b.number_of_returns.empty()) p.number_of_returns = b.number_of_returns[i];
      if (!b.gps_time.empty()) p.gps_time = b.gps_time[i];
      // Back to what the record stores: a rank in degrees (0-5), 0.006-degree steps (6-10).
      if (!b.scan_angle.empty())
        p.scan_angle = int16_t(std::lround(extended ? b.scan_angle[i] / 0.006f : b.scan_angle[i]));
      if (!b.user_data.empty()) p.user_data = b.user_data[i];
      if (!b.point_source_id.empty()) p.point_source_id = b.point_source_id[i];
      points.push_back(p);
    }
  }
  return points;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: %s DIR POINTS [NODE_CAP STEP [no-int64|int64 [brotli]]]\n"
                 "       %s DIR INPUT.las|laz [NODE_CAP STEP [brotli]]\n",
                 argv[0], argv[0]);
    return 2;
  }
  try {
    const bool from_las = !all_digits(argv[2]);
    const size_t cap = argc > 3 ? std::stoul(argv[3]) : from_las ? 10000 : 500;
    const int step = argc > 4 ? std::stoi(argv[4]) : from_las ? 3 : 2;
    const int brotli_arg = from_las ? 5 : 6;
    const bool compress = argc > brotli_arg && std::string(argv[brotli_arg]) == "brotli";
    const auto brotli = compress ? stipple::test::potree_brotli : nullptr;
    std::vector<PotreePoint> points;
    stipple::test::PotreeWriteResult r;
    if (from_las) {
      stipple::io::LasHeader h;
      points = las_points(argv[2], h);
      if (points.empty()) throw std::runtime_error(std::string(argv[2]) + ": no points");
      // The file's own resolution (the finest of its axes' scales).
      const double scale = std::min({h.scale.x, h.scale.y, h.scale.z});
      const std::string name = std::filesystem::path(argv[2]).stem().string();
      r = stipple::test::write_potree_attributes(
          argv[1], points,
          stipple::test::potree_las_attributes(h.has_rgb, h.has_gps_time, h.point_format >= 6), cap,
          step, brotli, scale, name);
    } else {
      points = stipple::test::potree_points(std::stoul(argv[2]));
      r = stipple::test::write_potree(argv[1], points, cap, step,
                                      !(argc > 5 && std::string(argv[5]) == "no-int64"), brotli);
    }
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (const auto& p : points) {
      const double c[3] = {p.x, p.y, p.z};
      for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], c[k]), hi[k] = std::max(hi[k], c[k]);
    }
    std::printf(
        "{\"nodes\": %zu, \"chunks\": %zu, \"depth\": %d, \"points\": %zu, \"min\": [%.17g, %.17g, "
        "%.17g], \"max\": [%.17g, %.17g, %.17g]}\n",
        r.nodes, r.chunks, r.depth, points.size(), lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
    return 1;
  }
  return 0;
}
