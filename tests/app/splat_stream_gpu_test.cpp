// Splat tilesets streamed by `stipple render` (tiles3d::SplatTilesetPlugin through the scene,
// drawn by one SplatPlugin set): at a fine --max-sse the streamed render equals the render of
// the source splat file; at a coarse --max-sse fewer splats are drawn (the summary's count);
// a point cloud and a splat tileset draw in one frame.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "las_bytes.hpp"
#include "stipple/renderer/png.hpp"
#include "test_util.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

// One small tileset for the whole file: 20k generated splats (SH degree 1), leaves of at most
// 2000, so a few levels of merged tiles above them.
struct Fixture {
  fs::path dir, spz, tileset;
  ~Fixture() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture x;
    x.dir = fs::temp_directory_path() / fmt::format("stipple-splat-stream-{}", ::getpid());
    fs::remove_all(x.dir);
    fs::create_directories(x.dir);
    x.spz = x.dir / "scene.spz";
    x.tileset = x.dir / "tiles" / "tileset.json";
    auto g = test::run_stipple(
        fmt::format("generate -o {} -n 20000 --sh-degree 1 --threads 2", x.spz.string()));
    EXPECT_EQ(g.exit_code, 0) << g.output;
    auto t = test::run_stipple(fmt::format("tile {} -o {} --max-leaf-splats 2000 --threads 2",
                                           x.spz.string(), (x.dir / "tiles").string()));
    EXPECT_EQ(t.exit_code, 0) << t.output;
    return x;
  }();
  return f;
}

struct Rendered {
  gpu::Image image;
  uint64_t splats = 0;
  std::string output;
};

// The camera is given (Z up, the data's coordinates) so that the file and the tileset (framed
// on its root volume otherwise) are seen from the same place.
Rendered render(const std::string& inputs, const std::string& extra, const std::string& name) {
  const fs::path out = fixture().dir / (name + ".png"), stats = fixture().dir / (name + ".json");
  const auto r = test::run_stipple(
      fmt::format("render {} -o {} --stats {} --width 160 --height 120 --background 0,0,0 "
                  "--camera 0,-45,40,0,-8,12 {}",
                  inputs, out.string(), stats.string(), extra));
  Rendered result;
  result.output = r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  if (r.exit_code != 0) return result;
  result.image = gpu::read_png(out);
  std::ifstream in(stats);
  result.splats = nlohmann::json::parse(in).at("splats").get<uint64_t>();
  return result;
}

const uint8_t kBlack[3] = {0, 0, 0};

}  // namespace

TEST(SplatStream, FineMaxSseEqualsTheSourceFile) {
  const Fixture& f = fixture();
  ASSERT_TRUE(fs::exists(f.tileset));
  const Rendered source = render(f.spz.string(), "", "source");
  const Rendered streamed = render(f.tileset.string(), "--max-sse 0.01", "fine");
  ASSERT_FALSE(source.image.rgba.empty());
  ASSERT_FALSE(streamed.image.rgba.empty());
  // Every leaf is drawn, and they hold the input.
  EXPECT_EQ(source.splats, 20000u);
  EXPECT_EQ(streamed.splats, 20000u) << streamed.output;
  const auto covered = test::coverage_stats(source.image, kBlack, 4);
  EXPECT_GT(covered.coverage, 0.2) << "the view shows the scene";
  // Tolerance: all but 0.2% of the pixels within 2 levels a channel (lavapipe: none differ).
  // The leaves re-encode the SPZ input's fixed point, and the tiles' splats reach the sort in
  // another order than the file's, so splats at equal depth may blend in another order.
  const double differing = test::differing_fraction(source.image, streamed.image, 2);
  std::printf("coverage %.3f; pixels differing by more than 2 levels %.4f\n", covered.coverage,
              differing);
  EXPECT_LT(differing, 0.002) << "differing " << differing;
}

TEST(SplatStream, CoarseMaxSseDrawsFewerSplats) {
  const Fixture& f = fixture();
  ASSERT_TRUE(fs::exists(f.tileset));
  const Rendered fine = render(f.tileset.string(), "--max-sse 0.01", "fine2");
  const Rendered coarse = render(f.tileset.string(), "--max-sse 1000", "coarse");
  EXPECT_EQ(fine.splats, 20000u);
  EXPECT_GT(coarse.splats, 0u) << coarse.output;
  EXPECT_LT(coarse.splats, fine.splats / 2) << coarse.output;
  std::printf("splats drawn: fine %llu, coarse %llu\n", (unsigned long long)fine.splats,
              (unsigned long long)coarse.splats);
  EXPECT_NE(coarse.output.find(fmt::format("{} splats", coarse.splats)), std::string::npos)
      << coarse.output;
  // Coarse tiles still cover the scene (merged splats, not holes).
  EXPECT_GT(test::coverage_stats(coarse.image, kBlack, 4).coverage,
            0.5 * test::coverage_stats(fine.image, kBlack, 4).coverage);
  // A splat budget below the leaves also draws coarser tiles.
  const Rendered budget = render(f.tileset.string(), "--max-sse 0.01 --splat-budget 5000", "b");
  EXPECT_GT(budget.splats, 0u);
  EXPECT_LE(budget.splats, 5000u) << budget.output;
}

TEST(SplatStream, PointsAndASplatTilesetInOneFrame) {
  const Fixture& f = fixture();
  ASSERT_TRUE(fs::exists(f.tileset));
  // A red square of points over the middle of the splat scene (which spans x -25..25, y
  // -25..8, z 7..28 in the data's Z-up frame), beside the splats: both are drawn.
  const fs::path las = f.dir / "points.las";
  test::LasFile file;
  file.points = test::grid_points(2500, -10.0, -20.0, 20.0, 22.0);
  for (auto& p : file.points) {
    p.r = 255;
    p.g = 0;
    p.b = 0;
  }
  const auto bytes = test::las_bytes(file);
  std::ofstream(las, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  const Rendered points = render(las.string(), "--point-size 2", "points");
  const Rendered both =
      render(fmt::format("{} {}", las.string(), f.tileset.string()), "--point-size 2", "both");
  const Rendered splats = render(f.tileset.string(), "", "splats");
  EXPECT_GT(both.splats, 0u) << both.output;
  EXPECT_EQ(both.splats, splats.splats);
  EXPECT_NE(both.output.find("2500 points"), std::string::npos) << both.output;
  // The frame holds both: it differs from either alone.
  EXPECT_GT(test::differing_fraction(both.image, points.image, 8), 0.05);
  EXPECT_GT(test::differing_fraction(both.image, splats.image, 8), 0.05);
}

TEST(SplatStream, BenchStreamFliesASplatTileset) {
  const Fixture& f = fixture();
  ASSERT_TRUE(fs::exists(f.tileset));
  // Sequential (each frame waits for the GPU), and pipelined (the render world on its own
  // thread, frames not waiting), as a viewer draws.
  for (const std::string mode : {"", "--pipelined"}) {
    SCOPED_TRACE(mode);
    const fs::path json = f.dir / "bench.json";
    const auto r = test::run_stipple(
        fmt::format("bench stream {} --renderer billboard --width 64 --height 48 --frames 8 "
                    "--splat-budget 5000 --json {} {}",
                    f.tileset.string(), json.string(), mode));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("M splats a frame"), std::string::npos) << r.output;
    std::ifstream in(json);
    const auto j = nlohmann::json::parse(in);
    EXPECT_EQ(j.at("frames").get<uint32_t>(), 8u);
    EXPECT_EQ(j.at("pipelined").get<bool>(), !mode.empty());
    EXPECT_EQ(j.at("frame_wall_ms").size(), 8u);
    // Every frame's GPU time comes back, also where no frame waited for it.
    EXPECT_EQ(j.at("frame_gpu_ms").size(), 8u);
    EXPECT_GT(j.at("gpu_ms_median").get<double>(), 0.0);
    // And by pass, each within the frame's.
    const auto& passes = j.at("gpu_pass_ms_median");
    EXPECT_FALSE(passes.empty());
    double sum = 0;
    for (const auto& [pass, ms] : passes.items()) sum += ms.get<double>();
    EXPECT_GT(sum, 0.0);
    // Frames do not wait for loads: some frames draw splats, none more than the budget.
    EXPECT_GT(j.at("splats_drawn_mean").get<double>(), 0.0);
    EXPECT_LE(j.at("splats_drawn_mean").get<double>(), 5000.0);
    EXPECT_GT(j.at("loads").get<uint64_t>(), 0u);
    // The frame's CPU by stage: the render world's Queue records the splat passes every frame.
    const auto& cpu = j.at("cpu_ms_mean");
    EXPECT_GT(cpu.at("render_queue").get<double>(), 0.0);
    EXPECT_GT(cpu.at("main_stages").get<double>(), 0.0);
    EXPECT_NE(r.output.find("CPU ms a frame by stage"), std::string::npos) << r.output;
  }
}
