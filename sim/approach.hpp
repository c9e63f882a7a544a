// A short scripted refuelling approach as a FrameSource (sim://approach): the receiver flies from
// an observation position behind and below the tanker, through pre-contact, to contact with the
// boom's nozzle, while the boom operator holds the boom; straight and level tanker. Each stereo
// frame has its truth (receiver pose, boom articulation), the stand-in for nav until nav/ lands.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/frame.hpp"
#include "render/augmenter.hpp"
#include "sim/synthetic_scene.hpp"

namespace augrig {

struct ApproachOptions {
  int frames = 90;  // stereo frames
  double fps = 30.0;
  SensorOptions sensor;
  double skew_ns = 0;               // right camera's mid-exposure offset from the left
  BoomDimensions boom;              // the boom whose nozzle the receiver flies to (the built-in one)
  double ground_speed_mps = 150.0;  // moves the ground texture under the tanker
};

struct ApproachTruth {
  TimestampNs t_ns = 0;  // mid-exposure of the left frame, ClockDomain::kSim
  SceneState scene;      // boom articulation and T_body_receiver
  SkyState sky;
};

// Truth of the scripted approach at time t (seconds since its start), for a rig and boom:
// tanker straight and level at 6000 m heading 090; boom at 30 deg elevation, azimuth 0, extension
// 1 m, extending smoothly to 3.5 m from 75 % to 97 % of the duration; the receptacle
// (`receptacle_m`, receiver body frame) flies a C1 path relative to the nozzle tip from observation
// (30 m aft, 2 m right, 12 m below) through pre-contact (15 m aft, 4 m below) to contact (exactly at
// the tip from 97 % of the duration on), with a smooth +-1 deg pitch/roll wobble. t is clamped to
// [0, duration]. ApproachSource samples it with duration = (frames - 1) / fps: its last frame is
// at contact.
// docs/SIMULATION.md describes it.
ApproachTruth approach_truth(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
                             double t_s, double duration_s, double ground_speed_mps = 150.0);

class ApproachSource final : public FrameSource {
 public:
  // Needs a current GL context. Renders lazily, in read(). The receptacle is the built-in
  // receiver's unless the rig names a receiver model file (then rig.receiver.receptacle_m).
  static Expected<std::unique_ptr<ApproachSource>> create(const Rig& rig, const ApproachOptions& options);
  ~ApproachSource() override;
  std::string uri() const override { return "sim://approach"; }
  // Left frame then right frame of each stereo frame, sequence = stereo index; t_ns =
  // round(sequence / fps * 1e9) (+ skew_ns for the right), ClockDomain::kSim; then kEndOfStream.
  // The timeout is ignored (rendering is synchronous).
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  // Truth of stereo frame `sequence` (valid for every sequence < options.frames).
  const ApproachTruth& truth(std::uint64_t sequence) const { return truths_.at(sequence); }
  std::size_t frame_count() const { return truths_.size(); }
  const Eigen::Vector3d& receptacle_m() const { return receptacle_m_; }

 private:
  ApproachSource() = default;
  Rig rig_;
  ApproachOptions options_;
  std::vector<ApproachTruth> truths_;
  std::unique_ptr<SyntheticSceneRenderer> renderer_;
  Eigen::Vector3d receptacle_m_ = Eigen::Vector3d::Zero();
  std::uint64_t next_ = 0;  // next frame to emit: 2*sequence + camera
};

}  // namespace augrig
