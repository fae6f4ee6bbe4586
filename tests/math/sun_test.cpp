#include <gtest/gtest.h>

#include <cmath>

#include <glm/geometric.hpp>

#include "stipple/core/error.hpp"
#include "stipple/math/sun.hpp"

using namespace stipple;

namespace {

struct Reference {
  const char* place;
  double lat, lon;
  int year, month, day;
  double hour_utc;
  double elevation, azimuth, equation_of_time, declination;
};

// NREL's Solar Position Algorithm (pvlib 0.16.1, method nrel_numpy, 1013.25 hPa, 10 C,
// delta T 67 s): apparent elevation, azimuth, equation of time (minutes), declination. NOAA's
// formulas are good to about 0.01-0.02 degrees against it in this century.
const Reference kReferences[] = {
    {"Boulder, solstice", 40.015, -105.2705, 2026, 6, 21, 19.0, 73.4148, 177.6190, -1.878, 23.4373},
    {"Sydney, solstice", -33.8688, 151.2093, 2026, 12, 21, 2.0, 79.4578, 351.2196, 2.145, -23.4350},
    {"Helsinki, equinox sunrise", 60.1699, 24.9384, 2026, 3, 20, 5.0, 4.0508, 97.0812, -7.519,
     -0.1608},
    {"February EoT minimum", 45.0, 15.0, 2026, 2, 11, 12.0, 30.1893, 192.8835, -14.172, -13.9272},
    {"November EoT maximum", 45.0, 15.0, 2026, 11, 3, 12.0, 27.4236, 200.8513, 16.450, -15.1510},
};

}  // namespace

TEST(Sun, MatchesTheSolarPositionAlgorithm) {
  for (const Reference& r : kReferences) {
    SCOPED_TRACE(r.place);
    const double jd = solar::julian_day(r.year, r.month, r.day, r.hour_utc);
    const solar::SolarPosition s = solar::solar_position(jd, r.lat, r.lon);
    EXPECT_NEAR(s.elevation_deg, r.elevation, 0.05);
    EXPECT_NEAR(s.azimuth_deg, r.azimuth, 0.05);
    EXPECT_NEAR(s.equation_of_time_min, r.equation_of_time, 0.1);
    EXPECT_NEAR(s.declination_deg, r.declination, 0.02);
  }
}

TEST(Sun, JulianDay) {
  // J2000.0 is 2000-01-01 12:00 TT; in UTC terms the Julian day of that instant is 2451545.0.
  EXPECT_DOUBLE_EQ(solar::julian_day(2000, 1, 1, 12.0), 2451545.0);
  EXPECT_DOUBLE_EQ(solar::julian_day(1970, 1, 1, 0.0), 2440587.5);
  EXPECT_DOUBLE_EQ(solar::julian_day(2024, 2, 29, 6.0), 2460369.75);
}

TEST(Sun, ParsesTimes) {
  const solar::SunTime local = solar::parse_sun_time("2026-06-21T06:00");
  EXPECT_TRUE(local.local);
  EXPECT_DOUBLE_EQ(local.julian_day, solar::julian_day(2026, 6, 21, 6.0));
  // Local mean solar time at 15 E is one hour ahead of UTC.
  EXPECT_NEAR(solar::julian_day_utc(local, 15.0), solar::julian_day(2026, 6, 21, 5.0), 1e-9);
  EXPECT_NEAR(solar::julian_day_utc(local, -90.0), solar::julian_day(2026, 6, 21, 12.0), 1e-9);

  const solar::SunTime utc = solar::parse_sun_time("2026-06-21 06:00:30Z");
  EXPECT_FALSE(utc.local);
  EXPECT_NEAR(utc.julian_day, solar::julian_day(2026, 6, 21, 6.0 + 30.0 / 3600.0), 1e-9);
  EXPECT_DOUBLE_EQ(solar::julian_day_utc(utc, 120.0), utc.julian_day);  // longitude ignored

  EXPECT_NEAR(solar::parse_sun_time("2026-06-21T08:00+02:00").julian_day,
              solar::julian_day(2026, 6, 21, 6.0), 1e-9);
  EXPECT_NEAR(solar::parse_sun_time("2026-06-21T01:00-0530").julian_day,
              solar::julian_day(2026, 6, 21, 6.5), 1e-9);

  for (const char* bad :
       {"", "2026-06-21", "2026-13-01T00:00", "2026-02-30T00:00", "2026-06-21T25:00",
        "2026-06-21T06:00X", "2026-06-21T06:00+2", "21/06/2026 06:00", "2026-06-21T06:60"})
    EXPECT_THROW(solar::parse_sun_time(bad), Error) << bad;
}

TEST(Sun, LocalNoonIsNearTheMeridian) {
  // At local mean noon the hour angle is the equation of time (4 minutes a degree), anywhere.
  for (double lon : {-120.0, 0.0, 37.5}) {
    const solar::SunTime noon = solar::parse_sun_time("2026-11-03T12:00");
    const solar::SolarPosition s =
        solar::solar_position(solar::julian_day_utc(noon, lon), 45.0, lon);
    EXPECT_NEAR(s.hour_angle_deg, s.equation_of_time_min / 4.0, 1e-6);
    EXPECT_NEAR(s.azimuth_deg, 180.0, 5.0);  // the sun is south at northern mid-latitudes
  }
}

TEST(Sun, DirectionInTheWorldFrame) {
  // World Y-up: east +X, north -Z.
  const glm::dvec3 east = solar::sun_direction(90.0, 0.0);
  EXPECT_NEAR(east.x, 1.0, 1e-12);
  EXPECT_NEAR(east.y, 0.0, 1e-12);
  const glm::dvec3 north = solar::sun_direction(0.0, 0.0);
  EXPECT_NEAR(north.z, -1.0, 1e-12);
  const glm::dvec3 up = solar::sun_direction(123.0, 90.0);
  EXPECT_NEAR(up.y, 1.0, 1e-12);
  const glm::dvec3 d = solar::sun_direction(200.0, 30.0);
  EXPECT_NEAR(glm::length(d), 1.0, 1e-12);
  EXPECT_NEAR(d.y, 0.5, 1e-12);
}
