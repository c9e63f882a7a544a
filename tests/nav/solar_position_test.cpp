// Tests for nav/solar_position.hpp: NREL SPA's published worked example (Reda & Andreas 2004), an
// independent oracle (PyEphem / libastro, a VSOP87 sun: tests/data/sun/make_reference.py wrote
// pyephem_reference.csv, read here without python), Meeus's Example 25.a, known solar facts
// (solstice declination, equation of time), the refraction formula and the API's edge cases.
#include "nav/solar_position.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "nav/geodesy.hpp"
#include "nav/gps_time.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::nav {
namespace {

Geodetic geodetic_deg(double lat_deg, double lon_deg, double h_m) {
  return {deg_to_rad(lat_deg), deg_to_rad(lon_deg), h_m};
}

// A UTC date and time of day as GPS time, with the table's GPS - UTC for the date.
TimestampNs gps_from_utc(int y, int mo, int d, int h, int mi, double s) {
  const CivilDate date{y, mo, d};
  const std::int64_t ns_of_day = (h * 3600 + mi * 60) * kNsPerSecond + s_to_ns(s);
  return gps_ns_from_utc(date, ns_of_day, leap_seconds_on(date));
}

// |a - b| of two angles in degrees, the short way round.
double angle_diff_deg(double a_deg, double b_deg) {
  return std::abs(std::remainder(a_deg - b_deg, 360.0));
}

double apparent_zenith_deg(const SolarPosition& s, double pressure_hPa, double temperature_C) {
  return rad_to_deg(s.zenith_rad - refraction_rad(kPi / 2 - s.zenith_rad, pressure_hPa, temperature_C));
}

// SPA's example: 2003-10-17 12:30:30 at UTC-7, Golden CO, delta T 67 s, 820 hPa, 11 C. The paper's
// topocentric zenith (refraction included) 50.11162 deg and azimuth 194.34024 deg.
TEST(SolarPosition, SpaWorkedExample) {
  const int leap = 13;  // GPS - UTC in 2003
  ASSERT_EQ(leap_seconds_on({2003, 10, 17}), leap);
  const TimestampNs t = gps_ns_from_utc({2003, 10, 17}, (19 * 3600 + 30 * 60 + 30) * kNsPerSecond, leap);
  const SolarPosition s = solar_position(t, geodetic_deg(39.742476, -105.1786, 1830.14), leap, 67.0);
  const double zenith_err = std::abs(apparent_zenith_deg(s, 820, 11) - 50.11162);
  const double azimuth_err = std::abs(rad_to_deg(s.azimuth_rad) - 194.34024);
  std::printf("SPA example: zenith error %.5f deg, azimuth error %.5f deg\n", zenith_err, azimuth_err);
  // Measured 0.0009 and 0.0055 deg.
  EXPECT_LE(zenith_err, 0.01);
  EXPECT_LE(azimuth_err, 0.01);
}

struct Reference {
  std::string utc;
  TimestampNs t_gps_ns = 0;
  Geodetic where;
  double alt_deg = 0, az_deg = 0, ra_deg = 0, dec_deg = 0, dist_au = 0;
};

std::vector<Reference> read_pyephem_reference() {
  std::ifstream f(test::data_path("sun/pyephem_reference.csv"));
  std::vector<Reference> rows;
  std::string line;
  std::getline(f, line);  // header
  while (std::getline(f, line)) {
    int y = 0, mo = 0, d = 0, h = 0, mi = 0, sec = 0;
    double lat = 0, lon = 0;
    Reference r;
    if (std::sscanf(line.c_str(), "%d-%d-%dT%d:%d:%d,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf", &y, &mo, &d, &h, &mi,
                    &sec, &lat, &lon, &r.where.h_m, &r.alt_deg, &r.az_deg, &r.ra_deg, &r.dec_deg,
                    &r.dist_au) != 14) {
      ADD_FAILURE() << "bad line: " << line;
      continue;
    }
    r.utc = line.substr(0, line.find(','));
    r.t_gps_ns = gps_from_utc(y, mo, d, h, mi, sec);
    r.where.lat_rad = deg_to_rad(lat);
    r.where.lon_rad = deg_to_rad(lon);
    rows.push_back(r);
  }
  return rows;
}

// Every row of PyEphem's table: topocentric zenith and azimuth (weighted by sin(zenith): the
// azimuth means nothing at the zenith), geocentric RA (weighted by cos(dec)), declination, distance.
// Measured: at most 0.006 deg and 1.1e-4 au; the method's own error in longitude reaches 0.01 deg.
TEST(SolarPosition, AgreesWithPyEphem) {
  const std::vector<Reference> rows = read_pyephem_reference();
  ASSERT_EQ(rows.size(), 42u);
  double max_zenith = 0, max_azimuth = 0, max_ra = 0, max_dec = 0, max_dist = 0;
  for (const Reference& r : rows) {
    SCOPED_TRACE(r.utc);
    const SolarPosition s = solar_position(r.t_gps_ns, r.where);
    const double zenith_ref = 90 - r.alt_deg;
    const double zenith_err = std::abs(rad_to_deg(s.zenith_rad) - zenith_ref);
    const double azimuth_err =
        angle_diff_deg(rad_to_deg(s.azimuth_rad), r.az_deg) * std::sin(deg_to_rad(zenith_ref));
    const double ra_err =
        angle_diff_deg(rad_to_deg(s.right_ascension_rad), r.ra_deg) * std::cos(s.declination_rad);
    const double dec_err = std::abs(rad_to_deg(s.declination_rad) - r.dec_deg);
    const double dist_err = std::abs(s.earth_sun_distance_au - r.dist_au);
    EXPECT_LE(zenith_err, 0.01);
    EXPECT_LE(azimuth_err, 0.01);
    EXPECT_LE(ra_err, 0.01);
    EXPECT_LE(dec_err, 0.01);
    EXPECT_LE(dist_err, 2e-4);
    max_zenith = std::max(max_zenith, zenith_err);
    max_azimuth = std::max(max_azimuth, azimuth_err);
    max_ra = std::max(max_ra, ra_err);
    max_dec = std::max(max_dec, dec_err);
    max_dist = std::max(max_dist, dist_err);
  }
  std::printf(
      "PyEphem, %zu rows, max errors: zenith %.5f deg, azimuth*sin(zenith) %.5f deg, RA*cos(dec) %.5f deg, "
      "declination %.5f deg, distance %.2e au\n",
      rows.size(), max_zenith, max_azimuth, max_ra, max_dec, max_dist);
}

// Meeus, Astronomical Algorithms, Example 25.a: 1992-10-13 0h TD, apparent RA 198.38083 deg,
// declination -7.78507 deg, R 0.99766 au (by the same low-accuracy method; nutation differs by < 1.5").
TEST(SolarPosition, MeeusExample25a) {
  // UTC 23:59:00 the day before with delta T = 60 s and no leap seconds is TD 0h exactly.
  const TimestampNs t = gps_ns_from_utc({1992, 10, 12}, (23 * 3600 + 59 * 60) * kNsPerSecond, 0);
  const SolarPosition s = solar_position(t, geodetic_deg(0, 0, 0), 0, 60.0);
  EXPECT_NEAR(rad_to_deg(s.right_ascension_rad), 198.38083, 0.001);
  EXPECT_NEAR(rad_to_deg(s.declination_rad), -7.78507, 0.001);
  EXPECT_NEAR(s.earth_sun_distance_au, 0.99766, 1e-5);
}

// The June solstice 2024 was at 20:51 UTC on the 20th: the sun's declination is then the obliquity
// (23.44 deg) and its right ascension 6 h.
TEST(SolarPosition, JuneSolstice2024) {
  const SolarPosition s = solar_position(gps_from_utc(2024, 6, 20, 20, 51, 0), geodetic_deg(0, 0, 0));
  EXPECT_NEAR(rad_to_deg(s.declination_rad), 23.44, 0.01);
  EXPECT_NEAR(rad_to_deg(s.right_ascension_rad), 90.0, 0.01);
}

// Early November the equation of time peaks at about +16.4 min (a sundial is that much fast).
TEST(SolarPosition, EquationOfTimeEarlyNovember) {
  const SolarPosition s = solar_position(gps_from_utc(2024, 11, 3, 12, 0, 0), geodetic_deg(51.5, 0, 0));
  EXPECT_NEAR(s.equation_of_time_s / 60, 16.4, 0.3);
  // And about -14.2 min in mid-February.
  const SolarPosition feb = solar_position(gps_from_utc(2024, 2, 11, 12, 0, 0), geodetic_deg(51.5, 0, 0));
  EXPECT_NEAR(feb.equation_of_time_s / 60, -14.2, 0.3);
}

// sun_ned is the unit vector of zenith and azimuth, and ECEF is that turned by R_ecef_ned.
TEST(SolarPosition, DirectionAgreesWithAngles) {
  for (const Reference& r : read_pyephem_reference()) {
    SCOPED_TRACE(r.utc);
    const SolarPosition s = solar_position(r.t_gps_ns, r.where);
    const double z = s.zenith_rad, a = s.azimuth_rad;
    const Eigen::Vector3d want(std::sin(z) * std::cos(a), std::sin(z) * std::sin(a), -std::cos(z));
    EXPECT_NEAR((s.sun_ned - want).norm(), 0.0, 1e-12);
    EXPECT_NEAR(s.sun_ned.norm(), 1.0, 1e-12);
    EXPECT_GE(s.azimuth_rad, 0.0);
    EXPECT_LT(s.azimuth_rad, 2 * kPi);
    EXPECT_EQ(s.sun_ned.z() < 0, r.alt_deg > 0);
    const Eigen::Vector3d ecef = sun_direction_ecef(s, r.where);
    const Eigen::Vector3d up_ecef = -R_ecef_ned(r.where.lat_rad, r.where.lon_rad).col(2);
    EXPECT_NEAR(ecef.norm(), 1.0, 1e-12);
    EXPECT_NEAR(ecef.dot(up_ecef), std::cos(z), 1e-12);
  }
}

// Saemundsson's refraction: 0.48 deg for a geometric elevation of 0 (the sun then appears 0.48 deg
// up); 0.57 deg at the apparent horizon; 1' at 45 deg; proportional to pressure; none once set.
TEST(SolarPosition, Refraction) {
  EXPECT_NEAR(rad_to_deg(refraction_rad(0.0)), 0.57, 0.1);
  EXPECT_NEAR(rad_to_deg(refraction_rad(0.0)), 0.483, 0.002);
  EXPECT_NEAR(rad_to_deg(refraction_rad(deg_to_rad(45))), 0.016, 0.001);
  // The geometric elevation that appears on the horizon, by bisection: its refraction is 34'.
  double lo = deg_to_rad(-0.8), hi = 0.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = (lo + hi) / 2;
    (mid + refraction_rad(mid) < 0 ? lo : hi) = mid;
  }
  EXPECT_NEAR(rad_to_deg(refraction_rad(lo)), 0.57, 0.01);
  EXPECT_NEAR(refraction_rad(deg_to_rad(10), 505), refraction_rad(deg_to_rad(10)) / 2, 1e-15);
  EXPECT_LT(refraction_rad(deg_to_rad(10), 1010, 40), refraction_rad(deg_to_rad(10), 1010, -20));
  EXPECT_EQ(refraction_rad(deg_to_rad(-1)), 0.0);
  EXPECT_EQ(refraction_rad(deg_to_rad(-30)), 0.0);
  EXPECT_GE(refraction_rad(kPi / 2), 0.0);
  EXPECT_LT(rad_to_deg(refraction_rad(kPi / 2)), 1e-4);
  double prev = refraction_rad(deg_to_rad(-0.83));
  for (double e_deg = -0.8; e_deg <= 90; e_deg += 0.1) {
    const double r = refraction_rad(deg_to_rad(e_deg));
    EXPECT_LE(r, prev) << e_deg;
    prev = r;
  }
}

// GPS - UTC is an int: a double there (a delta T put first) does not compile.
template <typename T>
concept TakesAsLeapSeconds = requires(T v) {
  solar_position(TimestampNs{}, Geodetic{}, v);
};
static_assert(TakesAsLeapSeconds<int>);
static_assert(!TakesAsLeapSeconds<double>);

// The overload without time scales takes GPS - UTC from the table and delta T from it.
TEST(SolarPosition, LeapSecondTableOverload) {
  const Geodetic where = geodetic_deg(48.1, 11.6, 8000);
  for (const TimestampNs t : {gps_from_utc(1990, 6, 1, 10, 0, 0), gps_from_utc(2012, 6, 30, 23, 59, 59.5),
                              gps_from_utc(2024, 3, 1, 9, 0, 0)}) {
    const int leap = leap_seconds_at_gps(t);
    const SolarPosition a = solar_position(t, where);
    const SolarPosition b = solar_position(t, where, leap, delta_t_s_from_leap_seconds(leap));
    EXPECT_EQ(a.zenith_rad, b.zenith_rad);
    EXPECT_EQ(a.azimuth_rad, b.azimuth_rad);
    EXPECT_EQ(a.equation_of_time_s, b.equation_of_time_s);
  }
  // In 2024 the defaults (18 s, 69.2 s) are the table's values to 0.016 s of delta T.
  const TimestampNs t = gps_from_utc(2024, 3, 1, 9, 0, 0);
  const SolarPosition table = solar_position(t, where);
  const SolarPosition defaults = solar_position(t, where, kDefaultLeapSeconds);
  EXPECT_NEAR(table.zenith_rad, defaults.zenith_rad, 1e-8);
  EXPECT_NEAR(table.azimuth_rad, defaults.azimuth_rad, 1e-8);
  // In 1990 GPS - UTC was 6 s: 12 s more turn the Earth by 0.05 deg.
  const TimestampNs t1990 = gps_from_utc(1990, 6, 1, 10, 0, 0);
  const double moved = std::acos(std::clamp(
      solar_position(t1990, where).sun_ned.dot(solar_position(t1990, where, kDefaultLeapSeconds).sun_ned),
      -1.0, 1.0));
  EXPECT_NEAR(rad_to_deg(moved), 12 * 360.0 / 86164, 0.01);
  EXPECT_DOUBLE_EQ(delta_t_s_from_leap_seconds(18, 0.1), 69.084);
}

// The GPS epoch (1980-01-06 00:00 UTC) and 2040 give sane values: the sun south-west of
// the south, early January's declination and distance; near the December solstice in 2040.
TEST(SolarPosition, GpsEpochAnd2040) {
  const SolarPosition epoch = solar_position(0, geodetic_deg(0, 0, 0));
  EXPECT_NEAR(rad_to_deg(epoch.declination_rad), -22.6, 0.1);
  EXPECT_NEAR(epoch.earth_sun_distance_au, 0.9833, 1e-3);
  EXPECT_GT(epoch.sun_ned.z(), 0);  // midnight at Greenwich
  const SolarPosition later = solar_position(gps_from_utc(2040, 12, 21, 12, 0, 0), geodetic_deg(0, 0, 0));
  EXPECT_NEAR(rad_to_deg(later.declination_rad), -23.43, 0.01);
  EXPECT_NEAR(rad_to_deg(later.zenith_rad), 23.43, 0.5);  // about noon at Greenwich
  EXPECT_TRUE(later.sun_ned.allFinite());
}

// Over a day in 10-minute steps the sun moves smoothly (at most 15 deg/h plus a little), its
// azimuth stays in [0, 2 pi), and at 45 N it goes once round the compass through north.
TEST(SolarPosition, ContinuousOverADay) {
  for (const double lat_deg : {45.0, -45.0}) {
    SCOPED_TRACE(lat_deg);
    const Geodetic where = geodetic_deg(lat_deg, -179.9, 1000);
    const TimestampNs t0 = gps_from_utc(2024, 3, 1, 0, 0, 0);
    const TimestampNs step = 600 * kNsPerSecond;
    SolarPosition prev = solar_position(t0, where);
    double turned_deg = 0;
    int wraps = 0;
    for (int i = 1; i <= 144; ++i) {
      const SolarPosition s = solar_position(t0 + i * step, where);
      ASSERT_GE(s.azimuth_rad, 0.0);
      ASSERT_LT(s.azimuth_rad, 2 * kPi);
      const double moved_deg = rad_to_deg(std::acos(std::clamp(s.sun_ned.dot(prev.sun_ned), -1.0, 1.0)));
      EXPECT_LT(moved_deg, 2.51);
      EXPECT_LT(std::abs(rad_to_deg(s.zenith_rad - prev.zenith_rad)), 2.51);
      const double daz_deg = std::remainder(rad_to_deg(s.azimuth_rad - prev.azimuth_rad), 360.0);
      EXPECT_LT(std::abs(daz_deg), 10.0);
      if (std::abs(s.azimuth_rad - prev.azimuth_rad) > kPi) ++wraps;
      turned_deg += daz_deg;
      prev = s;
    }
    // North of the sun the azimuth increases (clockwise), south of it decreases: once round.
    EXPECT_NEAR(turned_deg, lat_deg > 0 ? 360.0 : -360.0, 1.0);
    EXPECT_EQ(wraps, 1);
  }
}

}  // namespace
}  // namespace augrig::nav
