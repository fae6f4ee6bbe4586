// `stipple view` in a virtual X server (xvfb-run): the window renders the data through the
// surface, the UI panel is drawn over it, and --frames/--screenshot end the run with a PNG.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "stipple/io/las.hpp"
#include "stipple/io/point_batch.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

class View : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(View, WindowShowsAutzenWithThePanel) {
  STIPPLE_REQUIRE_DATA(path, "laz/autzen_trim.laz");
  if (test::run_command("command -v xvfb-run").exit_code != 0)
    GTEST_SKIP() << "xvfb-run is not installed";
  fs::path dir =
      fs::temp_directory_path() / fmt::format("stipple_view_{}_{}", GetParam(), ::getpid());
  fs::create_directories(dir);
  auto view = [&](const std::string& name, const std::string& extra) {
    return test::run_command(
        fmt::format("xvfb-run -a -s '-screen 0 1600x900x24' {} view {} --backend {} --frames 60 "
                    "--screenshot {} {}",
                    STIPPLE_BINARY, path.string(), GetParam(), (dir / name).string(), extra));
  };
  test::CommandResult plain = view("plain.png", "--no-ui");
  if (plain.exit_code != 0 && plain.output.find("cannot open a window") != std::string::npos)
    GTEST_SKIP() << "no X display could be made: " << plain.output;
  ASSERT_EQ(plain.exit_code, 0) << plain.output;
  test::CommandResult with_ui = view("ui.png", "");
  ASSERT_EQ(with_ui.exit_code, 0) << with_ui.output;

  gpu::Image image = gpu::read_png(dir / "plain.png");
  ASSERT_EQ(image.width, 1280u);
  ASSERT_EQ(image.height, 720u);
  // The data's own mean colour (8-bit values stored in 16-bit fields).
  size_t colored = 0;
  const auto data_mean = test::mean_rgb(path, &colored);
  ASSERT_EQ(colored, 110000u);
  const uint8_t bg[3] = {18, 20, 26};  // the default background 0.07, 0.08, 0.1
  auto stats = test::coverage_stats(image, bg, 1);
  EXPECT_GT(stats.coverage, 0.10);
  EXPECT_LT(stats.coverage, 0.5);
  // Within 10 levels of the data's mean per channel. The window shows the surfaces in front
  // (the canopy over the ground) with eye-dome shading, some 7 levels darker than the mean of
  // every point when framed from the bounding box and 8.3 since the data fills the window
  // (item 11 of issue 21): the headless test's 8 leaves no room for that.
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(stats.mean[c], data_mean[c], 10.0) << "channel " << c;

  // With the panel: the same picture, plus the panel in the top-left corner.
  gpu::Image ui = gpu::read_png(dir / "ui.png");
  ASSERT_EQ(ui.width, image.width);
  ASSERT_EQ(ui.height, image.height);
  size_t panel_diff = 0, panel_pixels = 0, outside_diff = 0;
  for (uint32_t y = 0; y < image.height; ++y)
    for (uint32_t x = 0; x < image.width; ++x) {
      size_t i = (size_t(y) * image.width + x) * 4;
      bool differs = false;
      for (int c = 0; c < 3; ++c) differs |= std::abs(image.rgba[i + c] - ui.rgba[i + c]) > 1;
      bool in_panel = x >= 20 && x < 200 && y >= 20 && y < 120;  // inside any panel layout
      panel_pixels += in_panel;
      panel_diff += in_panel && differs;
      outside_diff += (x >= 500 || y >= 520) && differs;
    }
  EXPECT_GT(double(panel_diff) / double(panel_pixels), 0.3);
  EXPECT_EQ(outside_diff, 0u);
  fs::remove_all(dir);
}

// The viewer over the virtualized path (seed 002): the window shows autzen from its pointlet
// cache, with the panel's virtualized section.
TEST_P(View, VirtualizedAutzenWithThePanel) {
  STIPPLE_REQUIRE_DATA(path, "laz/autzen_trim.laz");
  if (test::run_command("command -v xvfb-run").exit_code != 0)
    GTEST_SKIP() << "xvfb-run is not installed";
  fs::path dir =
      fs::temp_directory_path() / fmt::format("stipple_view_virtual_{}_{}", GetParam(), ::getpid());
  fs::create_directories(dir);
  auto r = test::run_command(fmt::format(
      "xvfb-run -a -s '-screen 0 1600x900x24' {} view {} --backend {} --frames 30 --virtual "
      "--pointlets 1000 --cache {} --screenshot {}",
      STIPPLE_BINARY, path.string(), GetParam(), (dir / "cache").string(),
      (dir / "virtual.png").string()));
  if (r.exit_code != 0 && r.output.find("cannot open a window") != std::string::npos)
    GTEST_SKIP() << "no X display could be made: " << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("drawing from a pointlet cache (--virtual)"), std::string::npos)
      << r.output;
  gpu::Image shot = gpu::read_png(dir / "virtual.png");
  ASSERT_EQ(shot.width, 1280u);
  // Right of the panel (which shows the virtualized section: x < 400).
  gpu::Image image{shot.width - 400, shot.height, {}};
  for (uint32_t y = 0; y < shot.height; ++y)
    image.rgba.insert(image.rgba.end(), shot.rgba.begin() + (size_t(y) * shot.width + 400) * 4,
                      shot.rgba.begin() + (size_t(y) + 1) * shot.width * 4);
  const uint8_t bg[3] = {18, 20, 26};
  // 1-pixel points with hole filling: autzen covers part of the window, in its own colours.
  size_t colored = 0;
  const auto data_mean = test::mean_rgb(path, &colored);
  auto stats = test::coverage_stats(image, bg, 1);
  EXPECT_GT(stats.coverage, 0.10);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(stats.mean[c], data_mean[c], 20.0) << "channel " << c;
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Backends, View, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });

// view --virtual over a LAS whose pointlet cache does not exist yet: the first frame is drawn at
// once from a sample read across the file while the cache builds in the background, and the run
// ends with the virtualized cloud (--frames counts from when it took over), framed as the
// sample was. A second run finds the cache current and opens it before the first frame, as
// without the sample.
TEST(ViewProgressive, SampleFirstThenTheCache) {
  if (test::run_command("command -v xvfb-run").exit_code != 0)
    GTEST_SKIP() << "xvfb-run is not installed";
  const fs::path dir =
      fs::temp_directory_path() / fmt::format("stipple_view_progressive_{}", ::getpid());
  fs::create_directories(dir);
  const std::string las = (dir / "g.las").string();
  ASSERT_EQ(test::run_stipple("generate -n 1000000 -o " + las).exit_code, 0);
  {
    // P at the first frame: a screenshot of what the window shows first.
    std::FILE* f = std::fopen((dir / "first.json").c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs(R"({"events": [{"frame": 0, "tap": "p"}]})", f);
    std::fclose(f);
  }
  auto view = [&](const std::string& shot, const std::string& extra) {
    return test::run_command(fmt::format(
        "cd {} && xvfb-run -a -s '-screen 0 1600x900x24' {} view {} --virtual --pointlets 1000 "
        "--no-ui --width 640 --height 360 --frames 20 --screenshot {} {}",
        dir.string(), STIPPLE_BINARY, las, (dir / shot).string(), extra));
  };
  test::CommandResult built = view("final.png", "--progressive-points 20000 --script first.json");
  if (built.exit_code != 0 && built.output.find("cannot open a window") != std::string::npos)
    GTEST_SKIP() << "no X display could be made: " << built.output;
  ASSERT_EQ(built.exit_code, 0) << built.output;
  EXPECT_NE(built.output.find("first image: 20000 points read across the input"), std::string::npos)
      << built.output;
  EXPECT_NE(built.output.find("building the pointlet cache in the background"), std::string::npos)
      << built.output;
  // The sample was drawn for at least one frame before the cache took over.
  const size_t at = built.output.find(" frames of the sample");
  ASSERT_NE(at, std::string::npos) << built.output;
  const size_t number = built.output.rfind("after ", at);
  ASSERT_NE(number, std::string::npos);
  EXPECT_GE(std::stoull(built.output.substr(number + 6, at - number - 6)), 1u) << built.output;

  const uint8_t bg[3] = {18, 20, 26};
  const gpu::Image first = gpu::read_png(dir / "stipple-screenshot-1.png");
  const gpu::Image last = gpu::read_png(dir / "final.png");
  ASSERT_EQ(first.width, 640u);
  ASSERT_EQ(last.width, 640u);
  const double first_coverage = test::coverage_stats(first, bg, 1).coverage;
  const double last_coverage = test::coverage_stats(last, bg, 1).coverage;
  EXPECT_GT(first_coverage, 0.05);
  EXPECT_GT(last_coverage, 0.05);
  // The last frame is the cache's million points, not the sample's 20,000.
  EXPECT_GT(test::differing_fraction(first, last, 2), 0.01);

  test::CommandResult reused = view("reused.png", "");
  ASSERT_EQ(reused.exit_code, 0) << reused.output;
  EXPECT_NE(reused.output.find("reused "), std::string::npos) << reused.output;
  EXPECT_EQ(reused.output.find("in the background"), std::string::npos) << reused.output;
  EXPECT_EQ(reused.output.find("first image:"), std::string::npos) << reused.output;
  // Framed from the sample, the switch keeps about the framing the cache's own fit gives.
  const double reused_coverage =
      test::coverage_stats(gpu::read_png(dir / "reused.png"), bg, 1).coverage;
  EXPECT_NEAR(last_coverage, reused_coverage, 0.25 * reused_coverage);
  fs::remove_all(dir);
}
