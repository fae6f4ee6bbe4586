// End-to-end tests of the `stipple` command: outputs, exit codes and error messages.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir() {
  fs::path dir =
      fs::temp_directory_path() /
      ("stipple-cli-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "-" +
       ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::create_directories(dir);
  return dir;
}

void write_file(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

}  // namespace

TEST(Cli, HelpListsCommands) {
  auto r = test::run_stipple("--help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* cmd : {"render", "info", "generate"})
    EXPECT_NE(r.output.find(cmd), std::string::npos) << cmd;
  EXPECT_EQ(test::run_stipple("render --help").exit_code, 0);
}

TEST(Cli, RenderBuiltInScene) {
  fs::path out = temp_dir() / "scene.png";
  auto r =
      test::run_stipple("render --scene-points 200000 --width 320 --height 200 -o " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto image = gpu::read_png(out);
  EXPECT_EQ(image.width, 320u);
  EXPECT_EQ(image.height, 200u);
  const uint8_t bg[3] = {18, 20, 26};  // 0.07, 0.08, 0.1
  auto stats = test::coverage_stats(image, bg, 1);
  EXPECT_GT(stats.coverage, 0.15);
  // Terrain and trees: green dominates the scene.
  EXPECT_GT(stats.mean[1], stats.mean[0]);
  EXPECT_GT(stats.mean[1], stats.mean[2]);
  EXPECT_NE(r.output.find("200000 points"), std::string::npos) << r.output;
}

TEST(Cli, BackendsAgreeOnAutzen) {
  STIPPLE_REQUIRE_DATA(path, "las/autzen_trim.las");
  fs::path dir = temp_dir();
  for (const char* backend : {"dawn", "wgpu"}) {
    auto r = test::run_stipple(
        fmt::format("render {} -o {}/{}.png --width 1280 --height 720 --backend {}", path.string(),
                    dir.string(), backend, backend));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("rendered 110000 points"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(std::string("with ") + backend), std::string::npos) << r.output;
  }
  auto dawn = gpu::read_png(dir / "dawn.png");
  auto wgpu = gpu::read_png(dir / "wgpu.png");
  // Tolerance: both run the same WGSL on the same Vulkan driver; allow 0.5% of pixels to differ
  // by more than 1 level (rasterisation tie-breaks between equal-depth quads).
  EXPECT_LT(test::differing_fraction(dawn, wgpu, 1), 0.005);
}

TEST(Cli, InfoReportsHeaderFacts) {
  STIPPLE_REQUIRE_DATA(autzen, "laz/autzen_trim.laz");
  auto r = test::run_stipple("info " + autzen.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("LAS 1.2, point format 3"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("110000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("LAZ compressed"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("RGB (8-bit values)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("unit foot"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Lambert_Conformal_Conic"), std::string::npos) << r.output;

  STIPPLE_REQUIRE_DATA(geographic, "las/epsg_4326.las");
  r = test::run_stipple("info --json " + geographic.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"geographic\": true"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"epsg\": 4326"), std::string::npos) << r.output;

  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  r = test::run_stipple("info " + copc.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("LAS 1.4, point format 6"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("COPC"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("518862"), std::string::npos) << r.output;
}

TEST(Cli, GpuInfo) {
  for (const char* backend : {"dawn", "wgpu"}) {
    auto r = test::run_stipple(std::string("info --gpu --backend ") + backend);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(std::string("WebGPU implementation: ") + backend), std::string::npos);
    EXPECT_NE(r.output.find("maxStorageBufferBindingSize"), std::string::npos);
    EXPECT_NE(r.output.find("Vulkan"), std::string::npos);
  }
}

TEST(Cli, GenerateWritesReadableLas) {
  fs::path out = temp_dir() / "gen.las";
  auto r = test::run_stipple("generate -n 300000 -o " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = test::run_stipple("info " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("LAS 1.4, point format 7"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("300000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("32633"), std::string::npos) << r.output;
  fs::path png = out.parent_path() / "gen.png";
  r = test::run_stipple("render " + out.string() + " --width 200 --height 150 -o " + png.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("rendered 300000 points"), std::string::npos) << r.output;
}

// Bad input: a clear message naming the file, a non-zero exit, no crash, no output file.
TEST(Cli, BadInputsFailCleanly) {
  fs::path dir = temp_dir();
  struct Case {
    std::string name, bytes, expect;
  };
  std::string las_header(375, '\0');
  std::memcpy(las_header.data(), "LASF", 4);
  std::vector<Case> cases = {
      {"empty.las", "", "empty.las"},
      {"text.las", "this is not a point cloud, just some text\n", "text.las"},
      {"truncated.las", las_header.substr(0, 100), "truncated.las"},
  };
  for (const auto& c : cases) {
    write_file(dir / c.name, c.bytes);
    fs::path png = dir / (c.name + ".png");
    for (const char* cmd : {"info", "render"}) {
      std::string args = std::string(cmd) + " " + (dir / c.name).string();
      if (std::string(cmd) == "render") args += " -o " + png.string();
      auto r = test::run_stipple(args);
      EXPECT_EQ(r.exit_code, 1) << cmd << " " << c.name << ": " << r.output;
      EXPECT_NE(r.output.find(c.expect), std::string::npos) << r.output;
      EXPECT_NE(r.output.find("error"), std::string::npos) << r.output;
    }
    EXPECT_FALSE(fs::exists(png)) << c.name;
  }
  auto r = test::run_stipple("render " + (dir / "missing.las").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("missing.las"), std::string::npos) << r.output;
  r = test::run_stipple("render --camera 1,2,3 -o " + (dir / "x.png").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--camera"), std::string::npos) << r.output;
  r = test::run_stipple("render --backend vulkan");
  EXPECT_NE(r.exit_code, 0);
}
