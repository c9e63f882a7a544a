#include "nav/solar_position.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "nav/gps_time.hpp"

namespace augrig::nav {
namespace {

constexpr double kAu_m = 149'597'870'700.0;  // IAU 2012
// J2000.0 (JD 2451545.0) is 7300.5 days after the GPS epoch (JD 2444244.5).
constexpr std::int64_t kJ2000FromGpsEpochNs = 7300 * kNsPerDay + kNsPerDay / 2;
constexpr double kArcsecToDeg = 1.0 / 3600.0;

// An angle in degrees reduced to [0, 360).
double wrap_deg(double deg) {
  const double r = std::fmod(deg, 360.0);
  return r < 0 ? r + 360.0 : r;
}
double sin_deg(double deg) {
  return std::sin(deg_to_rad(deg));
}
double cos_deg(double deg) {
  return std::cos(deg_to_rad(deg));
}

// An angle in radians reduced to [0, 2 pi); -0 and values rounding up to 2 pi become 0.
double wrap_2pi(double rad) {
  double r = std::fmod(rad, 2 * kPi);
  if (r < 0) r += 2 * kPi;
  return r >= 2 * kPi ? 0.0 : r + 0.0;
}

// Nutation in longitude and obliquity (degrees) at T Julian centuries of TT since J2000: the four
// largest terms (Meeus ch. 22), good to 0.5" and 0.1".
struct Nutation {
  double dpsi_deg, deps_deg;
};
Nutation nutation(double T) {
  const double omega = 125.04452 - 1934.136261 * T;  // Moon's ascending node
  const double l_sun = 280.4665 + 36000.7698 * T;    // mean longitudes of the Sun
  const double l_moon = 218.3165 + 481267.8813 * T;  // and the Moon
  const double dpsi = -17.20 * sin_deg(omega) - 1.32 * sin_deg(2 * l_sun) - 0.23 * sin_deg(2 * l_moon) +
                      0.21 * sin_deg(2 * omega);
  const double deps = 9.20 * cos_deg(omega) + 0.57 * cos_deg(2 * l_sun) + 0.10 * cos_deg(2 * l_moon) -
                      0.09 * cos_deg(2 * omega);
  return {dpsi * kArcsecToDeg, deps * kArcsecToDeg};
}

// The sun's geocentric apparent place and the Greenwich apparent sidereal time at d_ut1 days of UT1
// and d_tt days of TT since J2000.0 (Meeus ch. 25, 22, 12, 28).
struct ApparentSun {
  double ra_deg, dec_deg, distance_au, gast_deg, equation_of_time_s;
};
ApparentSun apparent_sun(double d_ut1, double d_tt) {
  const double T = d_tt / 36525.0;
  const double l0 = wrap_deg(280.46646 + T * (36000.76983 + T * 0.0003032));  // mean longitude
  const double m = 357.52911 + T * (35999.05029 - T * 0.0001537);             // mean anomaly
  const double e = 0.016708634 - T * (0.000042037 + T * 0.0000001267);        // orbit's eccentricity
  const double c = (1.914602 - T * (0.004817 + T * 0.000014)) * sin_deg(m) +
                   (0.019993 - T * 0.000101) * sin_deg(2 * m) + 0.000289 * sin_deg(3 * m);  // centre
  const double true_lon = l0 + c;
  const double distance_au = 1.000001018 * (1 - e * e) / (1 + e * cos_deg(m + c));

  const Nutation nut = nutation(T);
  // Apparent longitude: nutation and the aberration 20.4898" / R.
  const double lambda = true_lon + nut.dpsi_deg - 20.4898 * kArcsecToDeg / distance_au;
  const double eps0 = 23.0 + 26.0 / 60 + (21.448 - T * (46.8150 + T * (0.00059 - T * 0.001813))) / 3600;
  const double eps = eps0 + nut.deps_deg;
  const double ra = wrap_deg(rad_to_deg(std::atan2(cos_deg(eps) * sin_deg(lambda), cos_deg(lambda))));
  const double dec = rad_to_deg(std::asin(sin_deg(eps) * sin_deg(lambda)));

  // Sidereal time runs on UT1; the equation of the equinoxes makes it apparent.
  const double Tu = d_ut1 / 36525.0;
  const double gmst = 280.46061837 + 360.98564736629 * d_ut1 + Tu * Tu * (0.000387933 - Tu / 38710000.0);
  const double equinoxes = nut.dpsi_deg * cos_deg(eps);
  const double gast = wrap_deg(gmst + equinoxes);
  // Equation of time (ch. 28), reduced to (-180, 180] degrees; 1 degree is 240 s.
  double eot_deg = wrap_deg(l0 - 0.0057183 - ra + equinoxes);
  if (eot_deg > 180) eot_deg -= 360;
  return {ra, dec, distance_au, gast, eot_deg * 240.0};
}

}  // namespace

SolarPosition solar_position(TimestampNs t_gps_ns, const Geodetic& where, int leap_seconds, double delta_t_s,
                             double ut1_minus_utc_s) {
  // Days since J2000.0 from integer nanoseconds, so that no precision is lost before the subtraction.
  const std::int64_t ns =
      t_gps_ns - kJ2000FromGpsEpochNs - static_cast<std::int64_t>(leap_seconds) * kNsPerSecond;
  const double d_ut1 = static_cast<double>(ns) / static_cast<double>(kNsPerDay) + ut1_minus_utc_s / 86400.0;
  const double d_tt = d_ut1 + delta_t_s / 86400.0;
  const ApparentSun sun = apparent_sun(d_ut1, d_tt);

  // The sun in ECEF: its Greenwich hour angle is GAST - RA, so its longitude is RA - GAST.
  const double lon = deg_to_rad(sun.ra_deg - sun.gast_deg), dec = deg_to_rad(sun.dec_deg);
  const Eigen::Vector3d sun_ecef_m =
      sun.distance_au * kAu_m *
      Eigen::Vector3d(std::cos(dec) * std::cos(lon), std::cos(dec) * std::sin(lon), std::sin(dec));
  // Topocentric: from the observer, which is the parallax.
  const Eigen::Vector3d to_sun_ecef = sun_ecef_m - ecef_from_geodetic(where);
  const Eigen::Vector3d d = (R_ecef_ned(where.lat_rad, where.lon_rad).transpose() * to_sun_ecef).normalized();

  SolarPosition out;
  out.sun_ned = d;
  out.zenith_rad = std::acos(std::clamp(-d.z(), -1.0, 1.0));
  out.azimuth_rad = wrap_2pi(std::atan2(d.y(), d.x()));
  out.declination_rad = dec;
  out.right_ascension_rad = wrap_2pi(deg_to_rad(sun.ra_deg));
  out.equation_of_time_s = sun.equation_of_time_s;
  out.earth_sun_distance_au = sun.distance_au;
  return out;
}

SolarPosition solar_position(TimestampNs t_gps_ns, const Geodetic& where) {
  const int leap_seconds = leap_seconds_at_gps(t_gps_ns);
  return solar_position(t_gps_ns, where, leap_seconds, delta_t_s_from_leap_seconds(leap_seconds), 0.0);
}

Eigen::Vector3d sun_direction_ecef(const SolarPosition& sun, const Geodetic& where) {
  return R_ecef_ned(where.lat_rad, where.lon_rad) * sun.sun_ned;
}

double refraction_rad(double geometric_elevation_rad, double pressure_hPa, double temperature_C) {
  const double e_deg = rad_to_deg(geometric_elevation_rad);
  // The sun's upper limb (0.26667 deg) below the refracted horizon (0.5667 deg): set, nothing to bend.
  if (!(e_deg >= -0.8333)) return 0.0;
  const double r_arcmin = 1.02 / std::tan(deg_to_rad(e_deg + 10.3 / (e_deg + 5.11)));
  const double scale = (pressure_hPa / 1010.0) * (283.0 / (273.0 + temperature_C));
  // Near the zenith the formula dips a hair below 0.
  return std::max(0.0, deg_to_rad(r_arcmin / 60.0) * scale);
}

}  // namespace augrig::nav
