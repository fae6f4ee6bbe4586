// The compute rasterizer over streamed data (`stipple render --renderer compute` of a tileset
// and of a COPC file): every resident tile or node is a run of LOD batches, and the image agrees
// with the billboard path's drawn the plain way (1-pixel points, nearest wins, no EDL, black
// background) in RGB and in the colour modes the compute path colours on its workers.
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
                        const std::string& tag) {
  const std::string common =
      " --width 480 --height 270 --point-size 1 --splat naive --no-edl --background 0,0,0 "
      "--max-sse 0.000001" +
      extra;
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
  for (const char* mode : {"elevation", "classification", "return", "constant"})
    expect_paths_agree(copc.string(), std::string(" --color ") + mode, dir,
                       std::string("copc_") + mode);
  // Intensity: the compute path needs the ramp's range (it colours tiles as they load).
  expect_paths_agree(copc.string(), " --color intensity --intensity-range 175,2062", dir,
                     "copc_intensity");
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
  expect_paths_agree(tileset, " --color elevation", dir, "tiles_elevation");
  fs::remove_all(dir);
}
