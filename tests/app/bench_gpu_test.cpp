// `stipple bench` runs end to end and writes well-formed results (no timing is asserted).
#include <gtest/gtest.h>

#include <sys/wait.h>

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
