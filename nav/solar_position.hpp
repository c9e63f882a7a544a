// solar_position: the sun's direction at a GPS instant seen from a WGS84 point, so that the virtual
// boom is lit like the real scene, plus atmospheric refraction as a separate step.
//
// Algorithm: the Meeus-based one of NOAA's solar calculator: J. Meeus, Astronomical Algorithms
// (2nd ed., 1998), ch. 25 (the sun's "low accuracy" coordinates), with the nutation of ch. 22 (its
// four largest terms, 0.5" instead of ch. 25's single term), the apparent sidereal time of ch. 12 and
// the equation of time of ch. 28. Topocentric: the observer's WGS84 ECEF position (nav/geodesy.hpp) is
// subtracted from the sun's, which is the parallax (at most 0.0024 deg). Polar motion and diurnal
// aberration (< 0.0001 deg) are left out. Against PyEphem (VSOP87) every 3 days of 2000-2033 the
// sun's longitude is off by 0.004 deg rms, 0.01 deg at most (ch. 25 leaves out the perturbations by
// the Moon and planets); the test's cases (1980-2040) are within 0.006 deg.
//
// The direction returned is the geometric one, which is what lights a scene at any altitude; the
// refraction of the air bends it only for an observer looking through the atmosphere near the
// ground, and refraction_rad() is there to compare with published apparent zenith angles.
//
// Time scales: the Earth's rotation goes with UT1 = GPS - leap_seconds + ut1_minus_utc_s (1 s of
// error turns the sun by 0.004 deg); the sun moves along the ecliptic in TT = UT1 + delta_t_s, so
// slowly (0.00001 deg per s) that delta_t_s matters little. See core/conventions.hpp for NED.
#pragma once

#include <Eigen/Core>

#include "core/conventions.hpp"
#include "nav/geodesy.hpp"

namespace augrig::nav {

struct SolarPosition {
  double zenith_rad = 0;   // geometric topocentric zenith angle, no refraction, [0, pi]
  double azimuth_rad = 0;  // from north, positive towards east, [0, 2 pi)
  Eigen::Vector3d sun_ned = -Eigen::Vector3d::UnitZ();  // unit vector to the sun in NED at the point
                                                        // (z down: a sun above the horizon has z < 0)
  // Geocentric apparent place of date (true equator and equinox), as the algorithm gives it.
  double declination_rad = 0;
  double right_ascension_rad = 0;  // [0, 2 pi)
  double equation_of_time_s = 0;   // apparent minus mean solar time (positive: a sundial is fast)
  double earth_sun_distance_au = 1;
};

// TT - UT1 that GPS - UTC implies: TT = TAI + 32.184 s = GPS + 51.184 s exactly, and
// UT1 = UTC + ut1_minus_utc_s.
constexpr double delta_t_s_from_leap_seconds(int leap_seconds, double ut1_minus_utc_s = 0) {
  return 51.184 + leap_seconds - ut1_minus_utc_s;
}
// TT - UT1 for the 2020s: delta_t_s_from_leap_seconds(kDefaultLeapSeconds) with UT1 - UTC = 0,
// rounded; right to within a second until the next leap second.
inline constexpr double kDefaultDeltaT_s = 69.2;

// The sun at GPS time t_gps_ns (ClockDomain::kGps) from `where` (ellipsoidal height), with
// leap_seconds = GPS - UTC (kDefaultLeapSeconds since 2017), delta_t_s = TT - UT1 and
// ut1_minus_utc_s (IERS's DUT1, |DUT1| < 0.9 s; 0 is good to 0.004 deg).
SolarPosition solar_position(TimestampNs t_gps_ns, const Geodetic& where, int leap_seconds,
                             double delta_t_s = kDefaultDeltaT_s, double ut1_minus_utc_s = 0);
// A double where GPS - UTC goes is a delta T put first by mistake: refused at compile time.
SolarPosition solar_position(TimestampNs, const Geodetic&, double, double = 0, double = 0) = delete;
// The same with GPS - UTC from the table of nav/gps_time.hpp for the instant
// (leap_seconds_at_gps()), delta_t_s_from_leap_seconds() of it, and UT1 - UTC = 0.
SolarPosition solar_position(TimestampNs t_gps_ns, const Geodetic& where);

// The unit vector towards the sun in ECEF: sun.sun_ned turned by R_ecef_ned at `where`.
Eigen::Vector3d sun_direction_ecef(const SolarPosition& sun, const Geodetic& where);

// Atmospheric refraction (rad, >= 0) by which the apparent elevation exceeds a geometric elevation:
// Saemundsson's formula, as NREL's SPA applies it, scaled by pressure and temperature at the observer.
// 0 below a geometric elevation of -0.8333 deg, where the sun has set (as in SPA). Apparent zenith =
// zenith_rad - refraction_rad(pi / 2 - zenith_rad, ...).
double refraction_rad(double geometric_elevation_rad, double pressure_hPa = 1010, double temperature_C = 10);

}  // namespace augrig::nav
