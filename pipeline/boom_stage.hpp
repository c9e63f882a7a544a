// The boom stage of the pipeline: each frame's boom articulation, from what the pose source gave
// (a scene's, a recording's or the simulation's boom) or from the mode in force:
//   fixed      the --boom fixed:EL,AZ,EXT articulation (or the pose source's boom as it comes);
//   scripted   a timeline (render/boom_control.hpp's BoomScript), t in seconds from the source's
//              first frame: a recording's or a EuRoC folder's first frame whatever the start, else
//              the run's first frame;
//   track      the nozzle aimed at the receptacle where the frame's receiver pose puts it;
//   interactive the operator's, nudged from the window and clamped to the rig's limits.
// What the stage commands is clamped to the rig's limits; a pose source's boom is used as given. Without a receiver pose nothing is tracked:
// the boom holds its last articulation.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

#include "pipeline/status.hpp"
#include "render/augmenter.hpp"
#include "render/boom_control.hpp"
#include "render/rig.hpp"

namespace augrig::pipeline {

// A boom given by the user (--boom): track (the receptacle, from the poses), fixed:EL_DEG,AZ_DEG,
// EXT_M, or script:FILE.csv. A script's times are seconds from the source's first frame: the
// recording's (or EuRoC folder's) first frame, also when the run starts later in it (--from-frame,
// --seek); a live or simulated source's first frame processed.
struct BoomArg {
  BoomMode mode = BoomMode::kTrackReceptacle;
  BoomArticulation fixed;
  BoomScript script;
  // The articulation for a frame `t_s` after the first, given what tracking would command.
  BoomCommand command(double t_s, const BoomCommand& tracked, const BoomLimits& limits) const;
};

class BoomStage {
 public:
  // `arg`: the user's boom; none: the pose source's boom as it comes (kFixed shows it as such).
  // `dims`: the boom's geometry tracking aims with (the scenario's, or the built-in boom's).
  BoomStage(const Rig& rig, const Eigen::Vector3d& receptacle_m, std::optional<BoomArg> arg,
            const BoomDimensions& dims = {});

  // Sets scene.boom for a frame `t_s` after the source's first frame (above), and how fast it moves
  // (scene.boom_rate_per_s, the camera look's motion blur): a script's slope (the articulation a
  // millisecond either side); a tracking boom's or the pose source's change since the last frame
  // (none across a gap over kMaxRateGap_s or back in time: a seek, a loop); a fixed or
  // hand-flown boom holds still (a nudge is a step, not a motion over an exposure).
  void apply(SceneState& scene, double t_s);
  static constexpr double kMaxRateGap_s = 0.25;

  DisplayBoomMode mode() const { return mode_; }
  // Taking the boom by hand (again) starts where it is: the hand boom of an earlier take-over is
  // forgotten when another mode flies it.
  void set_mode(DisplayBoomMode m) {
    if (!(m == DisplayBoomMode::kInteractive && mode_ == DisplayBoomMode::kInteractive)) interactive_.reset();
    mode_ = m;
  }
  // Moves the interactive boom (from the window); selects interactive mode.
  void nudge(const BoomNudge& n);
  // "track", "fixed (the scene's)", ... for banners and the HUD.
  std::string describe() const;

 private:
  Rig rig_;
  Eigen::Vector3d receptacle_m_;
  BoomDimensions dims_;
  std::optional<BoomArg> arg_;
  DisplayBoomMode mode_ = DisplayBoomMode::kFixed;
  std::optional<BoomArticulation> interactive_, last_;
  double last_t_s_ = 0;
  DisplayBoomMode last_mode_ = DisplayBoomMode::kFixed;
  BoomArticulation rate(const BoomArticulation& now, double t_s) const;
};

}  // namespace augrig::pipeline
