// Filters and clip regions on the GPU (`render --classes ... --clip-box ...`): a filtered class
// disappears and nothing else changes, and what the GPU keeps is what `stipple clip` keeps on the
// CPU (the same points rendered from the clipped file give the same image).
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

class FilterRender : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / fmt::format("stipple-filter-render-{}", ::getpid());
    fs::create_directories(dir_);
    // The built-in scene as a file, so that `stipple clip` can make the references.
    const auto r =
        test::run_stipple(fmt::format("generate -n 150000 -o {}", (dir_ / "scene.las").string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // Classification colours, opaque points without blending or EDL: a pixel shows exactly the
  // palette colour of the nearest point, so removing points changes only where they were.
  // `view`: the camera flags (a tileset's frame is not the source's: it is framed by default).
  static gpu::Image render(const std::string& input, const std::string& name,
                           const std::string& extra, const std::string& backend = "wgpu",
                           const std::string& renderer = "billboard",
                           const std::string& view = kSceneView) {
    const fs::path out = dir_ / name;
    const auto r = test::run_stipple(fmt::format(
        "render {} -o {} --width 400 --height 260 {} --color classification --splat naive "
        "--no-edl --point-size 2 --renderer {} --backend {} {}",
        input, out.string(), view, renderer, backend, extra));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return gpu::read_png(out);
  }

  static std::string clip(const std::string& name, const std::string& args) {
    const fs::path out = dir_ / name;
    const auto r = test::run_stipple(fmt::format("clip {} -o {} {}", scene(), out.string(), args));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return out.string();
  }

  static std::string scene() { return (dir_ / "scene.las").string(); }
  static void expect_filters_match_clips(const std::string& renderer, bool with_gps);
  static void expect_class_disappears(const std::string& renderer,
                                      const std::string& input = scene(),
                                      const std::string& extra = "",
                                      const std::string& view = kSceneView);
  static constexpr const char* kSceneView = "--camera 500000,5099890,320,500000,5100000,200";
  static fs::path dir_;
};
fs::path FilterRender::dir_;

bool is_color(const gpu::Image& image, size_t pixel, const uint8_t rgb[3]) {
  const uint8_t* p = &image.rgba[pixel * 4];
  return std::abs(p[0] - rgb[0]) <= 1 && std::abs(p[1] - rgb[1]) <= 1 &&
         std::abs(p[2] - rgb[2]) <= 1;
}

}  // namespace

TEST_F(FilterRender, FilteredClassDisappearsAndNothingElseChanges) {
  expect_class_disappears("billboard");
}

// The compute rasterizer's visibility buffer keeps the nearest point of each pixel: dropping a
// class changes only the pixels it won.
TEST_F(FilterRender, FilteredClassDisappearsOnTheComputePath) {
  expect_class_disappears("compute");
}

// The filters reach every source: a tileset streamed (both renderers) and the virtualized path
// (a pointlet cache, compute), with the same assertions as the in-memory cloud. The virtualized
// path's hole filling is off (it fills empty pixels from their neighbours, so hiding a class
// would change pixels beside it), and it takes 2,000-point pointlets (the default 100,000 make
// one pointlet of this small file).
TEST_F(FilterRender, FilteredClassDisappearsOnTilesetsAndTheVirtualizedPath) {
  const fs::path tiles = dir_ / "tiles";
  const auto r = test::run_stipple(fmt::format("tile {} -o {}", scene(), tiles.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string tileset = (tiles / "tileset.json").string();
  expect_class_disappears("billboard", tileset, "", "--azimuth 30 --elevation 40");
  expect_class_disappears("compute", tileset, "", "--azimuth 30 --elevation 40");
  expect_class_disappears("compute", scene(),
                          fmt::format("--virtual --pointlets 2000 --fill-radius 0 --cache {}",
                                      (dir_ / "cache").string()));
}

// A COPC file streamed by its hierarchy takes clip boxes too (lone-star holds class 0 only, so
// a box it is): a box around everything drawn in outside mode leaves nothing; the west half
// inside covers a part of the full view's pixels and none it left empty.
TEST_F(FilterRender, ClipBoxReachesTheCopcStream) {
  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  const uint8_t bg[3] = {18, 20, 26};
  for (const std::string renderer : {"billboard", "compute"}) {
    SCOPED_TRACE(renderer);
    const gpu::Image all =
        render(copc.string(), "copc-all-" + renderer + ".png", "", "wgpu", renderer, "");
    const gpu::Image none =
        render(copc.string(), "copc-none-" + renderer + ".png",
               "--clip-box 515300,4918300,2300,515500,4918500,2400 --clip-mode outside", "wgpu",
               renderer, "");
    const gpu::Image west =
        render(copc.string(), "copc-west-" + renderer + ".png",
               "--clip-box 515300,4918300,2300,515385,4918500,2400", "wgpu", renderer, "");
    const auto full = test::coverage_stats(all, bg, 1);
    EXPECT_GT(full.coverage, 0.05);
    EXPECT_EQ(test::coverage_stats(none, bg, 1).covered, 0u);
    const auto half = test::coverage_stats(west, bg, 1);
    EXPECT_GT(half.covered, full.covered / 5);
    EXPECT_LT(half.covered, full.covered * 4 / 5);
    size_t new_pixels = 0;
    for (size_t i = 0; i < size_t(all.width) * all.height; ++i) {
      auto is_bg = [&](const gpu::Image& im) {
        const uint8_t* p = &im.rgba[i * 4];
        return std::abs(p[0] - bg[0]) <= 1 && std::abs(p[1] - bg[1]) <= 1 &&
               std::abs(p[2] - bg[2]) <= 1;
      };
      new_pixels += is_bg(all) && !is_bg(west);
    }
    EXPECT_EQ(new_pixels, 0u);
  }
}

void FilterRender::expect_class_disappears(const std::string& renderer, const std::string& input,
                                           const std::string& extra, const std::string& view) {
  const std::string tag = fs::path(input).stem().string() + "-" + renderer +
                          (extra.empty() ? "" : "-" + extra.substr(2, 7));
  const gpu::Image all = render(input, "all-" + tag + ".png", extra, "wgpu", renderer, view);
  const gpu::Image no_buildings = render(input, "no-buildings-" + tag + ".png",
                                         "--classes 0-5,7-255 " + extra, "wgpu", renderer, view);
  ASSERT_EQ(all.rgba.size(), no_buildings.rgba.size());
  SCOPED_TRACE(tag);
  const uint8_t building[3] = {220, 80, 60};  // ASPRS class 6 in the palette
  size_t before = 0, after = 0, changed_elsewhere = 0, other = 0;
  const size_t n = size_t(all.width) * all.height;
  for (size_t i = 0; i < n; ++i) {
    const bool was_building = is_color(all, i, building);
    before += was_building;
    after += is_color(no_buildings, i, building);
    if (was_building) continue;
    ++other;
    bool same = true;
    for (int c = 0; c < 3; ++c) same &= all.rgba[i * 4 + c] == no_buildings.rgba[i * 4 + c];
    changed_elsewhere += !same;
  }
  EXPECT_GT(before, n / 50);  // buildings cover a visible part of the view
  EXPECT_EQ(after, 0u);       // and are gone
  // Every pixel that did not show a building is unchanged (exactly: same points, same order).
  EXPECT_EQ(changed_elsewhere, 0u) << "of " << other;
}

// The GPU keeps what `stipple clip` keeps: the same view of the clipped file matches. Tolerance:
// 0.5% of pixels, as the two clouds are chunked differently (other float origins, other draw
// order among equal depths).
TEST_F(FilterRender, GpuFiltersMatchTheClippedFiles) {
  expect_filters_match_clips("billboard", true);
}

// The compute rasterizer drops hidden points in its geometry pass: the same comparisons, on
// the 64-bit visibility buffer (wgpu-native) and the two-pass fallback (Dawn). Its batches
// hold no GPS time, so that case stays with the billboards.
TEST_F(FilterRender, ComputeFiltersMatchTheClippedFiles) {
  expect_filters_match_clips("compute", false);
}

void FilterRender::expect_filters_match_clips(const std::string& renderer, bool with_gps) {
  struct Case {
    std::string name, render_flags, clip_flags;
  };
  const fs::path polygon = dir_ / "area.geojson";
  std::ofstream(polygon) << R"({"type": "Polygon", "coordinates": [[[499960, 5099950],
      [500050, 5099970], [500010, 5100060], [499960, 5099950]], [[499990, 5099980],
      [500010, 5099980], [500000, 5100000], [499990, 5099980]]]})";
  const Case cases[] = {
      {"box", "--clip-box 499970,5099960,190,500040,5100030,240,25",
       "--box 499970,5099960,190,500040,5100030,240,25"},
      {"outside", "--clip-box 499970,5099960,190,500040,5100030,240,25 --clip-mode outside",
       "--box 499970,5099960,190,500040,5100030,240,25 --outside"},
      {"polygon", "--clip-polygon " + polygon.string() + " --returns first",
       "--polygon " + polygon.string() + " --returns first"},
      {"gps-and-plane", "--gps-time-range 300000000.3,300000000.9 --clip-plane 0,0,-1,215",
       "--gps-time-range 300000000.3,300000000.9 --plane 0,0,-1,215"},
  };
  for (const Case& c : cases) {
    if (!with_gps && c.name == "gps-and-plane") continue;
    for (const char* backend : {"wgpu", "dawn"}) {
      if (renderer == "billboard" && std::string(backend) == "dawn") continue;
      const std::string tag = fmt::format("{}-{}-{}", c.name, renderer, backend);
      const gpu::Image gpu = render(scene(), tag + "-gpu.png", c.render_flags, backend, renderer);
      const std::string clipped = clip(c.name + ".las", c.clip_flags);
      const gpu::Image cpu = render(clipped, tag + "-cpu.png", "", backend, renderer);
      const uint8_t bg[3] = {18, 20, 26};
      const auto stats = test::coverage_stats(gpu, bg, 1);
      EXPECT_GT(stats.coverage, 0.02) << tag;  // something is drawn
      EXPECT_LT(test::differing_fraction(gpu, cpu, 1), 0.005) << tag;
    }
  }
}

// Highlight keeps every point and tints those inside the region; Dawn compiles the filter
// shaders (extras variant included) as wgpu-native does; the compute rasterizer tints in its
// resolve (wgpu-native) and accumulation (Dawn) passes.
TEST_F(FilterRender, HighlightTintsTheRegionOnBothBackends) {
  for (const std::string variant : {"wgpu", "dawn", "wgpu compute", "dawn compute"}) {
    const bool compute = variant.find("compute") != std::string::npos;
    const std::string backend = variant.substr(0, 4);
    const std::string renderer = compute ? "compute" : "billboard";
    const std::string tag = backend + "-" + renderer;
    const gpu::Image all = render(scene(), "plain-" + tag + ".png", "", backend, renderer);
    const gpu::Image lit = render(
        scene(), "highlight-" + tag + ".png",
        fmt::format("--clip-box 499970,5099960,150,500040,5100030,300 --clip-mode highlight {}",
                    compute ? "" : "--point-source-range 0,65535"),
        backend, renderer);
    const uint8_t bg[3] = {18, 20, 26};
    // Same coverage (nothing hidden), but many pixels changed colour (tinted).
    EXPECT_NEAR(test::coverage_stats(lit, bg, 1).coverage,
                test::coverage_stats(all, bg, 1).coverage, 0.002)
        << variant;
    const double changed = test::differing_fraction(all, lit, 8);
    EXPECT_GT(changed, 0.05) << variant;
    EXPECT_LT(changed, 0.6) << variant;
  }
}
