// baseline_nav: a moving-baseline RTK rover's log (u-blox NAV-RELPOSNED: the receiver's GPS antenna
// relative to the tanker's, the moving base) fused into the relative navigation of `augrig nav`.
//   load_rover_log()  the UBX log's NAV-RELPOSNED messages as nav::BaselineMeasurement on GPS time:
//                     each time of week resolved to the GPS week that puts it nearest the previous
//                     one, starting from a reference time (the GPS logs' first fix)
//   BaselineNav       nav::BaselineFusion of the measurements against the INS baseline of the two
//                     aircraft's solutions (their GPS antennas: aircraft.yaml lever_arm_m) and its
//                     covariance (the two antennas' position covariances): the INS baseline's error
//                     at any time, combined with what the absolute solutions say of it. With
//                     metres-off absolute GPS the baseline decides; with RTK on both the two average.
// The correction moves the receiver's position (the relative position is what matters) and gives
// the relative position the fusion's covariance; attitudes are untouched.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "nav/baseline_fusion.hpp"
#include "nav/ins.hpp"
#include "nav/ubx.hpp"

namespace augrig::pipeline {

struct RoverLog {
  std::string path;
  std::vector<nav::BaselineMeasurement> measurements;  // one per NAV-RELPOSNED, file order
  nav::UbxStreamCounts counts;                         // frames and bytes, as read
  std::size_t pvt = 0, other_frames = 0, truncated_bytes = 0;
  nav::LogIssues issues;  // damaged frames and messages, "FILE: offset N: ..."
  std::string summary() const;  // one line: what was read, every count
};
// Errors: the file cannot be read, is not UBX, or holds no NAV-RELPOSNED.
Expected<RoverLog> load_rover_log(const std::string& path, TimestampNs reference_gps_ns);

class BaselineNav {
 public:
  // Antennas in each aircraft's body frame (FRD), metres.
  static Expected<BaselineNav> fuse(const std::vector<nav::BaselineMeasurement>& measurements,
                                    const nav::NavTrajectory& tanker, const nav::NavTrajectory& receiver,
                                    const Eigen::Vector3d& tanker_antenna_body_m,
                                    const Eigen::Vector3d& receiver_antenna_body_m,
                                    const nav::BaselineFusionOptions& options = {});
  // Corrects the two states at t_nav_ns in place (the receiver's position moved, the relative
  // position's covariance replaced, tanker position covariance and position cross terms zeroed).
  // False, states untouched: no correction there (before, after or in a gap of the baseline).
  bool correct(TimestampNs t_nav_ns, nav::NavState& tanker, nav::NavState& receiver) const;
  const nav::BaselineFusionReport& report() const { return fusion_->report(); }

  // The antenna-to-antenna vector (NED at the tanker's antenna) of two states, and its covariance
  // from their position covariances.
  struct InsBaseline : nav::InsBaselineSample {
    Eigen::Matrix3d R_ecef_ned;
  };
  InsBaseline ins_baseline(const nav::NavState& tanker, const nav::NavState& receiver) const;

 private:
  std::optional<nav::BaselineFusion> fusion_;
  Eigen::Vector3d tanker_antenna_m_ = Eigen::Vector3d::Zero(), receiver_antenna_m_ = Eigen::Vector3d::Zero();
};

}  // namespace augrig::pipeline
