// Relative pose: checked against GeographicLib's LocalCartesian (an independent route through the
// tangent plane at the tanker) and its covariance against Monte Carlo.
#include "nav/relative_pose.hpp"

#include <gtest/gtest.h>

#include <random>

#include <GeographicLib/LocalCartesian.hpp>

#include "core/conventions.hpp"
#include "nav/geodesy.hpp"

namespace augrig::nav {
namespace {

Pose ecef_pose(const Geodetic& g, double yaw_rad, double pitch_rad, double roll_rad) {
  const Eigen::Matrix3d R_ecef_body =
      R_ecef_ned(g.lat_rad, g.lon_rad) * rotation_from_ypr(yaw_rad, pitch_rad, roll_rad);
  return Pose::from(R_ecef_body, ecef_from_geodetic(g));
}

TEST(RelativePose, MatchesLocalCartesianAtTheTanker) {
  // Tanker over southern Germany at 7 km heading 090, level; receiver a few tens of metres away
  // given by geodetic coordinates (so the test does not reuse the code's own ECEF path).
  const Geodetic tk{deg_to_rad(48.1), deg_to_rad(11.5), 7000.0};
  const Geodetic rx{deg_to_rad(48.1) - deg_to_rad(2e-5), deg_to_rad(11.5) - deg_to_rad(2.7e-4), 6990.0};
  const double yaw = deg_to_rad(90.0);
  const RelativePose r = relative_pose({ecef_pose(tk, yaw, 0, 0), {}}, {ecef_pose(rx, yaw, 0, 0), {}});

  const GeographicLib::LocalCartesian lc(48.1, 11.5, 7000.0);
  double e = 0, n = 0, u = 0;
  lc.Forward(rad_to_deg(rx.lat_rad), rad_to_deg(rx.lon_rad), rx.h_m, e, n, u);
  // NED -> body FRD for yaw 090, level: forward = east, right = south, down = down.
  const Eigen::Vector3d expect(e, -n, -u);
  EXPECT_LT((r.T_a_receiver.translation_m - expect).norm(), 1e-6)
      << r.T_a_receiver.translation_m.transpose() << " vs " << expect.transpose();
  // Same yaw in nearby NED frames: the relative rotation is only the tilt between the two frames
  // (the receiver's NED is rotated by the arc between them, a few microradians).
  EXPECT_LT(Eigen::AngleAxisd(r.T_a_receiver.rotation).angle(), 1e-5);
}

TEST(RelativePose, HandWorkedAttitude) {
  const Geodetic p{deg_to_rad(-33.9), deg_to_rad(151.2), 3000.0};
  const Pose tk = ecef_pose(p, deg_to_rad(30), 0, 0);
  const Pose rx = ecef_pose(p, deg_to_rad(40), deg_to_rad(2), deg_to_rad(-3));
  const RelativePose r = relative_pose({tk, {}}, {rx, {}});
  const YawPitchRoll e = ypr_from_rotation(r.T_a_receiver.R());
  // Receiver yaw 10 deg to the right of the tanker; its pitch and roll are about its own axes.
  const Eigen::Matrix3d expect = rotation_from_ypr(deg_to_rad(10), deg_to_rad(2), deg_to_rad(-3));
  EXPECT_LT((r.T_a_receiver.R() - expect).norm(), 1e-12);
  EXPECT_NEAR(rad_to_deg(e.yaw_rad), 10.0, 1e-9);
}

TEST(RelativePose, CovarianceMatchesMonteCarlo) {
  const Geodetic tk{deg_to_rad(35), deg_to_rad(-117), 6000};
  const Pose T_t = ecef_pose(tk, deg_to_rad(123), deg_to_rad(3), deg_to_rad(20));
  const Pose T_r = T_t * Pose::from(rotation_from_ypr(0.05, -0.02, 0.1), Eigen::Vector3d(-25, 3, 8));
  Mat6 Ct = Mat6::Zero(), Cr = Mat6::Zero();
  Ct.diagonal() << 0.02, 0.03, 0.04, 1e-3, 2e-3, 3e-3;
  Cr.diagonal() << 0.05, 0.01, 0.02, 3e-3, 1e-3, 2e-3;
  Ct = Ct.cwiseProduct(Ct);
  Cr = Cr.cwiseProduct(Cr);
  const RelativePose r = relative_pose({T_t, Ct}, {T_r, Cr});
  const Pose T_cam_body = Pose::from(rotation_from_ypr(3.0, -0.4, 0.1), Eigen::Vector3d(2.0, 0.3, 0.5));
  const RelativePose rc = in_frame(T_cam_body, r);

  std::mt19937_64 rng(42);
  std::normal_distribution<double> n01;
  auto perturb = [&](const Pose& T, const Mat6& C) {
    Eigen::Matrix<double, 6, 1> d;
    for (int i = 0; i < 6; ++i) d(i) = n01(rng) * std::sqrt(C(i, i));
    const Eigen::Vector3d th = d.tail<3>();
    Pose out = T;
    out.translation_m += d.head<3>();
    if (th.norm() > 0) {
      out.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(th.norm(), th.normalized())) * T.rotation;
    }
    return out;
  };
  const int N = 20000;
  Mat6 S = Mat6::Zero();
  for (int i = 0; i < N; ++i) {
    const RelativePose s = in_frame(T_cam_body, relative_pose({perturb(T_t, Ct), {}}, {perturb(T_r, Cr), {}}));
    Eigen::Matrix<double, 6, 1> d;
    d.head<3>() = s.T_a_receiver.translation_m - rc.T_a_receiver.translation_m;
    const Eigen::AngleAxisd aa(s.T_a_receiver.rotation * rc.T_a_receiver.rotation.conjugate());
    d.tail<3>() = aa.angle() * aa.axis();
    S += d * d.transpose();
  }
  S /= N;
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(std::sqrt(S(i, i)), std::sqrt(rc.cov(i, i)), 0.03 * std::sqrt(rc.cov(i, i))) << "axis " << i;
  }
  EXPECT_NEAR(std::sqrt(S.topLeftCorner<3, 3>().trace()), rc.sigma_position_m(), 0.02 * rc.sigma_position_m());
}

}  // namespace
}  // namespace augrig::nav
