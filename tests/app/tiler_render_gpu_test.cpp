// `stipple tile` end to end through the renderer: autzen_trim tiled to 3D Tiles, then the tileset
// (`stipple render DIR/tileset.json`) and the LAS itself (`stipple render autzen_trim.las`)
// rendered from the same azimuth/elevation with raw colours (compute rasterizer, no EDL, black
// background). The two frames differ by construction: the LAS is framed in its source
// coordinates (Lambert conformal conic, feet) and the tileset by its root bounding volume in a
// local east-north-up frame (metres, rotated by the grid convergence, padded), so the images are
// compared statistically, not pixel by pixel.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

#include "stipple/io/las.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {}  // namespace

// Tiles autzen_trim and renders the tileset and the LAS from the same framing parameters.
static void tile_and_render(bool compare_images) {
  STIPPLE_REQUIRE_DATA(las, "las/autzen_trim.las");
  fs::path dir = fs::temp_directory_path() / ("stipple_tiler_render_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::path tiles = dir / "autzen_tiles";
  // A small tile cap so the tileset has several levels (additive refinement), not one tile; a
  // root spacing of 100 m makes every level's geometric error (100, 50, 25 m) exceed the
  // renderer's screen-space error budget at this image size, so every tile is selected.
  auto r = test::run_stipple("tile " + las.string() + " -o " + tiles.string() +
                             " --spacing 100 --max-node-points 20000");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  ASSERT_NE(r.output.find("tiled 110000 points"), std::string::npos) << r.output;

  // The data's own mean colour (8-bit values stored in 16-bit fields).
  size_t colored = 0;
  const auto data_mean = test::mean_rgb(las, &colored);
  ASSERT_EQ(colored, 110000u);

  // Raw colours: naive splatting, no EDL, on black.
  const std::string framing =
      " --width 640 --height 360 --azimuth 30 --elevation 40 --splat naive --no-edl "
      "--background 0,0,0";
  const std::string common = framing + " --color rgb";
  fs::path las_png = dir / "las.png", tiles_png = dir / "tileset.png";
  r = test::run_stipple("render " + las.string() + " -o " + las_png.string() + common);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("rendered 110000 points"), std::string::npos) << r.output;
  r = test::run_stipple("render " + (tiles / "tileset.json").string() + " -o " +
                        tiles_png.string() + common);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The whole tileset fits the view at this size: every tile down to the finest level is
  // selected, so every point is drawn exactly once (additive refinement, no duplicates).
  EXPECT_NE(r.output.find("rendered 110000 points"), std::string::npos) << r.output;

  const uint8_t black[3] = {0, 0, 0};
  auto las_stats = test::coverage_stats(gpu::read_png(las_png), black, 0);
  if (!compare_images) {
    // Tolerance: the LAS render's covered pixels within 8 levels of the data's mean colour.
    EXPECT_GT(las_stats.coverage, 0.05);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(las_stats.mean[c], data_mean[c], 8.0) << "channel " << c;
    fs::remove_all(dir);
    return;
  }
  auto tiles_stats = test::coverage_stats(gpu::read_png(tiles_png), black, 0);
  std::printf(
      "coverage: LAS %.4f, tileset %.4f; mean colour LAS (%.1f %.1f %.1f), tileset "
      "(%.1f %.1f %.1f), data (%.1f %.1f %.1f)\n",
      las_stats.coverage, tiles_stats.coverage, las_stats.mean[0], las_stats.mean[1],
      las_stats.mean[2], tiles_stats.mean[0], tiles_stats.mean[1], tiles_stats.mean[2],
      data_mean[0], data_mean[1], data_mean[2]);
  EXPECT_GT(las_stats.coverage, 0.05);
  EXPECT_GT(tiles_stats.coverage, 0.05);
  // Tolerance: coverage within 25% (relative) of each other. The framings differ (padded root
  // volume vs LAS header box, ~1 degree of grid convergence) and the automatic point size is
  // chosen per cloud, which moves the covered area by a few percent, not by a quarter.
  EXPECT_NEAR(tiles_stats.coverage / las_stats.coverage, 1.0, 0.25);
  // Tolerance: mean colour of covered pixels within 8 levels per channel of each other and
  // within 8 levels of the data's mean (the bound render_gpu_test uses for the LAS alone):
  // same points, same raw colours, only which points win overlapping pixels differs.
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(tiles_stats.mean[c], las_stats.mean[c], 8.0) << "channel " << c;
    EXPECT_NEAR(tiles_stats.mean[c], data_mean[c], 8.0) << "channel " << c;
    EXPECT_NEAR(las_stats.mean[c], data_mean[c], 8.0) << "channel " << c;
  }
  // The tiles' intensity and classification attributes drive the same colour modes as the LAS
  // fields (a tileset without them falls back to elevation colours: a blue-to-red ramp, not
  // grey). Tolerance: mean colour of covered pixels within 10 levels per channel for the
  // classification palette; 15 for the intensity ramp, whose percentiles come from 128-point
  // samples per tile and whose covered pixels favour the coarse levels' larger splats.
  for (const char* mode : {"classification", "intensity"}) {
    fs::path a = dir / (std::string("las_") + mode + ".png"),
             b = dir / (std::string("tiles_") + mode + ".png");
    r = test::run_stipple("render " + las.string() + " -o " + a.string() + framing + " --color " +
                          mode);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    r = test::run_stipple("render " + (tiles / "tileset.json").string() + " -o " + b.string() +
                          framing + " --color " + mode);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    auto sa = test::coverage_stats(gpu::read_png(a), black, 0);
    auto sb = test::coverage_stats(gpu::read_png(b), black, 0);
    std::printf("%s: LAS (%.1f %.1f %.1f), tileset (%.1f %.1f %.1f)\n", mode, sa.mean[0],
                sa.mean[1], sa.mean[2], sb.mean[0], sb.mean[1], sb.mean[2]);
    const bool grey = std::string(mode) == "intensity";
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(sb.mean[c], sa.mean[c], grey ? 15.0 : 10.0) << mode << " " << c;
    if (grey) {  // the intensity ramp is grey: every channel equal
      EXPECT_NEAR(sb.mean[0], sb.mean[1], 0.5);
      EXPECT_NEAR(sb.mean[1], sb.mean[2], 0.5);
    }
  }
  fs::remove_all(dir);
}

TEST(TilerRender, AutzenTilesetLoadsEveryPoint) {
  tile_and_render(false);
}

TEST(TilerRender, AutzenTilesetRendersLikeItsLas) {
  tile_and_render(true);
}
