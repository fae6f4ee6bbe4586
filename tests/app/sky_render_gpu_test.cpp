// The Nishita sky behind the points (`render --sky --sun AZ,EL`), on both render paths: where
// points are drawn the image is the points' colour, exactly as without the sky; elsewhere the
// sky, whose horizon towards a rising sun is redder (higher R/B) than at noon, and whose zenith
// at noon is blue. Small images of the built-in scene, constant red points without blending or
// EDL, so that a covered pixel has one known colour.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <fmt/format.h>

#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

constexpr uint32_t kWidth = 160, kHeight = 100;
constexpr double kFovDeg = 50.0;
// Looking east at the scene (71 m across, its ground at about 200 m) from 100 m west of its
// centre and 30 m above its ground, pitched down by atan(30 / 100): the horizon lies in the
// upper fifth of the image, the points in the middle.
constexpr const char* kEastView = "--camera 499900,5100000,230,500000,5100000,200";
const double kPitchDeg = -std::atan(30.0 / 100.0) * 180.0 / M_PI;
// Looking up at 84 degrees above the scene's centre: sky only.
constexpr const char* kUpView = "--camera 500000,5100000,260,500000,5100010,360";

class SkyRender : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / fmt::format("stipple-sky-render-{}", ::getpid());
    fs::create_directories(dir_);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  gpu::Image render(const std::string& name, const std::string& view, const std::string& extra) {
    const fs::path out = dir_ / (GetParam() + "-" + name + ".png");
    const auto r = test::run_stipple(fmt::format(
        "render -o {} --width {} --height {} --fov {} {} --scene-points 60000 --color constant "
        "--constant-color 1,0,0 --splat naive --no-edl --point-size 3 --background 0,0,0 "
        "--renderer {} {}",
        out.string(), kWidth, kHeight, kFovDeg, view, GetParam(), extra));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return gpu::read_png(out);
  }
  static fs::path dir_;
};
fs::path SkyRender::dir_;

const uint8_t* pixel(const gpu::Image& image, uint32_t x, uint32_t y) {
  return &image.rgba[(size_t(y) * image.width + x) * 4];
}

bool is_red(const uint8_t* p) {
  return p[0] >= 254 && p[1] <= 1 && p[2] <= 1;
}
bool is_black(const uint8_t* p) {
  return p[0] == 0 && p[1] == 0 && p[2] == 0;
}

// Elevation (degrees) of the view ray through the middle of row `y` of the east view.
double row_elevation(uint32_t y) {
  const double half = std::tan(kFovDeg * 0.5 * M_PI / 180.0);
  const double ndc_y = 1.0 - (y + 0.5) / (kHeight * 0.5);
  return kPitchDeg + std::atan(ndc_y * half) * 180.0 / M_PI;
}

// Mean R/B of the sky pixels (not covered by points in `mask`) whose ray is 1-4 degrees above the
// horizon, in the left third of the image (away from the sun's disc straight ahead).
double horizon_red_blue(const gpu::Image& sky, const gpu::Image& mask, size_t* count) {
  double sum = 0;
  *count = 0;
  for (uint32_t y = 0; y < kHeight; ++y) {
    const double e = row_elevation(y);
    if (e < 1.0 || e > 4.0) continue;
    for (uint32_t x = 0; x < kWidth / 3; ++x) {
      if (!is_black(pixel(mask, x, y))) continue;
      const uint8_t* p = pixel(sky, x, y);
      sum += double(p[0]) / std::max(1.0, double(p[2]));
      ++*count;
    }
  }
  return *count ? sum / double(*count) : 0.0;
}

}  // namespace

TEST_P(SkyRender, PointsInFrontOfTheSkyAndSunriseRedderThanNoon) {
  // Without the sky: the plain (black) background, red where points are.
  const gpu::Image plain = render("plain", kEastView, "");
  const gpu::Image noon = render("noon", kEastView, "--sky --sun 180,60");
  const gpu::Image sunrise = render("sunrise", kEastView, "--sun 90,2");  // --sun implies --sky
  ASSERT_EQ(plain.width, kWidth);
  ASSERT_EQ(noon.width, kWidth);
  ASSERT_EQ(sunrise.width, kWidth);

  size_t covered = 0, sky = 0;
  for (uint32_t y = 0; y < kHeight; ++y)
    for (uint32_t x = 0; x < kWidth; ++x) {
      const uint8_t* p = pixel(plain, x, y);
      ASSERT_TRUE(is_black(p) || is_red(p)) << x << "," << y;
      if (is_red(p)) {
        ++covered;
        // Points in front of the sky: the points' colour, exactly.
        EXPECT_TRUE(is_red(pixel(noon, x, y))) << x << "," << y;
        EXPECT_TRUE(is_red(pixel(sunrise, x, y))) << x << "," << y;
      } else {
        ++sky;
        // The sky where nothing was drawn: never the plain background.
        EXPECT_FALSE(is_black(pixel(noon, x, y))) << x << "," << y;
      }
    }
  // The view holds both terrain and sky.
  EXPECT_GT(covered, kWidth * kHeight / 20);
  EXPECT_GT(sky, kWidth * kHeight / 2);

  size_t n_noon = 0, n_sunrise = 0;
  const double rb_noon = horizon_red_blue(noon, plain, &n_noon);
  const double rb_sunrise = horizon_red_blue(sunrise, plain, &n_sunrise);
  ASSERT_GT(n_noon, 50u);
  ASSERT_EQ(n_noon, n_sunrise);
  // At noon the horizon is a pale blue-white (R/B under 1); towards a sun 2 degrees up it is
  // orange (R/B well over 1). The margin is wide: the measured values are in the report.
  EXPECT_LT(rb_noon, 1.0);
  EXPECT_GT(rb_sunrise, 1.5 * rb_noon) << "noon " << rb_noon << ", sunrise " << rb_sunrise;
  std::printf("horizon R/B: noon %.3f, sunrise %.3f (%zu pixels)\n", rb_noon, rb_sunrise, n_noon);
}

TEST_P(SkyRender, ZenithIsBlueAtNoon) {
  const gpu::Image noon = render("zenith-noon", kUpView, "--sun 180,60");
  ASSERT_EQ(noon.width, kWidth);
  const uint8_t* p = pixel(noon, kWidth / 2, kHeight / 2);
  std::printf("zenith at noon: %u %u %u\n", p[0], p[1], p[2]);
  // Blue dominates: B over G over R, and clearly so.
  EXPECT_GT(int(p[2]), int(p[1]) + 20);
  EXPECT_GT(int(p[1]), int(p[0]));
  EXPECT_GT(p[2], 120);
}

TEST_P(SkyRender, SunDiscIsVisible) {
  // Looking straight at a sun 20 degrees up: the middle pixel is the (near-white) disc.
  const gpu::Image image =
      render("disc", "--camera 500000,5100000,260,500100,5100000,296.4", "--sun 90,20");
  ASSERT_EQ(image.width, kWidth);
  const uint8_t* p = pixel(image, kWidth / 2, kHeight / 2);
  EXPECT_GE(p[0], 240);
  EXPECT_GE(p[1], 240);
  EXPECT_GE(p[2], 200);
}

TEST_P(SkyRender, TilesetWithNothingInViewShowsTheSky) {
  // A streamed tileset whose tiles are all out of view still draws the sky (the billboard path
  // runs its passes over no chunks rather than clearing to the background).
  STIPPLE_REQUIRE_DATA(laz, "laz/autzen_trim.laz");
  const fs::path tiles = dir_ / (GetParam() + "-tiles");
  const auto t = test::run_stipple(fmt::format("tile {} -o {}", laz.string(), tiles.string()));
  ASSERT_EQ(t.exit_code, 0) << t.output;
  // 1 km above the data (local east-north-up metres), looking up.
  const gpu::Image up = render("tileset-up", "--camera 0,0,1000,0,10,2000 --max-frames 20",
                               "--sun 270,30 " + (tiles / "tileset.json").string());
  ASSERT_EQ(up.width, kWidth);
  const uint8_t* p = pixel(up, kWidth / 2, kHeight / 2);
  EXPECT_FALSE(is_black(p));
  EXPECT_GT(int(p[2]), int(p[0]) + 20);  // blue sky
}

INSTANTIATE_TEST_SUITE_P(Renderers, SkyRender, ::testing::Values("billboard", "compute"));

TEST(SkyOptions, SunTimePlacesTheSunAtTheData) {
  // The built-in scene is in UTM zone 33N at 15 E, 46.05 N: at local mean noon of the June
  // solstice the sun is south, 90 - 46.05 + 23.44 degrees up (refraction adds under 0.01).
  const fs::path out =
      fs::temp_directory_path() / fmt::format("stipple-sky-time-{}.png", ::getpid());
  const auto r = test::run_stipple(fmt::format(
      "-v render --sun-time 2026-06-21T12:00 --scene-points 2000 --width 32 --height 32 "
      "--renderer billboard -o {}",
      out.string()));
  fs::remove(out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const size_t at = r.output.find("sun at 2026-06-21T12:00 (local mean solar time) at lon 15.0000");
  ASSERT_NE(at, std::string::npos) << r.output;
  double azimuth = 0, elevation = 0;
  const size_t a = r.output.find("azimuth ", at);
  ASSERT_NE(a, std::string::npos);
  ASSERT_EQ(std::sscanf(r.output.c_str() + a, "azimuth %lf, elevation %lf", &azimuth, &elevation),
            2)
      << r.output;
  EXPECT_NEAR(azimuth, 180.0, 2.0);
  EXPECT_NEAR(elevation, 90.0 - 46.05 + 23.44, 0.1);
}

TEST(SkyOptions, SunTimeNeedsAValidTimeAndExcludesSun) {
  const auto both =
      test::run_stipple("render --sun 10,10 --sun-time 2026-06-21T06:00 -o /dev/null");
  EXPECT_NE(both.exit_code, 0);
  EXPECT_NE(both.output.find("excludes"), std::string::npos) << both.output;
  const auto bad = test::run_stipple("render --sun-time 2026-06-21 -o /dev/null");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("--sun-time"), std::string::npos) << bad.output;
}
