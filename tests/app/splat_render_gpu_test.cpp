// Gaussian splat files through `stipple render` (scene::plan_scene reads them, SplatPlugin draws
// them): a splat file alone is framed and drawn, with its count in the summary; a damaged splat
// file is an error naming it, with no image. Splats and points in one frame, depth-tested, are
// tests/splats' (SplatPlugin through the engine).
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir() {
  const fs::path dir =
      fs::temp_directory_path() / fmt::format("stipple-splat-render-{}", ::getpid());
  fs::create_directories(dir);
  return dir;
}

const uint8_t kBlack[3] = {0, 0, 0};

}  // namespace

TEST(SplatRender, SplatFileAloneIsFramedAndDrawn) {
  STIPPLE_REQUIRE_DATA(path, "splats/playcanvas-engine/biker.spz");
  const fs::path out = temp_dir() / "biker.png";
  const auto r = test::run_stipple(fmt::format(
      "render {} -o {} --width 160 --height 120 --background 0,0,0", path.string(), out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("152746 splats"), std::string::npos) << r.output;
  const auto image = gpu::read_png(out);
  // Framed on the splats' centres: the standing rider covers about a tenth of the view (0.093
  // on lavapipe), not a speck.
  const auto stats = test::coverage_stats(image, kBlack, 4);
  EXPECT_GT(stats.coverage, 0.06) << "coverage " << stats.coverage;
}

TEST(SplatRender, DamagedSplatFileIsAnErrorNamingIt) {
  STIPPLE_REQUIRE_DATA(path, "splats/splat-transform/minimal-v4.spz");
  const fs::path dir = temp_dir();
  const fs::path bad = dir / "cut.spz", out = dir / "cut.png";
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), {});
  bytes.resize(bytes.size() / 2);
  std::ofstream(bad, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
  const auto r = test::run_stipple(fmt::format("render {} -o {}", bad.string(), out.string()));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("cut.spz"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}
