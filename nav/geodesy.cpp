#include "nav/geodesy.hpp"

#include <cmath>

#include <GeographicLib/Constants.hpp>
#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/NormalGravity.hpp>

#include "core/conventions.hpp"

namespace augrig::nav {

Eigen::Vector3d ecef_from_geodetic(const Geodetic& g) {
  Eigen::Vector3d p;
  GeographicLib::Geocentric::WGS84().Forward(rad_to_deg(g.lat_rad), rad_to_deg(g.lon_rad), g.h_m, p.x(),
                                             p.y(), p.z());
  return p;
}

Geodetic geodetic_from_ecef(const Eigen::Vector3d& p_ecef_m) {
  double lat_deg = 0, lon_deg = 0, h_m = 0;
  GeographicLib::Geocentric::WGS84().Reverse(p_ecef_m.x(), p_ecef_m.y(), p_ecef_m.z(), lat_deg, lon_deg, h_m);
  return {deg_to_rad(lat_deg), deg_to_rad(lon_deg), h_m};
}

Eigen::Matrix3d R_ecef_ned(double lat_rad, double lon_rad) {
  const double sl = std::sin(lat_rad), cl = std::cos(lat_rad);
  const double so = std::sin(lon_rad), co = std::cos(lon_rad);
  Eigen::Matrix3d R;
  // columns: north, east, down
  R << -sl * co, -so, -cl * co,  //
      -sl * so, co, -cl * so,    //
      cl, 0.0, -sl;
  return R;
}

Eigen::Vector3d gravity_ecef(const Eigen::Vector3d& p_ecef_m) {
  Eigen::Vector3d g;
  GeographicLib::NormalGravity::WGS84().U(p_ecef_m.x(), p_ecef_m.y(), p_ecef_m.z(), g.x(), g.y(), g.z());
  return g;
}

double meridian_radius_m(double lat_rad) {
  const double a = GeographicLib::Constants::WGS84_a();
  const double f = GeographicLib::Constants::WGS84_f();
  const double e2 = f * (2 - f);
  const double s = std::sin(lat_rad);
  const double w = 1 - e2 * s * s;
  return a * (1 - e2) / (w * std::sqrt(w));
}

double prime_vertical_radius_m(double lat_rad) {
  const double a = GeographicLib::Constants::WGS84_a();
  const double f = GeographicLib::Constants::WGS84_f();
  const double e2 = f * (2 - f);
  const double s = std::sin(lat_rad);
  return a / std::sqrt(1 - e2 * s * s);
}

}  // namespace augrig::nav
