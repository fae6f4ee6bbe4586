// `stipple bench` runs end to end and writes well-formed results (no timing is asserted).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>

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
