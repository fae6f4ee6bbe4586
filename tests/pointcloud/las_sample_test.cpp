// pc::read_las_sample, the first image of render --progressive: about the points asked for,
// spread across the whole file. LAS: single records at a stride, so the sample's first and last
// points are the file's first and (nearly) last; LAZ: points from every chunk, found through
// the chunk table, so every chunk's first point is in the sample.
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "scene_las.hpp"

#include "stipple/io/las.hpp"
#include "stipple/pointcloud/point_cloud.hpp"

using namespace stipple;
namespace fs = std::filesystem;

namespace {

std::vector<glm::dvec3> all_positions(const fs::path& path) {
  io::LasReader reader(path);
  std::vector<glm::dvec3> out;
  while (reader.read_positions(out, 1 << 16) > 0) {
  }
  return out;
}

std::vector<glm::dvec3> sample_positions(const fs::path& path, uint64_t want, uint64_t* read) {
  io::LasReader reader(path);
  std::vector<glm::dvec3> out;
  *read = pc::read_las_sample(reader, want, [&](io::PointBatch& b) {
    out.insert(out.end(), b.positions.begin(), b.positions.end());
  });
  return out;
}

}  // namespace

TEST(LasSample, LasTakesRecordsAtAStride) {
  const fs::path dir = fs::temp_directory_path() / ("stipple-sample-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path path = test::write_scene_las(dir / "scene.las", 120000);
  const std::vector<glm::dvec3> all = all_positions(path);
  uint64_t read = 0;
  const std::vector<glm::dvec3> sample = sample_positions(path, 1000, &read);
  ASSERT_EQ(sample.size(), 1000u);
  EXPECT_EQ(read, 1000u);
  // Record i * 120 for i < 1000.
  for (size_t i = 0; i < sample.size(); i += 111) EXPECT_EQ(sample[i], all[i * 120]) << i;
  EXPECT_EQ(sample.back(), all[999 * 120]);
  // Asking for more than there is reads everything, in order.
  EXPECT_EQ(sample_positions(path, 1000000, &read), all);
  EXPECT_EQ(read, all.size());
  fs::remove_all(dir);
}

TEST(LasSample, LazTakesPointsFromEveryChunk) {
  const fs::path dir =
      fs::temp_directory_path() / ("stipple-sample-laz-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path path = test::write_scene_las(dir / "scene.laz", 230000, true);
  const uint32_t chunk = io::read_las_header(path).laz_chunk_points;
  ASSERT_GT(chunk, 0u);
  const uint64_t chunks = (230000 + chunk - 1) / chunk;
  ASSERT_GE(chunks, 3u);
  const std::vector<glm::dvec3> all = all_positions(path);
  uint64_t read = 0;
  const std::vector<glm::dvec3> sample = sample_positions(path, 100 * chunks, &read);
  // 100 of every chunk: every 8th of its first 800 points.
  EXPECT_EQ(sample.size(), 100 * chunks);
  EXPECT_EQ(read, sample.size());
  for (uint64_t c = 0; c < chunks; ++c) {
    EXPECT_EQ(sample[c * 100], all[c * chunk]) << c;
    EXPECT_EQ(sample[c * 100 + 99], all[c * chunk + 99 * 8]) << c;
  }
  // A third of every chunk: every 3rd point of as much as it has of 3 times that (the batches
  // handed on in between do not change which).
  const uint64_t per = chunk / 3, thin = 3;
  const std::vector<glm::dvec3> large = sample_positions(path, per * chunks, &read);
  size_t at = 0;
  for (uint64_t c = 0; c < chunks; ++c) {
    const uint64_t length = std::min<uint64_t>(per * thin, 230000 - c * chunk);
    for (uint64_t k = 0; k < length; k += thin, ++at) {
      ASSERT_LT(at, large.size());
      ASSERT_EQ(large[at], all[c * chunk + k]) << c << " " << k;
    }
  }
  EXPECT_EQ(at, large.size());
  EXPECT_EQ(read, large.size());
  fs::remove_all(dir);
}
