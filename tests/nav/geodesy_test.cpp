// Tests for nav/geodesy.hpp against GeographicLib's own command-line tools (geographiclib-tools,
// installed by scripts/install-deps.sh): GeoConvert turns the test points, written in
// degrees-minutes-seconds with hemisphere letters, into signed decimal degrees; CartConvert gives
// ECEF and local east-north-up coordinates; GeodSolve gives geodesic distances, from which the
// radii of curvature follow. Plus hand-worked NED frames and the published WGS84 normal gravity
// at the equator and the poles. A missing tool fails the test; it is never skipped.
#include "nav/geodesy.hpp"

#include <array>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::nav {
namespace {

constexpr double kWgs84A = 6378137.0;
constexpr double kWgs84F = 1 / 298.257223563;

// Text of a double for a tool's input: fixed notation (the tools read "e" in "1e-05" as a
// hemisphere letter), 14 decimals (1e-14 degree, 1e-14 m).
std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.14f", v);
  return buf;
}

// Runs a GeographicLib tool on input lines (through a file, so quotes need no escaping) and
// returns the numbers of each output line. Fails the test when the tool is missing or fails.
std::vector<std::vector<double>> run_tool(const std::string& tool, const std::string& args,
                                          const std::vector<std::string>& lines) {
  std::string where;
  if (test::run_command("command -v " + tool, &where) != 0) {
    ADD_FAILURE() << tool << " not found on PATH: install geographiclib-tools (scripts/install-deps.sh); "
                  << "these tests compare nav/geodesy.cpp against it and must not be skipped";
    return {};
  }
  const std::string dir = test::output_dir("geodesy_" + tool);
  const std::string input = dir + "/input.txt";
  {
    std::ofstream f(input);
    for (const std::string& l : lines) f << l << "\n";
  }
  std::string out;
  const int rc = test::run_command(tool + " " + args + " --input-file " + input, &out);
  if (rc != 0) {
    ADD_FAILURE() << tool << " " << args << " failed (" << rc << "): " << out;
    return {};
  }
  std::vector<std::vector<double>> rows;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::vector<double> row;
    for (double v = 0; ls >> v;) row.push_back(v);
    rows.push_back(row);
  }
  if (rows.size() != lines.size()) ADD_FAILURE() << tool << " gave " << rows.size() << " lines: " << out;
  return rows;
}

struct Point {
  const char* dms;  // as a surveyor would write it, converted by GeoConvert
  double h_m;
};

// Equator, both poles (nearly), all four hemisphere combinations, the antimeridian, 12 km up,
// below the ellipsoid.
const Point kPoints[] = {
    {"0d0'0\"N 0d0'0\"E", 0.0},
    {"89d59'59.9\"N 45d0'0\"E", 100.0},
    {"89d59'30\"S 120d30'0\"W", 2835.0},
    {"33d51'35.9\"S 151d12'40\"E", 58.0},
    {"37d23'27.95\"N 122d2'16.17\"W", -6.776},
    {"51d28'40\"N 0d0'5.3\"W", 12000.0},
    {"31d30'N 35d30'E", -430.5},
    {"10d0'0\"S 179d59'59.99\"W", 500.25},
    {"0d0'0.1\"S 90d0'0\"E", 35786000.0},
};

std::vector<Geodetic> test_points() {
  std::vector<std::string> lines;
  for (const Point& p : kPoints) lines.emplace_back(p.dms);
  const auto rows = run_tool("GeoConvert", "-g -p 9", lines);
  std::vector<Geodetic> out;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].size(), 2u);
    if (rows[i].size() != 2) return {};
    out.push_back({deg_to_rad(rows[i][0]), deg_to_rad(rows[i][1]), kPoints[i].h_m});
  }
  return out;
}

std::string geodetic_line(const Geodetic& g) {
  return num(rad_to_deg(g.lat_rad)) + " " + num(rad_to_deg(g.lon_rad)) + " " + num(g.h_m);
}

TEST(Geodesy, GeoConvertGivesTheHemisphereSigns) {
  const std::vector<Geodetic> pts = test_points();
  ASSERT_EQ(pts.size(), std::size(kPoints));
  EXPECT_NEAR(rad_to_deg(pts[3].lat_rad), -(33 + 51 / 60.0 + 35.9 / 3600), 1e-12);
  EXPECT_NEAR(rad_to_deg(pts[3].lon_rad), 151 + 12 / 60.0 + 40 / 3600.0, 1e-12);
  EXPECT_LT(pts[2].lon_rad, 0);
  EXPECT_LT(pts[4].lon_rad, 0);
  EXPECT_LT(pts[7].lat_rad, 0);
}

TEST(Geodesy, EcefMatchesCartConvert) {
  const std::vector<Geodetic> pts = test_points();
  ASSERT_FALSE(pts.empty());
  std::vector<std::string> lines;
  for (const Geodetic& g : pts) lines.push_back(geodetic_line(g));
  const auto rows = run_tool("CartConvert", "-p 9", lines);
  ASSERT_EQ(rows.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 3u);
    const Eigen::Vector3d expected(rows[i][0], rows[i][1], rows[i][2]);
    const Eigen::Vector3d p = ecef_from_geodetic(pts[i]);
    EXPECT_LT((p - expected).norm(), 1e-4)
        << kPoints[i].dms << ": " << p.transpose() << " vs " << expected.transpose();
  }
}

TEST(Geodesy, GeodeticFromEcefMatchesCartConvertReverse) {
  const std::vector<Geodetic> pts = test_points();
  ASSERT_FALSE(pts.empty());
  // ECEF points a little off the test points, so the reverse is not fed its own forward output.
  std::vector<Eigen::Vector3d> ecef;
  std::vector<std::string> lines;
  for (const Geodetic& g : pts) {
    const Eigen::Vector3d p = ecef_from_geodetic(g) + Eigen::Vector3d(123.456, -78.9, 42.0);
    ecef.push_back(p);
    lines.push_back(num(p.x()) + " " + num(p.y()) + " " + num(p.z()));
  }
  const auto rows = run_tool("CartConvert", "-r -p 9", lines);
  ASSERT_EQ(rows.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 3u);
    const Geodetic g = geodetic_from_ecef(ecef[i]);
    const double dlat_m = (g.lat_rad - deg_to_rad(rows[i][0])) * meridian_radius_m(g.lat_rad);
    double dlon = g.lon_rad - deg_to_rad(rows[i][1]);
    dlon = std::remainder(dlon, 2 * kPi);
    const double dlon_m = dlon * prime_vertical_radius_m(g.lat_rad) * std::cos(g.lat_rad);
    EXPECT_LT(std::abs(dlat_m), 1e-4) << kPoints[i].dms;
    EXPECT_LT(std::abs(dlon_m), 1e-4) << kPoints[i].dms;
    EXPECT_LT(std::abs(g.h_m - rows[i][2]), 1e-4) << kPoints[i].dms;
    // And the round trip through our own forward.
    EXPECT_LT((ecef_from_geodetic(g) - ecef[i]).norm(), 1e-6) << kPoints[i].dms;
  }
}

TEST(Geodesy, NedFrameMatchesCartConvertLocalCartesian) {
  const std::vector<Geodetic> pts = test_points();
  ASSERT_FALSE(pts.empty());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Geodetic& o = pts[i];
    // Neighbours up to tens of kilometres away, above and below.
    std::vector<Geodetic> nb;
    for (const auto& d : {std::array<double, 3>{1e-4, 0, 0},
                          {0, 2e-4, 0},
                          {-3e-3, 5e-3, 500},
                          {0.2, -0.3, -1000},
                          {0, 0, 12000}}) {
      nb.push_back({o.lat_rad + deg_to_rad(d[0]), o.lon_rad + deg_to_rad(d[1]), o.h_m + d[2]});
      if (std::abs(rad_to_deg(nb.back().lat_rad)) > 90) nb.back().lat_rad = o.lat_rad - deg_to_rad(d[0]);
    }
    std::vector<std::string> lines;
    for (const Geodetic& g : nb) lines.push_back(geodetic_line(g));
    const auto rows = run_tool("CartConvert", "-p 9 -l " + geodetic_line(o), lines);
    ASSERT_EQ(rows.size(), nb.size());
    const Eigen::Matrix3d R = R_ecef_ned(o.lat_rad, o.lon_rad);
    const Eigen::Vector3d p0 = ecef_from_geodetic(o);
    for (std::size_t k = 0; k < nb.size(); ++k) {
      ASSERT_EQ(rows[k].size(), 3u);
      const Eigen::Vector3d ned = R.transpose() * (ecef_from_geodetic(nb[k]) - p0);
      const Eigen::Vector3d enu_expected(rows[k][0], rows[k][1], rows[k][2]);
      const Eigen::Vector3d enu(ned.y(), ned.x(), -ned.z());
      EXPECT_LT((enu - enu_expected).norm(), 1e-4) << kPoints[i].dms << " neighbour " << k << ": "
                                                   << enu.transpose() << " vs " << enu_expected.transpose();
    }
  }
}

TEST(Geodesy, NedFrameHandWorked) {
  const auto expect_frame = [](double lat_deg, double lon_deg, const Eigen::Vector3d& n,
                               const Eigen::Vector3d& e, const Eigen::Vector3d& d) {
    const Eigen::Matrix3d R = R_ecef_ned(deg_to_rad(lat_deg), deg_to_rad(lon_deg));
    EXPECT_LT((R.col(0) - n).norm(), 1e-15) << lat_deg << " " << lon_deg << " north " << R.col(0).transpose();
    EXPECT_LT((R.col(1) - e).norm(), 1e-15) << lat_deg << " " << lon_deg << " east " << R.col(1).transpose();
    EXPECT_LT((R.col(2) - d).norm(), 1e-15) << lat_deg << " " << lon_deg << " down " << R.col(2).transpose();
  };
  // On the equator at the prime meridian the point is on +X: north is +Z, east +Y, down -X.
  expect_frame(0, 0, {0, 0, 1}, {0, 1, 0}, {-1, 0, 0});
  // On the equator at 90 E the point is on +Y: east points to -X, down to -Y.
  expect_frame(0, 90, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0});
  // At the north pole (longitude 0): north is towards the prime meridian's far side (-X), down -Z.
  expect_frame(90, 0, {-1, 0, 0}, {0, 1, 0}, {0, 0, -1});
  // At 45 S on the antimeridian the point is at (-c, 0, -c): north tilts up and towards -X.
  const double c = std::sqrt(0.5);
  expect_frame(-45, 180, {-c, 0, c}, {0, -1, 0}, {c, 0, c});

  for (double lat : {-89.0, -30.0, 0.0, 12.5, 60.0, 89.9}) {
    for (double lon : {-179.0, -45.0, 0.0, 100.0}) {
      const Eigen::Matrix3d R = R_ecef_ned(deg_to_rad(lat), deg_to_rad(lon));
      EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-14);
      EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
      // Down is the ellipsoid normal, pointing inwards: -(geodetic normal).
      const Eigen::Vector3d up(std::cos(deg_to_rad(lat)) * std::cos(deg_to_rad(lon)),
                               std::cos(deg_to_rad(lat)) * std::sin(deg_to_rad(lon)),
                               std::sin(deg_to_rad(lat)));
      EXPECT_LT((R.col(2) + up).norm(), 1e-15);
    }
  }
}

TEST(Geodesy, NormalGravity) {
  // WGS84 normal gravity on the ellipsoid (NIMA TR8350.2): 9.7803253359 at the equator,
  // 9.8321849379 at the poles.
  const auto at = [](double lat_deg, double lon_deg, double h) {
    const Geodetic g{deg_to_rad(lat_deg), deg_to_rad(lon_deg), h};
    return std::pair{gravity_ecef(ecef_from_geodetic(g)), R_ecef_ned(g.lat_rad, g.lon_rad).col(2).eval()};
  };
  const auto [g_eq, down_eq] = at(0, 0, 0);
  EXPECT_NEAR(g_eq.norm(), 9.7803253359, 1e-8);
  const auto [g_np, down_np] = at(90, 0, 0);
  EXPECT_NEAR(g_np.norm(), 9.8321849379, 1e-8);
  const auto [g_sp, down_sp] = at(-90, 0, 0);
  EXPECT_NEAR(g_sp.norm(), 9.8321849379, 1e-8);
  for (double lat : {-75.0, -20.0, 0.0, 33.0, 51.5, 89.0}) {
    for (double lon : {-120.0, 0.0, 151.0}) {
      const auto [g0, down0] = at(lat, lon, 0);
      // On the ellipsoid (an equipotential surface of the normal field) gravity is along the normal.
      EXPECT_GT(g0.normalized().dot(down0), 1 - 1e-14) << lat << " " << lon;
      EXPECT_GT(g0.norm(), 9.78);
      EXPECT_LT(g0.norm(), 9.833);
      // 12 km up: still down within a few arc seconds, and weaker by the free-air gradient
      // (about 3.086e-6 s^-2 per metre).
      const auto [g12, down12] = at(lat, lon, 12000);
      EXPECT_GT(g12.normalized().dot(down12), std::cos(1e-4)) << lat << " " << lon;
      EXPECT_NEAR(g12.norm() - g0.norm(), -3.086e-6 * 12000, 1.5e-3) << lat << " " << lon;
    }
  }
}

TEST(Geodesy, RadiiOfCurvature) {
  const double e2 = kWgs84F * (2 - kWgs84F);
  EXPECT_NEAR(meridian_radius_m(0), kWgs84A * (1 - e2), 1e-6);
  EXPECT_NEAR(prime_vertical_radius_m(0), kWgs84A, 1e-6);
  EXPECT_NEAR(meridian_radius_m(kPi / 2), kWgs84A / std::sqrt(1 - e2), 1e-6);
  EXPECT_NEAR(prime_vertical_radius_m(kPi / 2), kWgs84A / std::sqrt(1 - e2), 1e-6);
  // Against GeodSolve: a short meridian arc is M * dlat, a short step along a parallel N cos(lat) dlon.
  const double lats[] = {-60.0, -10.0, 0.0, 25.0, 51.5, 80.0};
  constexpr double kStepDeg = 1e-3;
  std::vector<std::string> lines;
  for (double lat : lats) {
    lines.push_back(num(lat - kStepDeg / 2) + " 10 " + num(lat + kStepDeg / 2) + " 10");
    lines.push_back(num(lat) + " 10 " + num(lat) + " " + num(10 + kStepDeg));
  }
  const auto rows = run_tool("GeodSolve", "-i -p 10", lines);
  ASSERT_EQ(rows.size(), lines.size());
  for (std::size_t i = 0; i < std::size(lats); ++i) {
    const double lat = deg_to_rad(lats[i]);
    ASSERT_EQ(rows[2 * i].size(), 3u);
    ASSERT_EQ(rows[2 * i + 1].size(), 3u);
    const double m = rows[2 * i][2] / deg_to_rad(kStepDeg);
    const double n = rows[2 * i + 1][2] / (deg_to_rad(kStepDeg) * std::cos(lat));
    EXPECT_NEAR(meridian_radius_m(lat) / m, 1.0, 1e-9) << lats[i];
    EXPECT_NEAR(prime_vertical_radius_m(lat) / n, 1.0, 1e-9) << lats[i];
  }
}

}  // namespace
}  // namespace augrig::nav
