// `stipple bench` runs end to end and writes well-formed results (no timing is asserted).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_util.hpp"

using namespace stipple;

namespace fs = std::filesystem;

namespace {

class Bench : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(Bench, SuballocWritesJson) {
  fs::path dir =
      fs::temp_directory_path() /
      ("stipple-bench-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "-" +
       GetParam());
  fs::create_directories(dir);
  fs::path json_path = dir / "suballoc.json";
  auto r = test::run_stipple("bench suballoc --count 200 --touch --free-order random --backend " +
                             GetParam() + " --json " + json_path.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Page (MB)"), std::string::npos) << r.output;
  std::ifstream in(json_path);
  auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["benchmark"], "suballoc");
  EXPECT_EQ(j["backend"], GetParam());
  EXPECT_FALSE(j["adapter"].get<std::string>().empty());
  EXPECT_EQ(j["count"], 200);
  uint64_t total = j["total_bytes"];
  EXPECT_GE(total, 200u * 128 * 1024);
  EXPECT_LE(total, 200u * 1024 * 1024);
  EXPECT_GT(j["direct"]["alloc_us"].get<double>(), 0.0);
  EXPECT_GT(j["direct"]["free_ns"].get<double>(), 0.0);
  ASSERT_EQ(j["suballocator"].size(), 4u);
  const uint64_t page_mb[] = {16, 32, 64, 128};
  for (size_t i = 0; i < 4; ++i) {
    const auto& row = j["suballocator"][i];
    EXPECT_EQ(row["page_mb"], page_mb[i]);
    uint64_t pages = row["pages"];
    // Enough pages for every byte, and not absurdly many.
    EXPECT_GE(pages * (page_mb[i] << 20), total);
    EXPECT_LE(pages, total / (page_mb[i] << 20) + 2);
    EXPECT_EQ(row["dedicated_buffers"], 0);
    EXPECT_EQ(row["bytes_used"], total);
    EXPECT_EQ(row["bytes_used_after_free"], 0);
    EXPECT_EQ(row["coalesced_after_free"], true);
    EXPECT_GT(row["alloc_us"].get<double>(), 0.0);
    EXPECT_GT(row["alloc_speedup"].get<double>(), 0.0);
  }
  fs::remove_all(dir);
}

TEST(BenchArgs, BadArgumentsFail) {
  EXPECT_NE(test::run_stipple("bench").exit_code, 0);
  auto r = test::run_stipple("bench suballoc --count 10 --min-kb 512 --max-kb 128");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--min-kb"), std::string::npos) << r.output;
}

// `bench raster --variants` takes names joined by '+' (a variant and the measurements combined
// with it): a combined variant draws the same points as the default (counters from the GPU), and
// an unknown name fails naming it, before anything is generated.
TEST(BenchRaster, CombinedVariantsRunAndUnknownOnesFail) {
  const fs::path json_path =
      fs::temp_directory_path() / ("stipple_bench_raster_" + std::to_string(::getpid()) + ".json");
  auto r = test::run_stipple(
      "bench raster --points 200000 --width 160 --height 90 --frames 1 --warmup 0 --no-billboard "
      "--backend wgpu --variants compute-precision,compute-hqs+no-sums --json " +
      json_path.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(json_path);
  const auto j = nlohmann::json::parse(in);
  ASSERT_EQ(j["runs"].size(), 4u) << j.dump();  // two variants, two views
  for (size_t i = 0; i < 4; i += 2) {
    const auto& plain = j["runs"][i];
    const auto& combined = j["runs"][i + 1];
    EXPECT_EQ(plain["variant"], "compute-precision");
    EXPECT_EQ(combined["variant"], "compute-hqs+no-sums");
    EXPECT_EQ(plain["view"], combined["view"]);
    EXPECT_GT(plain["points_rendered"].get<uint64_t>(), 0u);
    EXPECT_EQ(combined["points_rendered"], plain["points_rendered"]);
    // Each pass's median time, the geometry pass's among them.
    ASSERT_TRUE(plain["pass_gpu_ms"].contains("raster-depth")) << plain.dump();
    EXPECT_EQ(plain["pass_gpu_ms"]["raster-depth"], plain["geometry_gpu_ms"]);
  }
  fs::remove(json_path);
  r = test::run_stipple("bench raster --points 1000 --no-billboard --variants compute-hqs+wg65");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("unknown variant 'wg65'"), std::string::npos) << r.output;
}

TEST_P(Bench, SplatsWritesJson) {
  fs::path dir =
      fs::temp_directory_path() /
      ("stipple-bench-splats-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
       "-" + GetParam());
  fs::create_directories(dir);
  fs::path json_path = dir / "splats.json";
  auto r = test::run_stipple("bench splats --count 3000 --sh 3 --size 96x64 --frames 2 --backend " +
                             GetParam() + " --json " + json_path.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("splat-sort"), std::string::npos) << r.output;
  std::ifstream in(json_path);
  auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["benchmark"], "splats");
  EXPECT_EQ(j["backend"], GetParam());
  EXPECT_EQ(j["splats"], 3000);
  EXPECT_EQ(j["sh_degree"], 3);
  // The generated box is in view: most splats survive culling.
  EXPECT_GT(j["visible"].get<uint32_t>(), 1500u);
  EXPECT_LE(j["visible"].get<uint32_t>(), 3000u);
  if (j.contains("passes")) {
    for (const char* pass : {"splat-project", "splat-sort", "splat-draw"})
      EXPECT_GT(j["passes"][pass].get<double>(), 0.0) << pass;
    EXPECT_GT(j["sort_only_ms"].get<double>(), 0.0);
    // Both rasterizers in one run.
    EXPECT_GT(j["variants"]["quads"]["frame_gpu_ms"].get<double>(), 0.0);
    for (const char* pass : {"splat-bin", "splat-tile-sort", "splat-raster", "splat-composite"})
      EXPECT_GT(j["variants"]["tiles"]["passes"][pass].get<double>(), 0.0) << pass;
  }
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Backends, Bench, ::testing::Values("dawn", "wgpu"),
                         [](const auto& info) { return info.param; });

// `bench stream` flies the camera path over a COPC file: every frame timed, the points it drew
// counted, and a non-tileset input refused.
TEST(BenchStream, FliesTheCameraPathOverCopc) {
  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  const fs::path json =
      fs::temp_directory_path() / ("stipple_bench_stream_" + std::to_string(::getpid()) + ".json");
  auto r = test::run_stipple("bench stream " + copc.string() +
                             " --frames 12 --width 320 --height 180 --json " + json.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("FPS avg"), std::string::npos) << r.output;
  auto j = nlohmann::json::parse(std::ifstream(json));
  EXPECT_EQ(j["frame_wall_ms"].size(), 12u);
  EXPECT_GT(j["fps"]["average"].get<double>(), 0.0);
  EXPECT_GT(j["points_drawn_mean"].get<double>(), 0.0);
  EXPECT_LE(j["loads"].get<uint64_t>(), 15u);  // each of the 15 nodes at most once (no evictions)
  EXPECT_EQ(j["errors"].get<uint64_t>(), 0u);
  fs::remove(json);
  auto bad =
      test::run_stipple("bench stream " + (test::data_dir() / "las/autzen_trim.las").string());
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("not a tileset or a COPC file"), std::string::npos) << bad.output;
}

namespace {

std::vector<std::vector<std::string>> read_csv(const fs::path& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
    rows.push_back(std::move(cells));
  }
  return rows;
}

}  // namespace

// `bench stream --samples` writes one row a frame with --sample-seconds 0 (and only the first and
// last frames' rows when the interval outlasts the run): the columns bench/soak.sh checks, the
// resident tile bytes within a budget smaller than the file's nodes and the GPU bytes within the
// buffers reserved for them; --duration ends a run by time.
TEST(BenchStream, SamplesEveryIntervalWithinTheBudgets) {
  STIPPLE_REQUIRE_DATA(copc, "laz/lone-star.copc.laz");
  const fs::path csv =
      fs::temp_directory_path() / ("stipple_bench_samples_" + std::to_string(::getpid()) + ".csv");
  auto r = test::run_stipple("bench stream " + copc.string() +
                             " --frames 12 --width 320 --height 180 --memory-mb 12 --samples " +
                             csv.string() + " --sample-seconds 0");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto rows = read_csv(csv);
  ASSERT_EQ(rows.size(), 13u);  // header + one row a frame
  const std::vector<std::string> header = {
      "seconds",        "frame",     "rss_bytes",          "resident_bytes",
      "memory_budget",  "gpu_bytes", "gpu_reserved_bytes", "resident_tiles",
      "gpu_tiles",      "loads",     "evictions",          "errors",
      "refused_uploads"};
  EXPECT_EQ(rows[0], header);
  double last_seconds = -1;
  uint64_t last_loads = 0;
  for (size_t i = 1; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), header.size()) << i;
    const auto col = [&](size_t c) { return std::stoull(rows[i][c]); };
    EXPECT_EQ(col(1), i);  // frame
    EXPECT_GE(std::stod(rows[i][0]), last_seconds);
    last_seconds = std::stod(rows[i][0]);
    EXPECT_GT(col(2), 0u);         // RSS
    EXPECT_EQ(col(4), 12u << 20);  // the budget asked for (it holds 6 of the 15 nodes)
    EXPECT_LE(col(3), col(4)) << "resident tile bytes over the budget at frame " << i;
    EXPECT_LE(col(5), col(6)) << "GPU bytes over the reserved buffers at frame " << i;
    EXPECT_GE(col(9), last_loads);
    last_loads = col(9);
    EXPECT_EQ(col(11), 0u);  // errors
  }
  const auto& last = rows.back();
  EXPECT_GT(std::stoull(last[9]), 0u);  // loads
  EXPECT_GT(std::stoull(last[3]), 0u);  // tiles resident ...
  EXPECT_GT(std::stoull(last[5]), 0u);  // ... and on the GPU
  EXPECT_GT(std::stoull(last[8]), 0u);

  r = test::run_stipple("bench stream " + copc.string() +
                        " --frames 3 --width 320 --height 180 --samples " + csv.string() +
                        " --sample-seconds 600");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  rows = read_csv(csv);
  ASSERT_EQ(rows.size(), 3u);  // header, the first frame, the last
  EXPECT_EQ(rows[1][1], "1");
  EXPECT_EQ(rows[2][1], "3");

  // --duration ends a run of more frames than the time allows; the last row is its last frame.
  const fs::path json = fs::temp_directory_path() /
                        ("stipple_bench_duration_" + std::to_string(::getpid()) + ".json");
  r = test::run_stipple("bench stream " + copc.string() +
                        " --frames 1000000 --duration 2 --width 160 --height 90 --json " +
                        json.string() + " --samples " + csv.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto j = nlohmann::json::parse(std::ifstream(json));
  const auto frames = j["frames"].get<uint64_t>();
  EXPECT_LT(frames, 1000000u);
  EXPECT_EQ(j["frame_wall_ms"].size(), frames);
  rows = read_csv(csv);
  // header and the first frame (a slow first frame, e.g. under ASan, may use all 2 s)
  ASSERT_GE(rows.size(), 2u);
  EXPECT_EQ(std::stoull(rows.back()[1]), frames);
  EXPECT_GE(std::stod(rows.back()[0]), 2.0);
  EXPECT_LT(std::stod(rows.back()[0]), 60.0);
  fs::remove(csv);
  fs::remove(json);

  auto bad = test::run_stipple("bench stream " + copc.string() +
                               " --frames 1 --samples /nonexistent-dir/samples.csv");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("/nonexistent-dir/samples.csv"), std::string::npos) << bad.output;
}
