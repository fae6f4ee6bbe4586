// Tile content with alpha (issue 44): what reaches the renderers. The file's alpha is kept in
// the chunks' colours where it means something (PointContent::alpha), fully transparent points
// are left out, the cloud says it has translucent points, and its LOD batches mark them for the
// compute rasterizer; content without alpha stays opaque and unmarked.
#include <gtest/gtest.h>

#include <glm/mat4x4.hpp>

#include "stipple/io/pnts.hpp"
#include "stipple/pointcloud/batches.hpp"
#include "stipple/tiles3d/tile_chunks.hpp"

using namespace stipple;

namespace {

// `n` points on a line, colour `rgba(i)`.
template <typename Rgba>
io::PointContent line_content(size_t n, bool alpha, Rgba rgba) {
  io::PointContent c;
  c.point_count = n;
  c.format = "pnts";
  c.alpha = alpha;
  for (size_t i = 0; i < n; ++i) {
    c.positions.push_back({float(i), 0.0f, 0.0f});
    c.rgba.push_back(rgba(i));
  }
  return c;
}

uint32_t rgba(uint32_t r, uint32_t g, uint32_t b, uint32_t a) {
  return r | g << 8 | b << 16 | a << 24;
}

}  // namespace

TEST(TranslucentContent, AlphaIsKeptMarkedAndZeroIsLeftOut) {
  // Alpha cycles through 0 (left out), 51 (translucent) and 255 (opaque).
  const uint32_t alphas[3] = {0, 51, 255};
  std::vector<io::PointContent> contents = {
      line_content(30, true, [&](size_t i) { return rgba(200, 100, 50, alphas[i % 3]); })};
  auto tile = tiles3d::make_tile_chunks(7, glm::dmat4(1.0), glm::dmat4(1.0), contents, true);
  EXPECT_EQ(tile->transparent_points, 10u);
  EXPECT_EQ(tile->points, 20u);
  EXPECT_TRUE(tile->attributes.has_translucent);
  size_t translucent = 0, opaque = 0;
  for (const auto& chunk : tile->chunks)
    for (const auto& v : chunk.vertices) {
      EXPECT_EQ(v.rgba & 0xffffffu, rgba(200, 100, 50, 0));
      translucent += (v.rgba >> 24) == 51;
      opaque += (v.rgba >> 24) == 255;
    }
  EXPECT_EQ(translucent, 10u);
  EXPECT_EQ(opaque, 10u);
  // The batches mark exactly the translucent points, whose positions stay in the low 30 bits.
  ASSERT_TRUE(tile->batches);
  const pc::BatchedCloud& b = *tile->batches;
  ASSERT_EQ(b.point_count(), 20u);
  for (size_t i = 0; i < b.point_count(); ++i) {
    const bool marked = (b.coarse[i] & pc::kTranslucentBit) != 0;
    EXPECT_EQ(marked, (b.color[i] >> 24) == 51) << i;
    EXPECT_EQ(b.coarse[i] >> 31, 0u) << i;
  }
}

TEST(TranslucentContent, ContentWithoutAlphaIsOpaqueAndUnmarked) {
  // PointContent::alpha off (pnts RGB, glb OPAQUE): whatever the alpha byte, opaque.
  std::vector<io::PointContent> contents = {
      line_content(12, false, [](size_t i) { return rgba(10, 20, 30, uint32_t(i * 20)); })};
  auto tile = tiles3d::make_tile_chunks(1, glm::dmat4(1.0), glm::dmat4(1.0), contents, true);
  EXPECT_EQ(tile->points, 12u);
  EXPECT_EQ(tile->transparent_points, 0u);
  EXPECT_FALSE(tile->attributes.has_translucent);
  for (const auto& chunk : tile->chunks)
    for (const auto& v : chunk.vertices) EXPECT_EQ(v.rgba >> 24, 255u);
  ASSERT_TRUE(tile->batches);
  for (uint32_t c : tile->batches->coarse) EXPECT_EQ(c & pc::kTranslucentBit, 0u);
}

TEST(TranslucentContent, CloudsWithoutTranslucencyAreNotMarked) {
  // LAS points without RGB have alpha 0: a cloud that does not say it has translucent points
  // is batched as before, word for word.
  pc::PointCloud cloud;
  pc::PointChunk chunk;
  for (int i = 0; i < 50; ++i) chunk.vertices.push_back({float(i), 0.0f, float(i % 7), 0u, 0u});
  cloud.chunks.push_back(chunk);
  cloud.point_count = 50;
  const pc::BatchedCloud plain = pc::build_batches(cloud);
  for (uint32_t c : plain.coarse) EXPECT_EQ(c & pc::kTranslucentBit, 0u);
  cloud.attributes.has_translucent = true;
  const pc::BatchedCloud marked = pc::build_batches(cloud);
  ASSERT_EQ(marked.coarse.size(), plain.coarse.size());
  for (size_t i = 0; i < plain.coarse.size(); ++i)
    EXPECT_EQ(marked.coarse[i], plain.coarse[i] | pc::kTranslucentBit);
}
