#include "render/motion_blur.hpp"

#include <algorithm>
#include <cmath>

namespace augrig {

BoomArticulation articulation_at(const BoomArticulation& mid, const BoomArticulation& rate_per_s,
                                 double dt_s) {
  return {mid.elevation_rad + rate_per_s.elevation_rad * dt_s,
          mid.azimuth_rad + rate_per_s.azimuth_rad * dt_s, mid.extension_m + rate_per_s.extension_m * dt_s};
}

bool moves(const BoomArticulation& r) {
  return r.elevation_rad != 0 || r.azimuth_rad != 0 || r.extension_m != 0;
}

double boom_motion_px(const BoomModel& boom, const Eigen::Vector3d& pivot_body_m, const RigCamera& cam,
                      const BoomArticulation& mid, const BoomArticulation& rate_per_s, double exposure_s) {
  if (!(exposure_s > 0) || !moves(rate_per_s)) return 0;
  const BoomArticulation a0 = articulation_at(mid, rate_per_s, -0.5 * exposure_s);
  const BoomArticulation a1 = articulation_at(mid, rate_per_s, 0.5 * exposure_s);
  const Pose T_cam_body = cam.T_body_cam.inverse();
  const Pose T_fixed[2] = {T_cam_body * boom_pose(pivot_body_m, a0),
                           T_cam_body * boom_pose(pivot_body_m, a1)};
  const Pose T_tele[2] = {T_fixed[0] * telescope_pose(a0), T_fixed[1] * telescope_pose(a1)};
  const double max_radius = cam.model.max_valid_radius();
  double most = 0;
  auto visit = [&](const Model& m, const Pose* T) {
    for (const Mesh& mesh : m.meshes)
      for (const Eigen::Vector3f& v : mesh.positions_m) {
        const Eigen::Vector3d p = v.cast<double>();
        const Eigen::Vector3d q0 = T[0] * p, q1 = T[1] * p;
        if (q0.z() < cam.near_m || q1.z() < cam.near_m) continue;
        const auto u0 = cam.model.project(q0, max_radius), u1 = cam.model.project(q1, max_radius);
        if (u0 && u1) most = std::max(most, (*u1 - *u0).norm());
      }
  };
  visit(boom.fixed, T_fixed);
  visit(boom.telescope, T_tele);
  return most;
}

int motion_samples(double motion_px) {
  if (!(motion_px >= kMotionMinPx)) return 1;
  return std::clamp(static_cast<int>(std::ceil(motion_px / kMotionStepPx)), 2, kMaxMotionSamples);
}

}  // namespace augrig
