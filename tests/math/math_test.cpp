#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include "stipple/math/camera.hpp"
#include "stipple/math/geo.hpp"

using namespace stipple;

TEST(Geo, GeodeticEcefRoundTrip) {
  // Known point: 0 lon, 0 lat, 0 h is (a, 0, 0).
  glm::dvec3 e = geo::geodetic_to_ecef({0, 0, 0});
  EXPECT_NEAR(e.x, geo::kWgs84A, 1e-6);
  EXPECT_NEAR(e.y, 0, 1e-6);
  EXPECT_NEAR(e.z, 0, 1e-6);
  // North pole: z is the semi-minor axis b = a(1-f).
  glm::dvec3 pole = geo::geodetic_to_ecef({0, 90, 0});
  EXPECT_NEAR(pole.z, geo::kWgs84A * (1 - geo::kWgs84F), 1e-6);
  for (glm::dvec3 llh : {glm::dvec3(-123.07, 44.05, 130.0), glm::dvec3(151.2, -33.9, 5.0),
                         glm::dvec3(13.4, 52.5, 2000.0)}) {
    glm::dvec3 back = geo::ecef_to_geodetic(geo::geodetic_to_ecef(llh));
    EXPECT_NEAR(back.x, llh.x, 1e-9);
    EXPECT_NEAR(back.y, llh.y, 1e-9);
    EXPECT_NEAR(back.z, llh.z, 1e-4);
  }
}

TEST(Geo, LocalEnuIsMetric) {
  geo::LocalEnu enu({-123.0, 44.0, 0.0});
  glm::dvec3 origin = enu.from_geodetic({-123.0, 44.0, 0.0});
  EXPECT_NEAR(glm::length(origin), 0.0, 1e-6);
  // One arc-second of latitude is about 30.9 m at 44 degrees north, pointing north.
  glm::dvec3 north = enu.from_geodetic({-123.0, 44.0 + 1.0 / 3600.0, 0.0});
  EXPECT_NEAR(north.y, 30.87, 0.05);
  EXPECT_NEAR(north.x, 0.0, 1e-6);
  glm::dvec3 up = enu.from_geodetic({-123.0, 44.0, 10.0});
  EXPECT_NEAR(up.z, 10.0, 1e-6);
}

TEST(Camera, ReverseZProjection) {
  Camera camera;
  camera.look_at({0, 0, 10}, {0, 0, 0});
  camera.near_plane = 0.5;
  glm::dmat4 vp = camera.view_projection(1.0);
  auto depth = [&](glm::dvec3 p) {
    glm::dvec4 c = vp * glm::dvec4(p, 1.0);
    return c.z / c.w;
  };
  // Depth is near/distance: 1 at the near plane, falling towards 0 at infinity.
  EXPECT_NEAR(depth({0, 0, 9.5}), 1.0, 1e-12);
  EXPECT_NEAR(depth({0, 0, 0}), 0.05, 1e-12);
  EXPECT_GT(depth({0, 0, 5}), depth({0, 0, -5}));
  // The target is in the centre of the view.
  glm::dvec4 c = vp * glm::dvec4(0, 0, 0, 1);
  EXPECT_NEAR(c.x / c.w, 0.0, 1e-12);
  EXPECT_NEAR(c.y / c.w, 0.0, 1e-12);
}

TEST(Camera, CameraRelativeMatchesFullTransform) {
  // Eq. 5: R^T (p - c) computed with the subtraction in double equals the full transform.
  Camera camera;
  glm::dvec3 eye(6378137.0 + 120.0, 15.0, -40.0);
  camera.look_at(eye, eye + glm::dvec3(-1, -0.2, 0.3));
  glm::dvec3 p = eye + glm::dvec3(-30.0, 2.0, 5.0);
  glm::dvec4 full = camera.view_projection(1.5) * glm::dvec4(p, 1.0);
  glm::dvec4 relative =
      camera.projection(1.5) * camera.view_rotation() * glm::dvec4(p - camera.position, 1.0);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(full[i], relative[i], 1e-6);
}

// One point (or every point at one location): framed as a few metres around it, not from a
// thousandth of a millimetre (where nothing showed).
TEST(Camera, FrameBoxOfAPointFramesAFewMetres) {
  Aabb box;
  box.extend(glm::dvec3(512345.5, 321.0, -5123456.5));
  Camera camera = frame_box(box, 16.0 / 9.0);
  const double distance = glm::length(camera.position - box.center());
  EXPECT_GT(distance, 2.0);
  EXPECT_LT(distance, 20.0);
  glm::dvec4 c = camera.view_projection(16.0 / 9.0) * glm::dvec4(box.center(), 1.0);
  EXPECT_NEAR(c.x / c.w, 0.0, 1e-6);
  EXPECT_NEAR(c.y / c.w, 0.0, 1e-6);
  EXPECT_GT(c.z / c.w, 0.0);  // in front of the near plane (reverse Z: 0 at infinity)
}

TEST(Camera, FrameBoxKeepsBoxInView) {
  Aabb box;
  box.min = {-100, 0, -50};
  box.max = {100, 30, 50};
  Camera camera = frame_box(box, 16.0 / 9.0);
  glm::dmat4 vp = camera.view_projection(16.0 / 9.0);
  for (int i = 0; i < 8; ++i) {
    glm::dvec3 corner((i & 1) ? box.max.x : box.min.x, (i & 2) ? box.max.y : box.min.y,
                      (i & 4) ? box.max.z : box.min.z);
    glm::dvec4 c = vp * glm::dvec4(corner, 1.0);
    ASSERT_GT(c.w, 0.0);
    EXPECT_LE(std::abs(c.x / c.w), 1.0);
    EXPECT_LE(std::abs(c.y / c.w), 1.0);
  }
}
