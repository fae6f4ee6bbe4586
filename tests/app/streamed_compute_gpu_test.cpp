// The compute rasterizer over streamed data (`stipple render --renderer compute` of a tileset
// and of a COPC file): every resident tile or node is a run of LOD batches, and the image agrees
// with the billboard path's drawn the plain way (1-pixel points, nearest wins, no EDL, black
// background) in RGB and in every colour mode.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

const uint8_t kBlack[3] = {0, 0, 0};

// Renders `input` both ways with `extra` options and compares. Tolerances: coverage within 2 %
// and mean colour within 2 levels per channel (measured on lavapipe: under 0.5 % and 0.5
// levels); they differ only in which of several points in a pixel wins.
void expect_paths_agree(const std::string& input, const std::string& extra, const fs::path& dir,
                        const std::string& tag, bool edl = false) {
  const std::string common =
      std::string(
          " --width 480 --height 270 --point-size 1 --splat naive --background 0,0,0 "
          "--max-sse 0.000001") +
      (edl ? "" : " --no-edl") + extra;
  const fs::path a = dir / (tag + "_billboard.png"), b = dir / (tag + "_compute.png");
  auto r = test::run_stipple("render " + input + " -o " + a.string() + common);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto r2 = test::run_stipple("render " + input + " --renderer compute -o " + b.string() + common);
  ASSERT_EQ(r2.exit_code, 0) << r2.output;
  // Both draw every point of the file.
  const auto drawn = [](const std::string& out) {
    const size_t at = out.find("rendered ");
    return at == std::string::npos ? std::string() : out.substr(at, out.find(" points", at) - at);
  };
  EXPECT_EQ(drawn(r.output), drawn(r2.output)) << r.output << r2.output;
  auto sa = test::coverage_stats(gpu::read_png(a), kBlack, 0);
  auto sb = test::coverage_stats(gpu::read_png(b), kBlack, 0);
  std::printf("%s: coverage %.4f vs %.4f, mean (%.1f %.1f %.1f) vs (%.1f %.1f %.1f)\n", tag.c_str(),
              sa.coverage, sb.coverage, sa.mean[0], sa.mean[1], sa.mean[2], sb.mean[0], sb.mean[1],
              sb.mean[2]);
  EXPECT_GT(sa.coverage, 0.02) << tag;
  EXPECT_NEAR(sb.coverage / sa.coverage, 1.0, 0.02) << tag;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sb.mean[c], sa.mean[c], 2.0) << tag << " channel " << c;
}

}  // namespace

TEST(StreamedCompute, CopcRendersLikeTheBillboardPath) {
  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  fs::path dir =
      fs::temp_directory_path() / ("stipple_streamed_compute_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // Every colour mode, intensity included without a range: both paths take the ramp's range
  // from the percentiles of the resident nodes' samples, and shade on the GPU.
  for (const char* mode : {"elevation", "intensity", "classification", "return", "constant"})
    expect_paths_agree(copc.string(), std::string(" --color ") + mode, dir,
                       std::string("copc_") + mode);
  fs::remove_all(dir);
}

TEST(StreamedCompute, TilesetRendersLikeTheBillboardPath) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  fs::path dir =
      fs::temp_directory_path() / ("stipple_streamed_tiles_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  auto r = test::run_stipple("tile " + las.string() + " -o " + (dir / "tiles").string() +
                             " --spacing 100 --max-node-points 20000");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string tileset = (dir / "tiles" / "tileset.json").string();
  expect_paths_agree(tileset, " --color rgb", dir, "tiles_rgb");
  for (const char* mode : {"elevation", "intensity", "classification"})
    expect_paths_agree(tileset, std::string(" --color ") + mode, dir, std::string("tiles_") + mode);
  fs::remove_all(dir);
}

// Eye-dome lighting (the same equations and flags on both paths) on a tileset and a COPC stream.
TEST(StreamedCompute, EyeDomeLightingMatchesTheBillboardPath) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  fs::path dir = fs::temp_directory_path() / ("stipple_streamed_edl_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  auto r = test::run_stipple("tile " + las.string() + " -o " + (dir / "tiles").string() +
                             " --spacing 100 --max-node-points 20000");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  expect_paths_agree((dir / "tiles" / "tileset.json").string(), " --color rgb", dir, "tiles_edl",
                     true);
  expect_paths_agree(copc.string(), " --color elevation", dir, "copc_edl", true);
  fs::remove_all(dir);
}

// HQS and hole filling on a tileset, against the same tileset drawn plainly on the compute path:
// HQS averages the points near the nearest depth (the covered pixels stay the same, the mean
// colour within 3 levels: measured 0.4), and hole filling only adds pixels (none of the plain
// image's covered pixels is emptied, and more are covered).
TEST(StreamedCompute, TilesetTakesHqsAndHoleFilling) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  fs::path dir =
      fs::temp_directory_path() / ("stipple_streamed_pipeline_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  auto r = test::run_stipple("tile " + las.string() + " -o " + (dir / "tiles").string() +
                             " --spacing 100 --max-node-points 20000");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string tileset = (dir / "tiles" / "tileset.json").string();
  const std::string common =
      " --renderer compute --width 480 --height 270 --background 0,0,0 --max-sse 0.000001 "
      "--color rgb --point-size 1 --no-edl";
  auto draw = [&](const std::string& tag, const std::string& extra) {
    const fs::path out = dir / (tag + ".png");
    auto rr = test::run_stipple("render " + tileset + " -o " + out.string() + common + extra);
    EXPECT_EQ(rr.exit_code, 0) << rr.output;
    return gpu::read_png(out);
  };
  const auto plain = draw("plain", ""), hqs = draw("hqs", " --hqs"),
             filled = draw("fill", " --fill-radius 3");
  const auto sp = test::coverage_stats(plain, kBlack, 0), sh = test::coverage_stats(hqs, kBlack, 0),
             sf = test::coverage_stats(filled, kBlack, 0);
  std::printf(
      "coverage plain %.4f hqs %.4f fill %.4f; mean plain (%.1f %.1f %.1f) hqs (%.1f %.1f "
      "%.1f)\n",
      sp.coverage, sh.coverage, sf.coverage, sp.mean[0], sp.mean[1], sp.mean[2], sh.mean[0],
      sh.mean[1], sh.mean[2]);
  ASSERT_GT(sp.coverage, 0.02);
  EXPECT_NEAR(sh.coverage / sp.coverage, 1.0, 0.01);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sh.mean[c], sp.mean[c], 3.0) << c;
  EXPECT_GT(sf.coverage, sp.coverage * 1.01);
  size_t emptied = 0;
  for (size_t i = 0; i + 3 < plain.rgba.size(); i += 4) {
    const bool a = plain.rgba[i] | plain.rgba[i + 1] | plain.rgba[i + 2];
    const bool b = filled.rgba[i] | filled.rgba[i + 1] | filled.rgba[i + 2];
    if (a && !b) ++emptied;
  }
  EXPECT_EQ(emptied, 0u);
  fs::remove_all(dir);
}
