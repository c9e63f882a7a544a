// Pose: a rigid transform T_a_b in double precision (see core/conventions.hpp for naming),
// plus Euler ZYX helpers. Poses stay double until they are camera-relative; only then may a
// renderer narrow them to float for the GPU.
#pragma once

#include <algorithm>
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace augrig {

struct Pose {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // R_a_b
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();       // origin of b expressed in a

  static Pose identity() { return {}; }
  static Pose from(const Eigen::Matrix3d& R_a_b, const Eigen::Vector3d& t_a_b_m) {
    return {Eigen::Quaterniond(R_a_b).normalized(), t_a_b_m};
  }
  static Pose from_matrix(const Eigen::Matrix4d& T) {
    return from(T.topLeftCorner<3, 3>(), T.topRightCorner<3, 1>());
  }

  Eigen::Matrix3d R() const { return rotation.toRotationMatrix(); }
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = R();
    T.topRightCorner<3, 1>() = translation_m;
    return T;
  }
  Pose inverse() const {
    const Eigen::Quaterniond qi = rotation.conjugate();
    return {qi, -(qi * translation_m)};
  }
  // T_a_c = T_a_b * T_b_c
  Pose operator*(const Pose& T_b_c) const {
    return {(rotation * T_b_c.rotation).normalized(), rotation * T_b_c.translation_m + translation_m};
  }
  // p_a = T_a_b * p_b
  Eigen::Vector3d operator*(const Eigen::Vector3d& p_b) const { return rotation * p_b + translation_m; }
};

// R = Rz(yaw) * Ry(pitch) * Rx(roll)   (intrinsic Z-Y'-X'', core/conventions.hpp)
inline Eigen::Matrix3d rotation_from_ypr(double yaw_rad, double pitch_rad, double roll_rad) {
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

struct YawPitchRoll {
  double yaw_rad = 0, pitch_rad = 0, roll_rad = 0;
};

// Inverse of rotation_from_ypr; pitch in [-pi/2, pi/2]. At |pitch| = pi/2 roll is set to 0.
inline YawPitchRoll ypr_from_rotation(const Eigen::Matrix3d& R) {
  YawPitchRoll e;
  const double s = -R(2, 0);
  e.pitch_rad = std::asin(std::clamp(s, -1.0, 1.0));
  if (std::abs(s) > 1.0 - 1e-12) {
    e.roll_rad = 0.0;
    e.yaw_rad = std::atan2(-R(0, 1), R(1, 1));
  } else {
    e.roll_rad = std::atan2(R(2, 1), R(2, 2));
    e.yaw_rad = std::atan2(R(1, 0), R(0, 0));
  }
  return e;
}

inline Pose pose_from_ypr(const Eigen::Vector3d& t_m, double yaw_rad, double pitch_rad, double roll_rad) {
  return Pose::from(rotation_from_ypr(yaw_rad, pitch_rad, roll_rad), t_m);
}

}  // namespace augrig
