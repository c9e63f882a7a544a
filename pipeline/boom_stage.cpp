#include "pipeline/boom_stage.hpp"

namespace augrig::pipeline {

std::string_view to_string(DisplayBoomMode m) {
  switch (m) {
    case DisplayBoomMode::kFixed:
      return "fixed";
    case DisplayBoomMode::kScripted:
      return "scripted";
    case DisplayBoomMode::kTrackReceptacle:
      return "track";
    case DisplayBoomMode::kInteractive:
      return "interactive";
  }
  return "?";
}

BoomCommand BoomArg::command(double t_s, const BoomCommand& tracked, const BoomLimits& limits) const {
  switch (mode) {
    case BoomMode::kFixed:
      return clamp_to_limits(fixed, limits);
    case BoomMode::kScripted:
      return clamp_to_limits(script.at(t_s), limits);
    case BoomMode::kTrackReceptacle:
      break;
  }
  return tracked;
}

BoomStage::BoomStage(const Rig& rig, const Eigen::Vector3d& receptacle_m, std::optional<BoomArg> arg,
                     const BoomDimensions& dims)
    : rig_(rig), receptacle_m_(receptacle_m), dims_(dims), arg_(std::move(arg)) {
  if (arg_)
    mode_ = arg_->mode == BoomMode::kTrackReceptacle ? DisplayBoomMode::kTrackReceptacle
            : arg_->mode == BoomMode::kScripted      ? DisplayBoomMode::kScripted
                                                     : DisplayBoomMode::kFixed;
}

BoomArticulation BoomStage::rate(const BoomArticulation& now, double t_s) const {
  const double dt = t_s - last_t_s_;
  // A new mode's first frame jumps from where the last one left the boom: no motion.
  if (!last_ || last_mode_ != mode_ || !(dt > 0 && dt <= kMaxRateGap_s)) return {};
  return {(now.elevation_rad - last_->elevation_rad) / dt, (now.azimuth_rad - last_->azimuth_rad) / dt,
          (now.extension_m - last_->extension_m) / dt};
}

void BoomStage::apply(SceneState& scene, double t_s) {
  scene.boom_rate_per_s = {};
  switch (mode_) {
    case DisplayBoomMode::kTrackReceptacle:
      // Without a receiver pose there is nothing to track: the boom holds still.
      if (scene.receiver_present) {
        scene.boom = track_point(scene.T_body_receiver * receptacle_m_, rig_.boom.pivot_body_m, dims_,
                                 rig_.boom.limits)
                         .articulation;
        scene.boom_rate_per_s = rate(scene.boom, t_s);
      } else if (last_) {
        scene.boom = *last_;
      }
      break;
    case DisplayBoomMode::kScripted:
    case DisplayBoomMode::kFixed:
      // The user's fixed or scripted boom when it is the mode in force; else the pose source's.
      if (arg_ && (mode_ == DisplayBoomMode::kScripted) == (arg_->mode == BoomMode::kScripted) &&
          arg_->mode != BoomMode::kTrackReceptacle) {
        scene.boom = arg_->command(t_s, BoomCommand{scene.boom, false}, rig_.boom.limits).articulation;
        if (arg_->mode == BoomMode::kScripted) {
          constexpr double h_s = 1e-3;
          const BoomCommand none{scene.boom, false};
          const BoomArticulation a0 = arg_->command(t_s - h_s, none, rig_.boom.limits).articulation,
                                 a1 = arg_->command(t_s + h_s, none, rig_.boom.limits).articulation;
          scene.boom_rate_per_s = {(a1.elevation_rad - a0.elevation_rad) / (2 * h_s),
                                   (a1.azimuth_rad - a0.azimuth_rad) / (2 * h_s),
                                   (a1.extension_m - a0.extension_m) / (2 * h_s)};
        }
      } else {
        scene.boom_rate_per_s = rate(scene.boom, t_s);  // the pose source's boom as it comes
      }
      break;
    case DisplayBoomMode::kInteractive:
      if (!interactive_) interactive_ = last_ ? *last_ : scene.boom;
      scene.boom = *interactive_;
      break;
  }
  last_ = scene.boom;
  last_t_s_ = t_s;
  last_mode_ = mode_;
}

void BoomStage::nudge(const BoomNudge& n) {
  if (!n.any()) return;
  if (mode_ != DisplayBoomMode::kInteractive) interactive_.reset();  // taken over: from where it is
  mode_ = DisplayBoomMode::kInteractive;
  BoomArticulation b = interactive_ ? *interactive_ : last_ ? *last_ : BoomArticulation{};
  b.elevation_rad += n.elevation_rad;
  b.azimuth_rad += n.azimuth_rad;
  b.extension_m += n.extension_m;
  interactive_ = clamp_to_limits(b, rig_.boom.limits).articulation;
}

std::string BoomStage::describe() const {
  switch (mode_) {
    case DisplayBoomMode::kTrackReceptacle:
      return "tracking the receptacle";
    case DisplayBoomMode::kScripted:
      return "scripted";
    case DisplayBoomMode::kFixed:
      return arg_ && arg_->mode == BoomMode::kFixed ? "fixed" : "as the poses give it";
    case DisplayBoomMode::kInteractive:
      return "interactive";
  }
  return "?";
}

}  // namespace augrig::pipeline
