#include "nav/relative_pose.hpp"

#include <cmath>

namespace augrig::nav {

namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

}  // namespace

double RelativePose::sigma_position_m() const {
  return std::sqrt(cov.topLeftCorner<3, 3>().trace());
}
double RelativePose::sigma_attitude_rad() const {
  return std::sqrt(cov.bottomRightCorner<3, 3>().trace());
}

RelativePose relative_pose(const PoseWithCovariance& tanker, const PoseWithCovariance& receiver) {
  // Difference in ECEF first (both are ~6.4e6 m from the Earth's centre; the difference is what
  // matters and double keeps it to nanometres), then rotate into the tanker body frame.
  const Eigen::Matrix3d R_body_ecef = tanker.T_ecef_body.R().transpose();
  const Eigen::Vector3d d_ecef = receiver.T_ecef_body.translation_m - tanker.T_ecef_body.translation_m;
  RelativePose out;
  out.T_a_receiver.translation_m = R_body_ecef * d_ecef;
  out.T_a_receiver.rotation =
      (tanker.T_ecef_body.rotation.conjugate() * receiver.T_ecef_body.rotation).normalized();

  // Jacobians w.r.t. [dp_t, dth_t] and [dp_r, dth_r] (errors in ECEF):
  //   p = R_be (p_r - p_t):   dp = R_be (dp_r - dp_t) + R_be [d]x dth_t
  //   R = R_be R_er:          dth_body = R_be (dth_r - dth_t)
  Mat6 J_t = Mat6::Zero(), J_r = Mat6::Zero();
  J_t.topLeftCorner<3, 3>() = -R_body_ecef;
  J_t.topRightCorner<3, 3>() = R_body_ecef * skew(d_ecef);
  J_t.bottomRightCorner<3, 3>() = -R_body_ecef;
  J_r.topLeftCorner<3, 3>() = R_body_ecef;
  J_r.bottomRightCorner<3, 3>() = R_body_ecef;
  // The two aircraft's filters are independent (their common GPS error cancels in the difference
  // and is not part of either covariance's relative share).
  out.cov = J_t * tanker.cov * J_t.transpose() + J_r * receiver.cov * J_r.transpose();
  return out;
}

RelativePose in_frame(const Pose& T_x_body, const RelativePose& r) {
  RelativePose out;
  out.T_a_receiver = T_x_body * r.T_a_receiver;
  // p_x = R_xb p_b + t: position and attitude errors both rotate by R_xb.
  Mat6 J = Mat6::Zero();
  const Eigen::Matrix3d R = T_x_body.R();
  J.topLeftCorner<3, 3>() = R;
  J.bottomRightCorner<3, 3>() = R;
  out.cov = J * r.cov * J.transpose();
  return out;
}

}  // namespace augrig::nav
