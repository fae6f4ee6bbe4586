#pragma once
// Shared helpers for tests: where the real LiDAR data lives, image statistics.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

// Helpers over a module are there only for tests that link it (each module's tests see only
// its own headers and those below).
#if __has_include("stipple/io/las.hpp")
#include "stipple/io/las.hpp"
#define STIPPLE_TEST_HAS_IO 1
#endif
#if __has_include("stipple/renderer/gpu.hpp")
#include "stipple/renderer/gpu.hpp"
#define STIPPLE_TEST_HAS_RENDERER 1
#endif

namespace stipple::test {

// ../shared/data beside the checkout, or STIPPLE_DATA_DIR; empty when absent.
inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("STIPPLE_DATA_DIR"); env && *env) return env;
  std::filesystem::path p = std::filesystem::path(STIPPLE_SOURCE_DIR) / ".." / "shared" / "data";
  return std::filesystem::exists(p) ? p : std::filesystem::path();
}

#define STIPPLE_REQUIRE_DATA(path_var, relative)                                 \
  auto path_var = ::stipple::test::data_dir() / (relative);                      \
  if (::stipple::test::data_dir().empty() || !std::filesystem::exists(path_var)) \
  GTEST_SKIP() << "test data " << (relative) << " not found (../shared/data is absent)"

#ifdef STIPPLE_TEST_HAS_RENDERER
struct CoverageStats {
  double coverage = 0;         // fraction of pixels that differ from the background
  double mean[3] = {0, 0, 0};  // mean RGB of covered pixels
  size_t covered = 0;
};

inline CoverageStats coverage_stats(const gpu::Image& image, const uint8_t background[3],
                                    int tolerance = 2) {
  CoverageStats s;
  size_t n = size_t(image.width) * image.height;
  double sum[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* p = &image.rgba[i * 4];
    bool bg = std::abs(p[0] - background[0]) <= tolerance &&
              std::abs(p[1] - background[1]) <= tolerance &&
              std::abs(p[2] - background[2]) <= tolerance;
    if (bg) continue;
    ++s.covered;
    for (int c = 0; c < 3; ++c) sum[c] += p[c];
  }
  s.coverage = double(s.covered) / double(n);
  for (int c = 0; c < 3; ++c) s.mean[c] = s.covered ? sum[c] / double(s.covered) : 0.0;
  return s;
}

// Fraction of pixels whose channels differ by more than `tolerance` between two images.
inline double differing_fraction(const gpu::Image& a, const gpu::Image& b, int tolerance) {
  if (a.width != b.width || a.height != b.height) return 1.0;
  size_t n = size_t(a.width) * a.height, diff = 0;
  for (size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c)
      if (std::abs(a.rgba[i * 4 + c] - b.rgba[i * 4 + c]) > tolerance) {
        ++diff;
        break;
      }
  return double(diff) / double(n);
}

#endif

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// Runs a shell command, capturing its output and exit code (128 + signal when killed).
inline CommandResult run_command(const std::string& command) {
  CommandResult r;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) r.output.append(buffer.data(), n);
  int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

// The `stipple` binary of this build with arguments.
inline CommandResult run_stipple(const std::string& args) {
  return run_command(std::string(STIPPLE_BINARY) + " " + args);
}

#ifdef STIPPLE_TEST_HAS_IO
// Mean 8-bit RGB of every point of a LAS/LAZ file whose 16-bit fields hold 8-bit values
// (autzen_trim); the reference that rendered images are compared with.
inline std::array<double, 3> mean_rgb(const std::filesystem::path& path, size_t* count = nullptr) {
  io::LasReader reader(path);
  io::PointBatch batch;
  while (reader.read(batch, 1 << 16)) {
  }
  std::array<double, 3> mean{0, 0, 0};
  for (auto c : batch.rgb) {
    mean[0] += c.r;
    mean[1] += c.g;
    mean[2] += c.b;
  }
  for (double& m : mean) m /= double(std::max<size_t>(1, batch.rgb.size()));
  if (count) *count = batch.rgb.size();
  return mean;
}

#endif

}  // namespace stipple::test
