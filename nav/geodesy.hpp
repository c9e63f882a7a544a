// geodesy: WGS84 geodetic <-> ECEF, the NED frame at a point, and normal gravity, all through
// GeographicLib (exact, no flat-earth shortcut). Angles in radians, heights ellipsoidal (metres
// above the WGS84 ellipsoid, not MSL). See core/conventions.hpp for the frames.
#pragma once

#include <Eigen/Core>

namespace augrig::nav {

// WGS84 Earth rotation rate (rad/s) and the ECEF angular velocity of the Earth w.r.t. inertial space.
inline constexpr double kEarthRate_radps = 7.292115e-5;
inline Eigen::Vector3d earth_rate_ecef() {
  return {0.0, 0.0, kEarthRate_radps};
}

struct Geodetic {
  double lat_rad = 0;
  double lon_rad = 0;
  double h_m = 0;  // ellipsoidal height
};

Eigen::Vector3d ecef_from_geodetic(const Geodetic& g);
Geodetic geodetic_from_ecef(const Eigen::Vector3d& p_ecef_m);

// R_ecef_ned at a latitude/longitude: columns are north, east, down expressed in ECEF.
Eigen::Matrix3d R_ecef_ned(double lat_rad, double lon_rad);

// Gravity (gravitation plus centrifugal, the normal field of the WGS84 ellipsoid) at an ECEF
// point, in ECEF, m/s^2. This is what an accelerometer at rest on the rotating Earth cancels.
Eigen::Vector3d gravity_ecef(const Eigen::Vector3d& p_ecef_m);

// Meridian and prime-vertical radii of curvature (m) at a latitude.
double meridian_radius_m(double lat_rad);
double prime_vertical_radius_m(double lat_rad);

}  // namespace augrig::nav
