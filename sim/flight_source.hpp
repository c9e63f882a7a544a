// FlightSource: a simulated flight's cameras as a FrameSource (sim://<scenario>). Each delivered
// frame (the camera-timing model's drops are skipped, as a real camera's would be) is rendered by
// SyntheticSceneRenderer from the truth at its true mid-exposure time: sky, horizon and ground from
// the tanker's attitude and height, and the textured receiver at its true relative pose. Frames come
// out in timestamp order, both cameras interleaved, stamped with the camera's own clock
// (ClockDomain::kDevice). The truth of every frame stays available for checks.
#pragma once

#include <memory>
#include <vector>

#include "core/frame.hpp"
#include "nav/logs.hpp"
#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/synthetic_scene.hpp"

namespace augrig::sim {

// Truth of one delivered camera frame.
struct FrameTruth {
  std::uint64_t sequence = 0;
  int camera = 0;
  TimestampNs t_camera_ns = 0;  // the camera's stamp (its clock)
  double t_true_s = 0;          // true mid-exposure, scenario time
  TimestampNs t_gps_ns = 0;     // the same instant in GPS time
  Pose T_body_receiver;         // receiver body in the tanker body frame at t_true_s
  Pose T_cam_receiver;          // ... in this camera
  BoomArticulation boom;        // the scenario's boom at t_true_s
  std::string phase;
};

// A frame's truth as a camera pose CSV row (nav/logs.hpp): T_cam_receiver, t_nav_ns = its GPS time,
// sigmas 0, the scenario's boom.
nav::CameraPoseRow pose_row(const FrameTruth& t);

// The truth of every frame the cameras deliver, in delivery order (by camera timestamp).
std::vector<FrameTruth> frame_truths(const Scenario& scenario, const Flight& flight,
                                     const std::vector<std::vector<CameraFrameTime>>& cameras);

// How fast the flight's boom moves at t_s (rad/s, m/s): a central difference of Flight::boom().
BoomArticulation boom_rate(const Flight& flight, double t_s);

// The sky state (tanker attitude, height, ground position) the renderer needs at t_s.
SkyState sky_at(const Scenario& scenario, const Flight& flight, double t_s);

class FlightSource final : public FrameSource {
 public:
  // Renders with the CPU back end (SceneBackend::kCpu, no GL context needed) unless `backend`
  // says otherwise (kOpenGL needs a current GL context). `frames` from frame_truths(); only those with
  // `every`-th sequence numbers (sequence % every == 0) are rendered and delivered.
  static Expected<std::unique_ptr<FlightSource>> create(const Scenario& scenario, const Flight& flight,
                                                        std::vector<FrameTruth> frames, int every = 1,
                                                        SceneBackend backend = SceneBackend::kCpu);
  std::string uri() const override { return "sim://" + scenario_.name; }
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  SourceCapabilities capabilities() const override { return {.finite = true}; }
  std::size_t pair_count() const override { return frames_.size() / 2; }
  std::size_t image_count() const override { return frames_.size(); }
  // The truth of the frame read() will render next (nullptr at the end), and skipping it unrendered:
  // a real-time source that has fallen behind loses frames as a camera would.
  const FrameTruth* peek() const { return next_ < frames_.size() ? &frames_[next_] : nullptr; }
  void skip() {
    if (next_ < frames_.size()) ++next_;
  }
  // Truth of the frame read() returned last.
  const FrameTruth& last_truth() const { return frames_.at(next_ - 1); }
  std::size_t frame_count() const { return frames_.size(); }
  // Renders the boom physically in the scene (SyntheticSceneRenderer::render_with_boom) at each
  // frame's true articulation: the frames a flight with a real boom would have given.
  void set_physical_boom(bool on) { physical_boom_ = on; }
  bool physical_boom() const { return physical_boom_; }

 private:
  FlightSource() = default;
  Scenario scenario_;
  const Flight* flight_ = nullptr;
  std::vector<FrameTruth> frames_;
  std::unique_ptr<SyntheticSceneRenderer> renderer_;
  SensorOptions sensor_;
  bool physical_boom_ = false;
  std::size_t next_ = 0;
};

}  // namespace augrig::sim
