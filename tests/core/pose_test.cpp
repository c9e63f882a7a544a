// Conventions by hand-worked cases: Euler ZYX, FRD/NED, T_a_b composition.
#include "core/pose.hpp"

#include <gtest/gtest.h>

#include "core/conventions.hpp"

namespace augrig {
namespace {

using Eigen::Vector3d;

TEST(Conventions, YawNinetyPointsNoseEast) {
  // Heading 90 deg: the body x axis (nose) points east = NED +y.
  const Eigen::Matrix3d R_ned_body = rotation_from_ypr(deg_to_rad(90), 0, 0);
  EXPECT_TRUE((R_ned_body * Vector3d::UnitX()).isApprox(Vector3d::UnitY(), 1e-12));
  // The right wing (body +y) then points south = NED -x.
  EXPECT_TRUE((R_ned_body * Vector3d::UnitY()).isApprox(-Vector3d::UnitX(), 1e-12));
}

TEST(Conventions, PositivePitchRaisesTheNose) {
  const Eigen::Matrix3d R = rotation_from_ypr(0, deg_to_rad(30), 0);
  const Vector3d nose = R * Vector3d::UnitX();
  EXPECT_NEAR(nose.x(), std::cos(deg_to_rad(30)), 1e-12);
  EXPECT_NEAR(nose.z(), -0.5, 1e-12);  // up is -z in NED
}

TEST(Conventions, PositiveRollDropsTheRightWing) {
  const Eigen::Matrix3d R = rotation_from_ypr(0, 0, deg_to_rad(30));
  const Vector3d right_wing = R * Vector3d::UnitY();
  EXPECT_NEAR(right_wing.z(), 0.5, 1e-12);  // down is +z
}

TEST(Conventions, EulerOrderIsYawThenPitchThenRoll) {
  // yaw 90, pitch 90: nose straight up regardless of yaw; with intrinsic Z-Y'-X'' the right
  // wing keeps pointing south (yaw applied first).
  const Eigen::Matrix3d R = rotation_from_ypr(deg_to_rad(90), deg_to_rad(45), 0);
  const Vector3d nose = R * Vector3d::UnitX();
  EXPECT_TRUE(nose.isApprox(Vector3d(0, std::sqrt(0.5), -std::sqrt(0.5)), 1e-12));
}

TEST(Conventions, EulerRoundTrip) {
  for (double yaw : {-170.0, -30.0, 0.0, 45.0, 179.0})
    for (double pitch : {-80.0, -10.0, 0.0, 25.0, 89.0})
      for (double roll : {-120.0, 0.0, 15.0, 175.0}) {
        const auto e =
            ypr_from_rotation(rotation_from_ypr(deg_to_rad(yaw), deg_to_rad(pitch), deg_to_rad(roll)));
        EXPECT_TRUE(
            rotation_from_ypr(e.yaw_rad, e.pitch_rad, e.roll_rad)
                .isApprox(rotation_from_ypr(deg_to_rad(yaw), deg_to_rad(pitch), deg_to_rad(roll)), 1e-9));
        EXPECT_NEAR(e.pitch_rad, deg_to_rad(pitch), 1e-9);
      }
}

TEST(Pose, ComposeAndInvert) {
  const Pose T_a_b = pose_from_ypr({1, 2, 3}, 0.3, -0.2, 0.1);
  const Pose T_b_c = pose_from_ypr({-4, 0.5, 2}, -1.0, 0.4, 0.7);
  const Vector3d p_c(0.7, -1.1, 5.0);
  EXPECT_TRUE(((T_a_b * T_b_c) * p_c).isApprox(T_a_b * (T_b_c * p_c), 1e-12));
  EXPECT_TRUE((T_a_b.inverse() * (T_a_b * p_c)).isApprox(p_c, 1e-12));
  EXPECT_TRUE((T_a_b * T_a_b.inverse()).matrix().isApprox(Eigen::Matrix4d::Identity(), 1e-12));
}

TEST(Pose, TimeConversionsRound) {
  EXPECT_EQ(s_to_ns(1.5), 1'500'000'000);
  EXPECT_EQ(s_to_ns(-0.25), -250'000'000);
  EXPECT_DOUBLE_EQ(ns_to_s(2'000'000'000), 2.0);
  EXPECT_EQ(to_string(ClockDomain::kHostMonotonic), "host_monotonic");
}

}  // namespace
}  // namespace augrig
