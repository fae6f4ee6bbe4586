#pragma once
// Where the sun stands in the sky of a place at a time, for the sky model's light direction
// (pointcloud/sky.hpp): NOAA's solar position formulas (after Meeus, "Astronomical Algorithms"),
// good to about a minute of arc between 1800 and 2100 — the solar declination, the equation of
// time, the hour angle, and from them the sun's elevation (with NOAA's refraction correction,
// i.e. where the sun appears) and azimuth (degrees clockwise from north).
//
// Times are ISO 8601 ("2026-06-21T06:00", seconds optional, "T" or a space). With a zone suffix
// ("Z", "+02:00", "-0530") the time is civil time at that offset from UTC; without one it is
// local mean solar time at the place's longitude (UTC + longitude / 15 hours), so "T12:00" is
// within the equation of time (at most about 16 minutes) of the sun's highest point anywhere.
#include <string>

#include <glm/vec3.hpp>

namespace stipple::solar {

struct SunTime {
  double julian_day = 0.0;  // of the written date and time, as if it were UTC
  bool local = true;        // no zone suffix: local mean solar time
};

// Parses an ISO 8601 date and time; throws stipple::Error naming the text when malformed.
SunTime parse_sun_time(const std::string& text);

// The Julian day (UTC) of `time` at longitude `lon_deg` (east positive; used by local times).
double julian_day_utc(const SunTime& time, double lon_deg);
// The Julian day (UTC) of a civil date and time in UTC (Gregorian calendar).
double julian_day(int year, int month, int day, double hours_utc);

struct SolarPosition {
  double declination_deg = 0.0;
  double equation_of_time_min = 0.0;  // apparent minus mean solar time, minutes
  double hour_angle_deg = 0.0;        // 0 at the meridian, positive in the afternoon
  double elevation_deg = 0.0;         // apparent: refraction included
  double azimuth_deg = 0.0;           // clockwise from north
};

// The sun at latitude and longitude (degrees, east positive) at a Julian day (UTC).
SolarPosition solar_position(double julian_day_utc, double lat_deg, double lon_deg);

// The unit vector towards the sun in the engine's world frame (Y-up, east +X, north -Z:
// z_up_to_y_up of a Z-up east-north-up frame) for an azimuth (clockwise from north) and an
// elevation, in degrees.
glm::dvec3 sun_direction(double azimuth_deg, double elevation_deg);

}  // namespace stipple::solar
