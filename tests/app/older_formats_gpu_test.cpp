// Files older writers made that stipple reads as their viewers do (issue 44): a Potree 1.4 cloud
// (PotreeConverter before 1.5: its octree listed in cloud.js) and an EPT dataset of version 0.0.0
// in the 1.0 layout (early Entwine), each written by the tests' own writers, through `stipple
// info` and `stipple render`.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "ept_writer.hpp"
#include "potree1_writer.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"
#include "tiles_fixtures.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

const uint8_t kBackground[3] = {18, 20, 26};  // render's default (0.07, 0.08, 0.1)

// Pixels that differ from the background by more than 2 on some channel.
size_t drawn_pixels(const gpu::Image& image) {
  size_t n = 0;
  for (size_t i = 0; i < size_t(image.width) * image.height; ++i)
    for (int k = 0; k < 3; ++k)
      if (std::abs(int(image.rgba[i * 4 + k]) - kBackground[k]) > 2) {
        ++n;
        break;
      }
  return n;
}

}  // namespace

// A Potree 1.4 cloud: `info` sums the points its hierarchy list declares (complete, since the
// list is the whole octree), and `render` draws it, covering a good part of the image.
TEST(OlderFormats, Potree14CloudRendersAndInfoSumsItsPoints) {
  const fs::path dir = test::fresh_temp_dir("older-potree14");
  const auto points = test::potree_points(8000);
  test::write_potree1(dir, points, {"1.4", "BINARY", 400, 1});
  const std::string cloud = (dir / "cloud.js").string();
  auto r = test::run_command(std::string("{ ") + STIPPLE_BINARY + " info --json " + cloud +
                             " 2>/dev/null; }");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = nlohmann::json::parse(r.output, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r.output;
  EXPECT_EQ(j["version"], "Potree 1.4") << j.dump();
  EXPECT_EQ(j["points"].get<uint64_t>(), points.size()) << j.dump();
  EXPECT_TRUE(j["points_complete"].get<bool>()) << j.dump();
  EXPECT_TRUE(j["errors"].empty()) << j.dump();
  const fs::path png = dir / "potree14.png";
  r = test::run_stipple(
      fmt::format("render {} -o {} --width 160 --height 120", cloud, png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  const gpu::Image image = gpu::read_png(png);
  EXPECT_GT(drawn_pixels(image), size_t(image.width) * image.height / 10) << r.output;
  fs::remove_all(dir);
}

// EPT version 0.0.0 in the 1.0 layout renders, with one warning naming the version.
TEST(OlderFormats, Ept000RendersWithAWarning) {
  const fs::path dir = test::fresh_temp_dir("older-ept000");
  test::write_ept(dir, test::ept_points(6000), "binary", 400, 2);
  ASSERT_NE(test::set_ept_version(dir, "0.0.0").find("\"0.0.0\""), std::string::npos);
  const fs::path png = dir / "ept000.png";
  auto r = test::run_stipple(fmt::format("render {} -o {} --width 160 --height 120",
                                         (dir / "ept.json").string(), png.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  size_t warnings = 0;
  for (size_t p = r.output.find("'0.0.0'"); p != std::string::npos;
       p = r.output.find("'0.0.0'", p + 1))
    ++warnings;
  EXPECT_EQ(warnings, 1u) << r.output;
  const gpu::Image image = gpu::read_png(png);
  EXPECT_GT(drawn_pixels(image), size_t(image.width) * image.height / 10) << r.output;
  fs::remove_all(dir);
}
