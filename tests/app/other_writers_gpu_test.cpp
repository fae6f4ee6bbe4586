// Files with the properties that files from other writers showed (issue 21): each test writes
// its input with the property named, runs `stipple`, and checks the image, the exit status or
// the printed text.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "las_bytes.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir() {
  fs::path dir =
      fs::temp_directory_path() / ("stipple-writers-" + std::to_string(::getpid()) + "-" +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

const uint8_t kBackground[3] = {18, 20, 26};  // render's default (0.07, 0.08, 0.1)

// Where an image differs from the background: pixel count and bounding box.
struct Covered {
  size_t pixels = 0;
  uint32_t x0 = ~0u, y0 = ~0u, x1 = 0, y1 = 0;
  double cx() const { return 0.5 * (x0 + x1); }
  double cy() const { return 0.5 * (y0 + y1); }
};

Covered covered(const gpu::Image& image, int tolerance = 2) {
  Covered c;
  for (uint32_t y = 0; y < image.height; ++y)
    for (uint32_t x = 0; x < image.width; ++x) {
      const uint8_t* p = &image.rgba[(size_t(y) * image.width + x) * 4];
      bool bg = true;
      for (int k = 0; k < 3; ++k) bg = bg && std::abs(p[k] - kBackground[k]) <= tolerance;
      if (bg) continue;
      ++c.pixels;
      c.x0 = std::min(c.x0, x), c.y0 = std::min(c.y0, y);
      c.x1 = std::max(c.x1, x), c.y1 = std::max(c.y1, y);
    }
  return c;
}

}  // namespace

// Item 1: zero extent (one point, or every point at one location) used to give a blank image
// reported as a success; it is framed as a few metres around the location now, and drawn.
TEST(OtherWriters, ZeroExtentCloudIsFramedAndDrawn) {
  const fs::path dir = temp_dir();
  for (size_t n : {size_t(1), size_t(500)}) {
    test::LasFile f;
    f.point_format = 2;
    f.scale = {0.001, 0.001, 0.001};
    for (size_t i = 0; i < n; ++i) {
      test::LasPoint p;
      p.x = 512345.678, p.y = 5123456.789, p.z = 321.5;
      p.r = 65535;  // red
      f.points.push_back(p);
    }
    const fs::path las = dir / fmt::format("at-one-place-{}.las", n);
    const fs::path png = dir / fmt::format("at-one-place-{}.png", n);
    test::write_las(las, f);
    auto r = test::run_stipple(
        fmt::format("render {} -o {} --width 160 --height 100", las.string(), png.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(fmt::format("rendered {} points", n)), std::string::npos) << r.output;
    const gpu::Image image = gpu::read_png(png);
    const Covered c = covered(image);
    // A point marker of several pixels, red, in the middle of the image.
    EXPECT_GE(c.pixels, 9u) << n;
    EXPECT_LT(c.pixels, 400u) << n;
    EXPECT_NEAR(c.cx(), 80.0, 16.0) << n;
    EXPECT_NEAR(c.cy(), 50.0, 10.0) << n;
    const auto stats = test::coverage_stats(image, kBackground);
    EXPECT_GT(stats.mean[0], 2.0 * stats.mean[1]) << n;
  }
}
