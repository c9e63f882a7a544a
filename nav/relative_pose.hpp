// Relative pose: the receiver in the tanker's body frame and in each camera, from both aircraft's
// fused poses in ECEF. Everything stays double and is made camera-relative here, before anything
// reaches float or the GPU. First-order covariance propagation gives each relative pose a 1-sigma.
#pragma once

#include <Eigen/Core>

#include "core/pose.hpp"

namespace augrig::nav {

using Mat6 = Eigen::Matrix<double, 6, 6>;

// An absolute pose with its uncertainty. Covariance order: [position (3), attitude (3)], both in
// ECEF axes; the attitude error is left-multiplicative: R_true = Exp(dtheta) * R_estimate.
struct PoseWithCovariance {
  Pose T_ecef_body;
  Mat6 cov = Mat6::Zero();
};

// T_a_receiver with its covariance in frame a's axes, same order and error convention as above
// (R_true = Exp(dtheta_a) * R_estimate).
struct RelativePose {
  Pose T_a_receiver;
  Mat6 cov = Mat6::Zero();
  double sigma_position_m() const;   // sqrt(trace of the position block)
  double sigma_attitude_rad() const; // sqrt(trace of the attitude block)
};

// The receiver body frame in the tanker body frame: T_body_receiver = T_ecef_tanker^-1 * T_ecef_receiver.
RelativePose relative_pose(const PoseWithCovariance& tanker, const PoseWithCovariance& receiver);

// Re-expresses a relative pose in another frame fixed to the tanker: T_x_receiver = T_x_body * T_body_receiver.
// T_x_body is calibration (T_cam_body for a camera) and carries no uncertainty here.
RelativePose in_frame(const Pose& T_x_body, const RelativePose& body_relative);

}  // namespace augrig::nav
