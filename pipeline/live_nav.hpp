// live_nav: the nav stage of `augrig run`. The live nav inputs (--nav STREAM=URI; a stream belongs
// to the aircraft its name starts with: tanker.gps, receiver.imu, ...) feed one nav::LiveFusion
// per aircraft. Each camera frame then asks for the receiver relative to that camera at its
// mid-exposure time on the nav clock (GPS time), and gets, with the pose, a verdict in plain words:
//   no pose   a filter not initialised yet, or the frame too far past the newest IMU sample;
//   stale     the newest valid fix of either aircraft at or before the frame's time, or its
//             newest IMU sample then, older than stale_after_s (the pose is dead-reckoned or
//             extrapolated); a frame asked about late, after the silence ended, is still stale;
//   good      otherwise;
// A moving-baseline rover's vectors (on a receiver.* stream) correct the relative position where
// they reach (docs/NAV_LIVE.md); the HUD says so.
// And, apart from those, whether either filter is still converging (nav::LiveFusionStatus::converged:
// its attitude sigmas still falling, its sigma optimistic; docs/NAV_FUSION.md, "Consistency").
// Frames reach the nav clock through the camera clocks' calibrated offsets to GPS time (the
// simulation, cameras on PTP/GPS time) or, for host-timed frames, through host_to_nav(): the GPS
// fixes' times of validity against their host arrival times (a lower envelope, capture/
// clock_offset.hpp), which leaves the receiver's constant output latency in the offset. Both
// aircraft share that error, so the relative pose suffers only its relative motion times it.
#pragma once

#include <array>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "pipeline/baseline_nav.hpp"
#include "pipeline/flight_nav.hpp"
#include "pipeline/status.hpp"
#include "capture/clock_offset.hpp"
#include "nav/camera_clock.hpp"
#include "nav/live_fusion.hpp"
#include "nav/live_input.hpp"

namespace augrig::pipeline {

class TankerRates;  // pipeline/camera_clock_online.hpp

enum class Aircraft : std::uint8_t { kTanker = 0, kReceiver = 1 };
std::string_view to_string(Aircraft a);
// The aircraft a stream name belongs to ("tanker.gps" -> tanker); nullopt for other names.
std::optional<Aircraft> aircraft_of_stream(std::string_view stream);

struct LiveNavOptions {
  double stale_after_s = 0.5;
  nav::LiveFusionOptions fusion;
  nav::BaselineFusionOptions baseline;
};

// One frame's nav.
struct FrameNav {
  std::optional<FramePose> pose;      // unset: no pose (see problems)
  bool stale = false;                 // a pose, but from data older than stale_after_s
  bool converging = false;            // a pose, but a filter not yet converged: its sigma is optimistic
  std::string converging_text;        // plain words, e.g. "receiver nav converging: ..."; empty otherwise
  std::vector<std::string> problems;  // plain words, e.g. "receiver GPS: no fix for 2.4 s"
  NavHud hud;
};

class LiveNav {
 public:
  LiveNav(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
          const nav::InsConfig& tanker, const nav::InsConfig& receiver, const LiveNavOptions& options = {});

  // From the input threads.
  void add(Aircraft aircraft, const nav::NavEvent& event);

  // The receiver in `camera` (rig index) at t_nav_ns.
  FrameNav at(int camera, TimestampNs t_nav_ns) const;

  // Host CLOCK_MONOTONIC to the nav clock, from the fixes received so far; an Error before any.
  Expected<TimestampNs> host_to_nav(TimestampNs host_ns) const;

  nav::LiveFusionStatus status(Aircraft aircraft) const;
  // The tanker's gyro increments, on GPS time, also to `rates` (the online camera clocks,
  // pipeline/camera_clock_online.hpp). Set before the inputs start.
  void feed_tanker_rates(std::shared_ptr<TankerRates> rates) { tanker_rates_ = std::move(rates); }
  // The tanker's attitude, ground velocity and height above flat terrain at terrain_height_m, from
  // its live fusion at a GPS time (within its history): the camera clocks' parallax removal.
  nav::GroundMotionFunction tanker_ground_motion(double terrain_height_m = 0) const;

  // The moving baseline's live fusion (a UBX rover's NAV-RELPOSNED on a receiver.* stream): what it
  // received and used; measurements == 0 when none came.
  LiveBaselineReport baseline_report() const { return baseline_.report(); }

 private:
  Rig rig_;
  BoomDimensions boom_;
  Eigen::Vector3d receptacle_m_;
  LiveNavOptions options_;
  std::array<std::unique_ptr<nav::LiveFusion>, 2> fusion_;
  // The moving baseline: the recent vectors, carried to each frame's time (pipeline/baseline_nav.hpp).
  LiveBaseline baseline_;
  mutable std::mutex clock_mutex_;
  ClockOffsetEstimator gps_to_host_;
  std::shared_ptr<TankerRates> tanker_rates_;  // "device" = GPS time, host = arrival
};

}  // namespace augrig::pipeline
