#include "stipple/math/sun.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "stipple/core/error.hpp"

namespace stipple::solar {
namespace {

constexpr double kPi = 3.14159265358979323846;
double rad(double d) {
  return d * kPi / 180.0;
}
double deg(double r) {
  return r * 180.0 / kPi;
}

// Days since 1970-01-01 of a Gregorian date (Hinnant's days_from_civil).
long long days_from_civil(long long y, unsigned m, unsigned d) {
  y -= m <= 2;
  const long long era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = unsigned(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + (long long)doe - 719468;
}

// Reads exactly `n` digits at `pos`.
bool digits(const std::string& s, size_t& pos, size_t n, int& out) {
  if (pos + n > s.size()) return false;
  out = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isdigit(static_cast<unsigned char>(s[pos + i]))) return false;
    out = out * 10 + (s[pos + i] - '0');
  }
  pos += n;
  return true;
}

// Atmospheric refraction (degrees) at a geometric elevation, NOAA's piecewise fit.
double refraction_deg(double e) {
  if (e > 85.0) return 0.0;
  const double t = std::tan(rad(e));
  double arcsec;
  if (e > 5.0)
    arcsec = 58.1 / t - 0.07 / (t * t * t) + 0.000086 / std::pow(t, 5);
  else if (e > -0.575)
    arcsec = 1735.0 + e * (-518.2 + e * (103.4 + e * (-12.79 + e * 0.711)));
  else
    arcsec = -20.772 / t;
  return arcsec / 3600.0;
}

}  // namespace

double julian_day(int year, int month, int day, double hours_utc) {
  return double(days_from_civil(year, unsigned(month), unsigned(day))) + 2440587.5 +
         hours_utc / 24.0;
}

SunTime parse_sun_time(const std::string& text) {
  auto bad = [&text]() {
    fail("--sun-time '{}': expected YYYY-MM-DDTHH:MM[:SS] with an optional Z or +HH:MM", text);
  };
  size_t p = 0;
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, s = 0;
  if (!digits(text, p, 4, y) || p >= text.size() || text[p++] != '-' || !digits(text, p, 2, mo) ||
      p >= text.size() || text[p++] != '-' || !digits(text, p, 2, d))
    bad();
  if (p >= text.size() || (text[p] != 'T' && text[p] != 't' && text[p] != ' ')) bad();
  ++p;
  if (!digits(text, p, 2, h) || p >= text.size() || text[p++] != ':' || !digits(text, p, 2, mi))
    bad();
  if (p < text.size() && text[p] == ':') {
    ++p;
    if (!digits(text, p, 2, s)) bad();
  }
  SunTime t;
  double offset_h = 0.0;
  if (p < text.size()) {
    const char c = text[p++];
    if ((c == 'Z' || c == 'z') && p == text.size()) {
      t.local = false;
    } else if (c == '+' || c == '-') {
      int oh, om = 0;
      if (!digits(text, p, 2, oh)) bad();
      if (p < text.size() && text[p] == ':') ++p;
      if (p < text.size() && !digits(text, p, 2, om)) bad();
      if (p != text.size() || oh > 14 || om > 59) bad();
      offset_h = (c == '-' ? -1.0 : 1.0) * (oh + om / 60.0);
      t.local = false;
    } else {
      bad();
    }
  }
  const int month_days[] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  if (mo < 1 || mo > 12 || d < 1 || d > month_days[mo - 1] || h > 24 || mi > 59 || s > 60 ||
      (h == 24 && (mi > 0 || s > 0)))
    bad();
  t.julian_day = julian_day(y, mo, d, h + mi / 60.0 + s / 3600.0 - offset_h);
  return t;
}

double julian_day_utc(const SunTime& time, double lon_deg) {
  return time.local ? time.julian_day - lon_deg / 360.0 : time.julian_day;
}

SolarPosition solar_position(double jd, double lat_deg, double lon_deg) {
  const double t = (jd - 2451545.0) / 36525.0;  // Julian centuries since J2000.0
  const double l0 = std::fmod(280.46646 + t * (36000.76983 + t * 0.0003032), 360.0);
  const double m = 357.52911 + t * (35999.05029 - 0.0001537 * t);
  const double e = 0.016708634 - t * (0.000042037 + 0.0000001267 * t);
  const double c = std::sin(rad(m)) * (1.914602 - t * (0.004817 + 0.000014 * t)) +
                   std::sin(rad(2 * m)) * (0.019993 - 0.000101 * t) +
                   std::sin(rad(3 * m)) * 0.000289;
  const double omega = 125.04 - 1934.136 * t;
  const double apparent_long = l0 + c - 0.00569 - 0.00478 * std::sin(rad(omega));
  const double mean_obliquity =
      23.0 + (26.0 + (21.448 - t * (46.815 + t * (0.00059 - t * 0.001813))) / 60.0) / 60.0;
  const double obliquity = mean_obliquity + 0.00256 * std::cos(rad(omega));

  SolarPosition out;
  const double decl = std::asin(std::sin(rad(obliquity)) * std::sin(rad(apparent_long)));
  out.declination_deg = deg(decl);
  const double y = std::pow(std::tan(rad(obliquity / 2.0)), 2);
  out.equation_of_time_min =
      4.0 * deg(y * std::sin(2 * rad(l0)) - 2 * e * std::sin(rad(m)) +
                4 * e * y * std::sin(rad(m)) * std::cos(2 * rad(l0)) -
                0.5 * y * y * std::sin(4 * rad(l0)) - 1.25 * e * e * std::sin(2 * rad(m)));

  // True solar time in minutes from the UTC time of day, the longitude and the equation of time.
  const double day_fraction = std::fmod(jd + 0.5, 1.0);
  double tst = std::fmod(day_fraction * 1440.0 + out.equation_of_time_min + 4.0 * lon_deg, 1440.0);
  if (tst < 0) tst += 1440.0;
  out.hour_angle_deg = tst / 4.0 - 180.0;

  const double lat = rad(lat_deg), ha = rad(out.hour_angle_deg);
  const double cos_zenith = std::clamp(
      std::sin(lat) * std::sin(decl) + std::cos(lat) * std::cos(decl) * std::cos(ha), -1.0, 1.0);
  const double elevation = 90.0 - deg(std::acos(cos_zenith));
  out.elevation_deg = elevation + refraction_deg(elevation);
  // Azimuth from south towards west, turned to clockwise from north.
  double az =
      deg(std::atan2(std::sin(ha), std::cos(ha) * std::sin(lat) - std::tan(decl) * std::cos(lat))) +
      180.0;
  out.azimuth_deg = std::fmod(az + 360.0, 360.0);
  return out;
}

glm::dvec3 sun_direction(double azimuth_deg, double elevation_deg) {
  const double az = rad(azimuth_deg), el = rad(elevation_deg);
  // East-north-up, then Z-up to Y-up: (e, n, u) -> (e, u, -n).
  return {std::cos(el) * std::sin(az), std::sin(el), -std::cos(el) * std::cos(az)};
}

}  // namespace stipple::solar
