#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

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

namespace {

// Each point's normalized device coordinates under `camera` (w > 0 asserted by the caller).
glm::dvec4 clip(const Camera& camera, double aspect, const glm::dvec3& p) {
  return camera.view_projection(aspect) * glm::dvec4(p, 1.0);
}

}  // namespace

// ViewFit: every point lands inside the view less the margin (5% of each side for a 320x180
// image), the binding pair of sides is touched exactly (to 1e-9 of the half-width) and the
// data's projected extent is centred on both axes; the result does not depend on the order.
TEST(Camera, ViewFitFillsTheViewToTheMargin) {
  const uint32_t w = 320, h = 180;
  const double aspect = double(w) / h;
  std::vector<glm::dvec3> points;
  uint32_t seed = 12345;
  auto next = [&] { return (seed = seed * 1664525u + 1013904223u) / 4294967296.0; };
  // A flat scan far from the origin (a UTM-like offset), with a few tall points.
  for (int i = 0; i < 2000; ++i)
    points.push_back(z_up_to_y_up({500000.0 + 300.0 * next(), 5000000.0 + 120.0 * next(),
                                   100.0 + (i % 97 == 0 ? 40.0 : 3.0) * next()}));
  for (bool reversed : {false, true}) {
    ViewFit fit(w, h, 30.0, 40.0, 50.0);
    if (reversed)
      for (auto it = points.rbegin(); it != points.rend(); ++it) fit.add(*it);
    else
      for (const auto& p : points) fit.add(p);
    const Camera camera = fit.camera();
    double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
    for (const auto& p : points) {
      const glm::dvec4 c = clip(camera, aspect, p);
      ASSERT_GT(c.w, 0.0);
      x0 = std::min(x0, c.x / c.w), x1 = std::max(x1, c.x / c.w);
      y0 = std::min(y0, c.y / c.w), y1 = std::max(y1, c.y / c.w);
    }
    const double limit = 0.9;  // 1 - 2 * 5%
    EXPECT_GE(x0, -limit - 1e-9);
    EXPECT_LE(x1, limit + 1e-9);
    EXPECT_GE(y0, -limit - 1e-9);
    EXPECT_LE(y1, limit + 1e-9);
    // As close as the margin allows: one axis spans the full 90%.
    EXPECT_NEAR(std::max(x1 - x0, y1 - y0), 2.0 * limit, 1e-9);
    EXPECT_NEAR(x0 + x1, 0.0, 1e-9);
    EXPECT_NEAR(y0 + y1, 0.0, 1e-9);
  }
}

// A box whose corners cannot widen the fit holds no point that can; one that reaches far past
// the fitted data can (a point just outside a face may still project inside the silhouette).
TEST(Camera, ViewFitSkipsBoxesInside) {
  ViewFit fit(200, 200);
  fit.add_corners({{-10, -10, -10}, {10, 10, 10}});
  EXPECT_FALSE(fit.could_widen({{-1, -1, -1}, {1, 1, 1}}));
  EXPECT_FALSE(fit.could_widen({{-10, -10, -10}, {10, 10, 10}}));
  EXPECT_TRUE(fit.could_widen({{-1, -1, -1}, {100, 1, 1}}));
  EXPECT_TRUE(fit.could_widen({{-1, -100, -1}, {1, 1, 1}}));
  EXPECT_FALSE(fit.could_widen(Aabb{}));
}

// Points on a line along the view direction (seen end-on): the eye stays in front of them all,
// not on the nearest one.
TEST(Camera, ViewFitOfALineSeenEndOnKeepsEveryPointInFront) {
  ViewFit fit(100, 100, 0.0, 90.0);  // looking straight down: a vertical line is seen end-on
  for (int i = 0; i < 10; ++i) fit.add(z_up_to_y_up({5.0, 7.0, 10.0 * i}));
  const Camera camera = fit.camera();
  for (int i = 0; i < 10; ++i) {
    const glm::dvec3 p = z_up_to_y_up({5.0, 7.0, 10.0 * i});
    const double depth = glm::dot(camera.forward(), p - camera.position);
    EXPECT_GT(depth, camera.near_plane) << i;
  }
}
