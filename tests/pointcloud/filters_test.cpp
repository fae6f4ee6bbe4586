// Filters and clip regions on the CPU (the definitions the shaders mirror), and picking that
// passes over hidden points.
#include <gtest/gtest.h>

#include <cmath>

#include "stipple/core/error.hpp"
#include "stipple/math/camera.hpp"
#include "stipple/pointcloud/filters.hpp"
#include "stipple/pointcloud/picking.hpp"
#include "stipple/pointcloud/profile.hpp"

using namespace stipple;
using namespace stipple::pc;

TEST(Filters, ReturnKinds) {
  // (return number, number of returns) of first, last, single and intermediate returns.
  EXPECT_TRUE(return_kind_matches(kReturnFirst, 1, 3));
  EXPECT_FALSE(return_kind_matches(kReturnFirst, 2, 3));
  EXPECT_TRUE(return_kind_matches(kReturnLast, 3, 3));
  EXPECT_TRUE(return_kind_matches(kReturnSingle, 1, 1));
  EXPECT_FALSE(return_kind_matches(kReturnSingle, 1, 2));
  EXPECT_TRUE(return_kind_matches(kReturnIntermediate, 2, 3));
  EXPECT_FALSE(return_kind_matches(kReturnIntermediate, 3, 3));
  EXPECT_TRUE(return_kind_matches(kReturnFirst | kReturnLast, 3, 3));
  EXPECT_TRUE(return_kind_matches(0, 2, 3));
}

TEST(Filters, ParsedClassesAndRanges) {
  PointFilter f;
  f.classes = parse_classes("2, 5-6,255", "--classes");
  EXPECT_TRUE(f.class_kept(2));
  EXPECT_TRUE(f.class_kept(5));
  EXPECT_TRUE(f.class_kept(6));
  EXPECT_TRUE(f.class_kept(255));
  EXPECT_FALSE(f.class_kept(3));
  EXPECT_FALSE(f.class_kept(7));
  EXPECT_TRUE(f.active());
  f.intensity = parse_range("10,20", "--intensity");
  EXPECT_TRUE(f.accepts(2, 1, 1, 15, 0, 0));
  EXPECT_FALSE(f.accepts(2, 1, 1, 21, 0, 0));
  EXPECT_FALSE(f.accepts(3, 1, 1, 15, 0, 0));
  EXPECT_THROW(parse_classes("1,-2", "--classes"), Error);
  EXPECT_THROW(parse_classes("300", "--classes"), Error);
  EXPECT_THROW(parse_range("3,1", "--x"), Error);
  EXPECT_THROW(parse_box("1,1,1,0,2,2", "--box"), Error);
  EXPECT_THROW(parse_plane("0,0,0,1", "--plane"), Error);
}

TEST(Filters, RotatedBoxPolygonWithHoleAndPlanes) {
  // A 10 x 2 box turned 90 degrees: long along Y.
  ClipBox box = parse_box("-5,-1,-1,5,1,1,90", "--box");
  EXPECT_TRUE(box.contains({0.5, 4.5, 0}));
  EXPECT_FALSE(box.contains({4.5, 0.5, 0}));
  const auto corners = box.corners();
  for (const glm::dvec3& c : corners) EXPECT_NEAR(std::abs(c.x), 1.0, 1e-9);
  ClipPolygon square{
      {{{0, 0}, {10, 0}, {10, 10}, {0, 10}}, {{4, 4}, {6, 4}, {6, 6}, {4, 6}}}, 0, 100};
  EXPECT_TRUE(square.contains({1, 1, 50}));
  EXPECT_FALSE(square.contains({5, 5, 50}));   // in the hole
  EXPECT_FALSE(square.contains({1, 1, 101}));  // above the extrusion
  ClipRegion region;
  region.polygons = {square};
  region.planes = {parse_plane("1,0,0,-2", "--plane")};  // x >= 2
  EXPECT_FALSE(region.contains({1, 1, 50}));
  EXPECT_TRUE(region.contains({3, 1, 50}));
  region.mode = ClipMode::Outside;
  EXPECT_TRUE(region.keeps({1, 1, 50}));
  region.mode = ClipMode::Highlight;
  EXPECT_TRUE(region.keeps({1, 1, 50}));
}

TEST(Filters, PickingPassesOverHiddenPoints) {
  // Two points on the ray: a nearer building point (class 6) and a farther ground point.
  PointChunk chunk;
  chunk.origin = glm::dvec3(0.0);
  chunk.vertices.push_back({0, 0, -5, 0, pack_attributes(0, 6, 1, 1)});
  chunk.vertices.push_back({0, 0, -9, 0, pack_attributes(0, 2, 1, 1)});
  chunk.first_point = 100;
  Aabb bounds;
  bounds.extend({0, 0, -9});
  bounds.extend({0, 0, -5});
  const PickRay ray{{0, 0, 0}, {0, 0, -1}, 0.01};
  std::optional<PickHit> hit;
  pick_in_chunk(chunk, bounds, ray, hit);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->source_point, 100u);
  PickFilter filter;
  filter.filter.set_class(6, false);
  hit.reset();
  pick_in_chunk(chunk, bounds, ray, hit, &filter);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->source_point, 101u);
  EXPECT_EQ((hit->vertex.attributes >> 16) & 0xffu, 2u);
  // A clip box around the nearer point only, kept outside: the farther one again.
  PickFilter clip;
  clip.clip.boxes.push_back({y_up_to_z_up({0, 0, -5}), glm::dvec3(1.0), 0.0});
  clip.clip.mode = ClipMode::Outside;
  hit.reset();
  pick_in_chunk(chunk, bounds, ray, hit, &clip);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->source_point, 101u);
}

TEST(Profile, CorridorDistanceAlongAndOffset) {
  const ProfileLine line = parse_profile_line("0,0,10,0,10,10", 2.0);
  EXPECT_DOUBLE_EQ(line.length(), 20.0);
  auto hit = line.locate({4, 0.5});
  ASSERT_TRUE(hit);
  EXPECT_DOUBLE_EQ(hit->along, 4.0);
  EXPECT_DOUBLE_EQ(hit->offset, 0.5);  // left of the line's direction
  hit = line.locate({10.5, 5});
  ASSERT_TRUE(hit);
  EXPECT_DOUBLE_EQ(hit->along, 15.0);
  EXPECT_DOUBLE_EQ(hit->offset, -0.5);  // right of the second segment
  EXPECT_FALSE(line.locate({4, 1.5}));
  // Round ends: within W/2 of the end point, beyond the segment.
  EXPECT_TRUE(line.locate({-0.6, 0.6}));
  EXPECT_FALSE(line.locate({-0.8, 0.8}));
}
