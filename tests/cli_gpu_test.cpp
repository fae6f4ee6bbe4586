// End-to-end tests of the `stipple` command: outputs, exit codes and error messages.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

struct Result {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

Result run(const std::string& args) {
  std::string command = std::string(STIPPLE_BINARY) + " " + args + " 2>&1";
  Result r;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) r.output.append(buffer.data(), n);
  int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

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
  auto r = run("--help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* cmd : {"render", "info", "generate"})
    EXPECT_NE(r.output.find(cmd), std::string::npos) << cmd;
  EXPECT_EQ(run("render --help").exit_code, 0);
}

TEST(Cli, RenderBuiltInScene) {
  fs::path out = temp_dir() / "scene.png";
  auto r = run("render --scene-points 200000 --width 320 --height 200 -o " + out.string());
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
    auto r = run(fmt::format("render {} -o {}/{}.png --width 1280 --height 720 --backend {}",
                             path.string(), dir.string(), backend, backend));
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
  auto r = run("info " + autzen.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("LAS 1.2, point format 3"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("110000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("LAZ compressed"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("RGB (8-bit values)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("unit foot"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Lambert_Conformal_Conic"), std::string::npos) << r.output;

  STIPPLE_REQUIRE_DATA(geographic, "las/epsg_4326.las");
  r = run("info --json " + geographic.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"geographic\": true"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"epsg\": 4326"), std::string::npos) << r.output;

  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  r = run("info " + copc.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("LAS 1.4, point format 6"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("COPC"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("518862"), std::string::npos) << r.output;
}

TEST(Cli, GpuInfo) {
  for (const char* backend : {"dawn", "wgpu"}) {
    auto r = run(std::string("info --gpu --backend ") + backend);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(std::string("WebGPU implementation: ") + backend), std::string::npos);
    EXPECT_NE(r.output.find("maxStorageBufferBindingSize"), std::string::npos);
    EXPECT_NE(r.output.find("Vulkan"), std::string::npos);
  }
}

TEST(Cli, GenerateWritesReadableLas) {
  fs::path out = temp_dir() / "gen.las";
  auto r = run("generate -n 300000 -o " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run("info " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("LAS 1.4, point format 7"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("300000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("32633"), std::string::npos) << r.output;
  fs::path png = out.parent_path() / "gen.png";
  r = run("render " + out.string() + " --width 200 --height 150 -o " + png.string());
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
      auto r = run(args);
      EXPECT_EQ(r.exit_code, 1) << cmd << " " << c.name << ": " << r.output;
      EXPECT_NE(r.output.find(c.expect), std::string::npos) << r.output;
      EXPECT_NE(r.output.find("error"), std::string::npos) << r.output;
    }
    EXPECT_FALSE(fs::exists(png)) << c.name;
  }
  auto r = run("render " + (dir / "missing.las").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("missing.las"), std::string::npos) << r.output;
  r = run("render --camera 1,2,3 -o " + (dir / "x.png").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("--camera"), std::string::npos) << r.output;
  r = run("render --backend vulkan");
  EXPECT_NE(r.exit_code, 0);
}
