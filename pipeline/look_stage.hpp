// LookStage: what the camera look (render/camera_look.hpp) needs per frame, kept off the
// per-frame path where it costs time:
//   - the sun: where the pose source gave none (no time or position), the documented default
//     sun, said once;
//   - the light's three terms (direct sun, sky, ground; per colour channel) measured on the
//     receiver, whose shape and colours are known (render/light_probe.hpp), from the frames and
//     masks of each sampled pair, used from the next pair on; until the receiver has been measured
//     (or where it cannot be: out of view, too few ways its surfaces face), the ground's light is
//     the frames' mean linear level and the sun and sky SceneLight::sun()'s clear sky. A scene
//     file's `sun` key sets all three instead;
//   - each camera's noise level function: configured (rig), or estimated online from its raw
//     frames (render/noise_level.hpp) on a thread of its own (idle priority), one frame per camera every
//     `noise_every_s` of frame time, refitted after each, restarted every `noise_window` frames so
//     that a change of gain is followed; each new fit reaches the augmenter between two frames.
// With the plain look it does nothing.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/frame.hpp"
#include "render/augmenter.hpp"
#include "render/light_probe.hpp"
#include "render/noise_level.hpp"

namespace augrig::pipeline {

struct LookConfig {
  Look look = Look::kPlain;
  // Per rig camera: the look's parameters; a camera whose `noise` is empty has it estimated.
  std::vector<CameraLookParams> cameras;
  double noise_every_s = 0.5;  // frame time between frames given to the estimator
  int noise_window = 20;       // frames per estimate before it starts afresh (keeping its last fit)
  // Estimate on the calling thread, at the frames' times: the same input gives the same pixels
  // (files, recordings, simulations). Live runs estimate on a thread of their own.
  bool synchronous = true;
};

// One camera's noise as the run knows it, for status lines, the recording and the report.
struct CameraNoiseState {
  NoiseLevelFunction nlf;     // empty: none yet
  bool configured = false;    // from the rig, not estimated
  std::uint64_t fits = 0;     // estimates made so far
  std::uint64_t frames = 0;   // frames the last estimate used
  std::string note;           // the estimator's last word (a fallback, too little to go on)
  bool failure_said = false;  // a note said that no estimate could be made yet
};

// The sun on the boom for a tanker at `p_ecef_m` with attitude `R_ecef_body` at GPS time
// `t_gps_ns` (nav/solar_position.hpp): direct light while the sun is above the horizon as seen
// from the tanker's height (the horizon dips below the local level at altitude).
SceneLight sun_light(TimestampNs t_gps_ns, const Pose& T_ecef_tanker);

class LookStage {
 public:
  explicit LookStage(LookConfig config);
  ~LookStage();
  LookStage(const LookStage&) = delete;
  LookStage& operator=(const LookStage&) = delete;

  // Gives the augmenter every camera's configured look (once, before the first frame) and takes
  // its receiver model for the light probe.
  Status configure(Augmenter& augmenter);
  // Per pair, before it is augmented: the default sun where the scene has none, new noise
  // estimates to the augmenter, and (now and then) the pair's raw frames to the estimator.
  // Returns a note to print once (the default sun, a camera's first noise estimate), or empty.
  std::vector<std::string> before_augment(const StereoFrame& frame, SceneState& scene, Augmenter& augmenter);
  // Per pair, after it is augmented: on the pairs sampled by before_augment(), the light measured
  // on the receiver (its visible points in both views).
  void after_augment(const StereoFrame& frame, const SceneState& scene, const StereoResult& result,
                     const Rig& rig);
  // Waits for the estimator's frame in progress (tests; the end of a run).
  void flush();
  // The light last measured on the receiver, if any.
  const std::optional<LightFit>& receiver_light() const { return probe_fit_; }

  Look look() const { return config_.look; }
  std::vector<CameraNoiseState> noise() const;
  // "look camera: sun ephemeris; noise left a 0.21 b 1.9 (4 fits), right ..." for status lines.
  std::string status() const;

 private:
  void estimator_loop();
  // Adds each camera's frame to its estimator and fits (the estimator's thread, or the caller's).
  void estimate(const std::vector<const Image*>& frames);
  // With `mutex_` held: hands newly fitted NLFs to the augmenter; the notes of first estimates.
  void hand_over(Augmenter& augmenter, std::vector<std::string>& notes);
  // "look: exposure left 4 ms (the rig's look.exposure_ms); right unknown: ...", said once.
  std::string exposure_note(const StereoFrame& frame) const;

  LookConfig config_;
  bool estimating_ = false;  // some camera's noise is estimated
  bool default_sun_said_ = false;
  bool exposure_said_ = false;
  LightSource last_light_ = LightSource::kFixed;
  TimestampNs next_sample_ns_ = 0;
  bool sampled_ = false;
  std::optional<Eigen::Vector3d> ground_;  // the ground's light from the frames (SceneLight::ground), R G B
  bool probe_due_ = false;                 // before_augment() sampled this pair
  std::optional<LightProbe> probe_;        // the camera look with a receiver model
  std::optional<LightFit> probe_fit_;
  std::string probe_note_;  // why the last pair could not be measured

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Image> pending_;  // frames waiting for the estimator (one per camera), empty: none
  bool busy_ = false, stop_ = false;
  std::vector<CameraNoiseState> noise_;
  std::vector<bool> fresh_;  // a fit the augmenter has not been given yet
  std::vector<NoiseLevelEstimator> estimators_;
  std::thread thread_;
};

}  // namespace augrig::pipeline
