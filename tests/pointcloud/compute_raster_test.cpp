// CPU side of the compute rasterizer: space-filling curves, quantization, batching, culling.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "stipple/io/procedural.hpp"
#include "stipple/pointcloud/batches.hpp"

using namespace stipple;

TEST(Curves, MortonInterleavesBits) {
  EXPECT_EQ(pc::morton_key(1, 0, 0), 4u);
  EXPECT_EQ(pc::morton_key(0, 1, 0), 2u);
  EXPECT_EQ(pc::morton_key(0, 0, 1), 1u);
  EXPECT_EQ(pc::morton_key(2, 0, 0), 32u);
  EXPECT_EQ(pc::morton_key(0x1fffff, 0x1fffff, 0x1fffff), (1ull << 63) - 1);
}

TEST(Curves, HilbertVisitsNeighboursInOrder) {
  // In an aligned 8^3 block the curve is a Hilbert curve of its own: consecutive keys are face
  // neighbours and every cell has its own key.
  std::vector<std::pair<uint64_t, glm::ivec3>> cells;
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) cells.push_back({pc::hilbert_key(x, y, z), {x, y, z}});
  std::sort(cells.begin(), cells.end(), [](auto& a, auto& b) { return a.first < b.first; });
  for (size_t i = 1; i < cells.size(); ++i) {
    ASSERT_NE(cells[i].first, cells[i - 1].first);
    glm::ivec3 d = glm::abs(cells[i].second - cells[i - 1].second);
    EXPECT_EQ(d.x + d.y + d.z, 1) << "step " << i;
  }
}

TEST(Quantize, PrecisionLevelsStayWithinTheirCell) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  glm::dvec3 min(500000.25, 120.5, -5100000.75), size(37.0, 12.5, 41.0);
  for (int i = 0; i < 1000; ++i) {
    glm::dvec3 p = min + size * glm::dvec3(u(rng), u(rng), u(rng));
    pc::QuantizedPoint q = pc::quantize(p, min, size);
    EXPECT_LT(q.coarse >> 30, 1u);
    for (int bits : {10, 20, 30}) {
      glm::dvec3 r = pc::dequantize(q, bits, min, size);
      for (int a = 0; a < 3; ++a)
        EXPECT_LE(std::abs(r[a] - p[a]), size[a] * std::ldexp(1.0, -bits) * 0.5 + 1e-9)
            << bits << " bits, axis " << a;
    }
  }
  // The far corner lands in the last cell, not beyond.
  pc::QuantizedPoint q = pc::quantize(min + size, min, size);
  EXPECT_EQ(q.coarse, 0x3fffffffu);
  EXPECT_EQ(q.fine, 0x3fffffffu);
}

namespace {
double mean_box_volume(const pc::BatchedCloud& c) {
  double v = 0;
  for (const auto& b : c.batches) v += b.size.x * b.size.y * b.size.z;
  return v / double(c.batches.size());
}
}  // namespace

TEST(Batches, CoverAllPointsWithVariableSizes) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 100.0);
  std::vector<glm::dvec3> positions(25'000);
  std::vector<uint32_t> colors(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    positions[i] = {u(rng), u(rng) * 0.2, u(rng)};
    colors[i] = uint32_t(i);
  }
  for (auto order : {pc::SpatialOrder::None, pc::SpatialOrder::Morton, pc::SpatialOrder::Hilbert}) {
    pc::BatchedCloud c;
    pc::append_batches(c, positions, colors, order, 1000);
    ASSERT_EQ(c.batches.size(), 25u);
    uint64_t next = 0;
    std::set<uint32_t> seen;
    for (const auto& b : c.batches) {
      EXPECT_EQ(b.first, next);
      next += b.count;
      for (uint64_t i = b.first; i < b.first + b.count; ++i) {
        seen.insert(c.color[i]);
        glm::dvec3 p = pc::dequantize({c.coarse[i], c.medium[i], c.fine[i]}, 30, b.min, b.size);
        EXPECT_NEAR(glm::length(p - positions[c.color[i]]), 0.0, 1e-6);
      }
    }
    EXPECT_EQ(next, positions.size());
    EXPECT_EQ(seen.size(), positions.size());
  }
  // A second, smaller run appended: batches of varying size in one layout (LOD nodes).
  pc::BatchedCloud c;
  pc::append_batches(c, positions, colors, pc::SpatialOrder::Morton, 10'240);
  pc::append_batches(c, std::span(positions).first(300), std::span(colors).first(300),
                     pc::SpatialOrder::Morton, 128);
  ASSERT_EQ(c.batches.size(), 3u + 3u);
  EXPECT_EQ(c.batches[2].count, 25'000u - 2 * 10'240u);
  EXPECT_EQ(c.batches[3].first, 25'000u);
  EXPECT_EQ(c.batches[5].count, 300u - 256u);
  EXPECT_EQ(c.point_count(), 25'300u);
}

TEST(Batches, SpatialOrderMakesCompactBoxes) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1000.0);
  std::vector<glm::dvec3> positions(100'000);
  std::vector<uint32_t> colors(positions.size(), 0);
  for (auto& p : positions) p = {u(rng), u(rng) * 0.01, u(rng)};
  pc::BatchedCloud none, morton, hilbert;
  pc::append_batches(none, positions, colors, pc::SpatialOrder::None, 1000);
  pc::append_batches(morton, positions, colors, pc::SpatialOrder::Morton, 1000);
  pc::append_batches(hilbert, positions, colors, pc::SpatialOrder::Hilbert, 1000);
  // 100 batches: ideally 1 % of the volume each; random order fills the whole box.
  EXPECT_LT(mean_box_volume(morton), mean_box_volume(none) * 0.05);
  EXPECT_LT(mean_box_volume(hilbert), mean_box_volume(none) * 0.05);
}

TEST(Batches, GeneratedSceneIsDeterministicAndCompact) {
  io::SceneParams params;
  params.point_count = 1'500'000;
  auto a = pc::generate_batched_scene(params, pc::SpatialOrder::Morton);
  auto b = pc::generate_batched_scene(params, pc::SpatialOrder::Morton);
  ASSERT_EQ(a.point_count(), params.point_count);
  EXPECT_EQ(a.batches.size(), b.batches.size());
  EXPECT_EQ(a.coarse, b.coarse);
  EXPECT_EQ(a.fine, b.fine);
  EXPECT_EQ(a.color, b.color);
  uint64_t next = 0;
  double extent = 0;
  for (const auto& batch : a.batches) {
    ASSERT_EQ(batch.first, next);
    next += batch.count;
    extent += std::max(batch.size.x, batch.size.z);
  }
  EXPECT_EQ(next, params.point_count);
  // 10,240 points at 12 per square metre cover ~850 m^2: boxes of tens of metres, not the
  // scene's 350 m flight lines.
  double scene = io::scene_size(params);
  EXPECT_LT(extent / double(a.batches.size()), scene * 0.25);
}

// A whole cloud of millions of points is sorted and batched on every core; the result is the
// one a plain sort gives (same total order: 30-bit curve key, then index), word for word.
TEST(Batches, ParallelBatchingEqualsTheSequentialSort) {
  const size_t n = 3'000'000;  // over the parallel threshold
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<glm::dvec3> positions(n);
  std::vector<uint32_t> colors(n), attributes(n);
  for (size_t i = 0; i < n; ++i) {
    // Clustered, with duplicates, so keys tie.
    positions[i] = {std::floor(u(rng) * 3000) * 0.1, std::floor(u(rng) * 500) * 0.1,
                    u(rng) < 0.5 ? 5.0 : u(rng) * 30};
    colors[i] = uint32_t(i);
    attributes[i] = uint32_t(i) * 2654435761u;
  }
  pc::BatchedCloud out;
  pc::BatchBuildStats stats;
  pc::BatchingOptions options;
  options.stats = &stats;
  pc::append_batches(out, positions, colors, attributes, options);
  EXPECT_EQ(stats.refined_cells, 0u);  // no cell holds a batch: the plain order below applies
  // The reference: keys over the bounds, a plain sort of (key, index), batches of 10240.
  Aabb box;
  for (const auto& p : positions) box.extend(p);
  const double extent = std::max({box.size().x, box.size().y, box.size().z});
  std::vector<std::pair<uint32_t, uint32_t>> keyed(n);
  for (size_t i = 0; i < n; ++i) {
    const glm::dvec3 c = glm::floor((positions[i] - box.min) * (1024.0 / extent));
    const auto cell = [](double v) { return uint32_t(std::clamp(v, 0.0, 1023.0)); };
    keyed[i] = {uint32_t(pc::morton_key(cell(c.x), cell(c.y), cell(c.z))), uint32_t(i)};
    ASSERT_EQ(keyed[i].first,
              pc::curve_key30(positions[i], box.min, extent, pc::SpatialOrder::Morton));
  }
  std::sort(keyed.begin(), keyed.end());
  ASSERT_EQ(out.point_count(), n);
  ASSERT_EQ(out.batches.size(), (n + pc::kBatchPoints - 1) / pc::kBatchPoints);
  size_t wrong = 0;
  for (size_t b = 0; b < out.batches.size(); ++b) {
    const pc::Batch& batch = out.batches[b];
    ASSERT_EQ(batch.first, b * pc::kBatchPoints);
    Aabb expected;
    for (uint32_t k = 0; k < batch.count; ++k)
      expected.extend(positions[keyed[batch.first + k].second]);
    wrong += batch.min != expected.min || batch.size != expected.size();
    for (uint32_t k = 0; k < batch.count; ++k) {
      const size_t i = batch.first + k;
      const uint32_t src = keyed[i].second;
      const auto q = pc::quantize(positions[src], batch.min, batch.size);
      wrong += out.color[i] != src || out.attributes[i] != attributes[src] ||
               out.coarse[i] != q.coarse || out.medium[i] != q.medium || out.fine[i] != q.fine;
    }
  }
  EXPECT_EQ(wrong, 0u);
}

// A far outlier stretches the curve's cube so that the real points crowd into a few of its
// cells: those cells are ordered again inside their own boxes, so the batches stay compact, and
// the parallel build gives the same words as the one on one thread.
TEST(Batches, OverfullCellsAreOrderedInTheirOwnBoxes) {
  const size_t n = 1'500'000;  // over the parallel threshold
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<glm::dvec3> positions(n);
  std::vector<uint32_t> colors(n);
  for (size_t i = 0; i < n; ++i) {
    positions[i] = {u(rng) * 200.0, u(rng) * 2.0, u(rng) * 200.0};  // a 200 m tile
    colors[i] = uint32_t(i);
  }
  positions[n / 2] = {-1.0e6, 0.0, 0.0};  // a stray point 1000 km away
  pc::BatchedCloud parallel, serial;
  pc::BatchBuildStats stats;
  pc::BatchingOptions options;
  options.stats = &stats;
  pc::append_batches(parallel, positions, colors, {}, options);
  options.parallel = false;
  options.stats = nullptr;
  pc::append_batches(serial, positions, colors, {}, options);
  EXPECT_GT(stats.refined_cells, 0u);
  EXPECT_EQ(parallel.color, serial.color);
  EXPECT_EQ(parallel.coarse, serial.coarse);
  EXPECT_EQ(parallel.fine, serial.fine);
  // Without refinement the tile fills one cell of the 1000 km cube: batches in index order,
  // each spanning the whole tile (40,000 m^2). Ordered inside the cell, a batch of 10,240 of
  // the tile's 1.5M points covers about 1/146 of it (~270 m^2); allow four times that.
  double area = 0;
  size_t counted = 0;
  for (const auto& b : parallel.batches) {
    if (b.size.x > 1000.0) continue;  // the one batch holding the outlier
    area += b.size.x * b.size.z;
    ++counted;
  }
  ASSERT_GT(counted, 0u);
  EXPECT_LT(area / double(counted), 4.0 * 40'000.0 / (double(n) / pc::kBatchPoints));
}

TEST(Culling, ClassifiesAndChoosesPrecision) {
  Camera camera;
  camera.fov_y = glm::radians(60.0);
  camera.look_at({0, 0, 0}, {0, 0, -10});
  pc::CullSettings s{640, 360};
  glm::mat4 vp = pc::raster_view_proj(camera, s.width, s.height);
  // In front, small: 10 bits.
  auto v = pc::classify_batch(vp, {-0.5f, -0.5f, -100.5f}, {1, 1, 1}, s);
  EXPECT_TRUE(v.visible);
  EXPECT_EQ(v.bits, 10);
  EXPECT_GT(v.size_px, 2.0f);
  EXPECT_LT(v.size_px, 5.0f);
  // Behind the camera, and off to the side: culled.
  EXPECT_FALSE(pc::classify_batch(vp, {-0.5f, -0.5f, 10.0f}, {1, 1, 1}, s).visible);
  EXPECT_FALSE(pc::classify_batch(vp, {500.0f, -0.5f, -100.0f}, {1, 1, 1}, s).visible);
  // Around the camera: reaches behind the near plane, so full precision.
  v = pc::classify_batch(vp, {-5, -5, -5}, {10, 10, 10}, s);
  EXPECT_TRUE(v.visible);
  EXPECT_EQ(v.bits, 30);
  // Large on screen but in front: 20 bits.
  v = pc::classify_batch(vp, {-2, -2, -3}, {4, 4, 1}, s);
  EXPECT_EQ(v.bits, 20);
  // LOD: small batches are skipped, and forced precision wins.
  s.min_batch_px = 10.0f;
  v = pc::classify_batch(vp, {-0.5f, -0.5f, -100.5f}, {1, 1, 1}, s);
  EXPECT_FALSE(v.visible);
  EXPECT_TRUE(v.lod_skip);
  s.min_batch_px = 0;
  s.force_bits = 30;
  EXPECT_EQ(pc::classify_batch(vp, {-0.5f, -0.5f, -100.5f}, {1, 1, 1}, s).bits, 30);
}
