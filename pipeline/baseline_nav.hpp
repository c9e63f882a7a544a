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
//   LiveBaseline      the real-time use (augrig run, a UBX rover on a receiver.* stream): a
//                     forward filter's solution jumps at every fix it takes (decimetres with
//                     single-point GPS), so a vector's error against it is stale a fix later. Each
//                     recent vector (within window_s) is carried instead to the frame's time by the
//                     two solutions' relative motion, which does not jump: their velocities
//                     (trapezoid) and attitudes (the antennas' lever arms) between the two times.
//                     The carried vectors are averaged, weighted by their accuracy and the relative
//                     velocity's uncertainty times their age; one farther than 5 sigma from the
//                     average is left out.
// The correction moves the receiver's position (the relative position is what matters) and gives
// the relative position the fusion's covariance; attitudes are untouched.
#pragma once

#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
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

// The antenna-to-antenna vector (NED at the tanker's antenna) of two states, with the sum of their
// position covariances (NED), and the rotation of that NED frame.
struct InsBaseline : nav::InsBaselineSample {
  Eigen::Matrix3d R_ecef_ned = Eigen::Matrix3d::Identity();
};
InsBaseline ins_baseline(const nav::NavState& tanker, const nav::NavState& receiver,
                         const Eigen::Vector3d& tanker_antenna_body_m, const Eigen::Vector3d& receiver_antenna_body_m);
// Applies a correction of the INS baseline to the two states: the receiver's position moved, the
// relative position's covariance replaced (tanker position covariance and position cross terms
// zeroed).
void apply_baseline_correction(const nav::BaselineCorrection& c, const InsBaseline& ib, nav::NavState& tanker,
                               nav::NavState& receiver);

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


 private:
  std::optional<nav::BaselineFusion> fusion_;
  Eigen::Vector3d tanker_antenna_m_ = Eigen::Vector3d::Zero(), receiver_antenna_m_ = Eigen::Vector3d::Zero();
};

struct LiveBaselineReport {
  std::uint64_t received = 0, invalid = 0, float_skipped = 0, out_of_order = 0;
  std::string summary() const;  // "moving baseline: N vectors received: ..."
};

class LiveBaseline {
 public:
  explicit LiveBaseline(const nav::BaselineFusionOptions& options = {}, double window_s = 1.0,
                        double min_relative_sigma_mps = 0.2);
  // From an input thread, in time order (an older one is counted out of order and left out).
  void add(const nav::BaselineMeasurement& m);
  // Both solutions at a past time (nullopt: not kept any more).
  using StatesAt = std::function<bool(TimestampNs t_ns, nav::NavState& tanker, nav::NavState& receiver)>;
  // The correction of the INS baseline of `tanker` and `receiver` (the states at t_ns); nullopt when
  // no usable vector lies within window_s before t_ns.
  std::optional<nav::BaselineCorrection> at(TimestampNs t_ns, const nav::NavState& tanker,
                                            const nav::NavState& receiver, const StatesAt& states_at,
                                            const Eigen::Vector3d& tanker_antenna_body_m,
                                            const Eigen::Vector3d& receiver_antenna_body_m) const;
  LiveBaselineReport report() const;

 private:
  nav::BaselineFusionOptions options_;
  TimestampNs window_ns_;
  double min_relative_sigma_mps_;
  mutable std::mutex mutex_;
  std::deque<nav::BaselineMeasurement> recent_;  // usable, newest last, window_s and a bit more
  LiveBaselineReport report_;
  TimestampNs last_ns_ = 0;
};

}  // namespace augrig::pipeline
