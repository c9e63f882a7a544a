// The scripted approach (sim/approach.hpp, docs/SIMULATION.md): truth as a pure function of time,
// images rendered lazily by SyntheticSceneRenderer, left then right per stereo frame.
#include "sim/approach.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <ctime>

#include "core/clock.hpp"
#include "render/models.hpp"

namespace augrig {

namespace {

double smoothstep(double a, double b, double x) {
  const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Receptacle relative to the nozzle tip, tanker body frame (FRD), at keyframes of normalised time.
// Consecutive keyframes are joined by smoothsteps: zero velocity at every keyframe, so the path is
// C1 and arrives at the tip without overshoot.
struct Key {
  double s;
  Eigen::Vector3d offset_m;
};
// Contact is reached a little before the end and held, so the last frame of a clip sampled at
// t < duration is in contact too.
constexpr double kContactS = 0.97;
const std::array<Key, 6> kPath = {{
    {0.00, {-30.0, 2.0, 12.0}},  // observation: aft, right of and below the tip
    {0.10, {-30.0, 2.0, 12.0}},
    {0.45, {-15.0, 0.0, 4.0}},  // pre-contact
    {0.55, {-15.0, 0.0, 4.0}},
    {kContactS, {0.0, 0.0, 0.0}},  // contact: the receptacle at the nozzle tip
    {1.00, {0.0, 0.0, 0.0}},
}};

Eigen::Vector3d path_offset(double s) {
  for (std::size_t i = 1; i < kPath.size(); ++i) {
    if (s <= kPath[i].s) {
      const double w = smoothstep(kPath[i - 1].s, kPath[i].s, s);
      return (1.0 - w) * kPath[i - 1].offset_m + w * kPath[i].offset_m;
    }
  }
  return kPath.back().offset_m;
}

constexpr double kHeadingRad = 90.0 * (kPi / 180.0);
constexpr double kAltitudeM = 6000.0;
constexpr double kElevationRad = 0.5236;
constexpr double kExtensionStartM = 1.0, kExtensionContactM = 3.5;
// Where the tanker starts over the (procedural) ground; arbitrary, away from noise lattice origin.
const Eigen::Vector2d kStartNorthEast(1234.0, -5678.0);

TimestampNs frame_time_ns(std::uint64_t sequence, double fps) {
  return static_cast<TimestampNs>(std::llround(static_cast<double>(sequence) / fps * 1e9));
}

}  // namespace

ApproachTruth approach_truth(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
                             double t_s, double duration_s, double ground_speed_mps) {
  ApproachTruth truth;
  const double t = std::clamp(t_s, 0.0, std::max(duration_s, 0.0));
  const double s = duration_s > 0 ? t / duration_s : 1.0;
  truth.t_ns = s_to_ns(t);

  // Tanker: straight and level, moving over the ground along its heading.
  truth.sky.R_ned_body = rotation_from_ypr(kHeadingRad, 0.0, 0.0);
  truth.sky.altitude_m = kAltitudeM;
  truth.sky.north_east_m =
      kStartNorthEast + ground_speed_mps * t * Eigen::Vector2d(std::cos(kHeadingRad), std::sin(kHeadingRad));

  // Boom: held at elevation and azimuth; the operator extends it for contact in the last quarter.
  BoomArticulation& art = truth.scene.boom;
  art.elevation_rad = kElevationRad;
  art.azimuth_rad = 0.0;
  art.extension_m =
      kExtensionStartM + (kExtensionContactM - kExtensionStartM) * smoothstep(0.75, kContactS, s);
  const Eigen::Vector3d tip_body =
      boom_pose(rig.boom.pivot_body_m, art) * Eigen::Vector3d(boom.nozzle_tip_m(art.extension_m), 0, 0);

  // Receiver: receptacle on its path relative to the tip, a gentle pitch/roll wobble around it.
  const Eigen::Vector3d receptacle_body = tip_body + path_offset(s);
  const double pitch = deg_to_rad(1.0) * std::sin(2.0 * kPi * 0.37 * t + 0.3);
  const double roll = deg_to_rad(1.0) * std::sin(2.0 * kPi * 0.53 * t + 1.1);
  const Eigen::Matrix3d R_body_receiver = rotation_from_ypr(0.0, pitch, roll);
  truth.scene.T_body_receiver = Pose::from(R_body_receiver, receptacle_body - R_body_receiver * receptacle_m);
  truth.scene.receiver_present = true;
  return truth;
}

ApproachSource::~ApproachSource() = default;

Expected<std::unique_ptr<ApproachSource>> ApproachSource::create(const Rig& rig,
                                                                 const ApproachOptions& options) {
  if (rig.cameras.size() != 2)
    return make_error("ApproachSource::create(): the rig needs 2 cameras, has ", rig.cameras.size());
  if (options.frames <= 0)
    return make_error("ApproachSource::create(): frames must be > 0, got ", options.frames);
  if (!(options.fps > 0)) return make_error("ApproachSource::create(): fps must be > 0");
  std::unique_ptr<ApproachSource> src(new ApproachSource());
  src->rig_ = rig;
  src->options_ = options;
  if (rig.receiver.model.path.empty()) {
    make_builtin_receiver(&src->receptacle_m_);  // the model the renderer draws
  } else {
    src->receptacle_m_ = rig.receiver.receptacle_m;
  }
  auto renderer = SyntheticSceneRenderer::create(rig);
  if (!renderer) return make_error("ApproachSource::create(): ", renderer.error().message);
  src->renderer_ = std::move(*renderer);

  // The clip spans the approach: the first frame at its start, the last at contact.
  const double duration_s = options.frames > 1 ? (options.frames - 1) / options.fps : 0.0;
  src->truths_.resize(static_cast<std::size_t>(options.frames));
  for (std::size_t i = 0; i < src->truths_.size(); ++i) {
    const TimestampNs t_ns = frame_time_ns(i, options.fps);
    src->truths_[i] = approach_truth(rig, options.boom, src->receptacle_m_, ns_to_s(t_ns), duration_s,
                                     options.ground_speed_mps);
    src->truths_[i].t_ns = t_ns;
  }
  return src;
}

Expected<ReadStatus> ApproachSource::read(Frame& out, std::chrono::nanoseconds /*timeout*/) {
  const std::uint64_t sequence = next_ / 2;
  const int camera = static_cast<int>(next_ % 2);
  if (sequence >= truths_.size()) return ReadStatus::kEndOfStream;
  const ApproachTruth& truth = truths_[sequence];
  // Each frame its own noise, reproducibly.
  SensorOptions sensor = options_.sensor;
  sensor.noise_seed = options_.sensor.noise_seed * 0x9e3779b97f4a7c15ull + next_;
  if (auto s = renderer_->render(camera, truth.sky, truth.scene.T_body_receiver, truth.scene.receiver_present,
                                 sensor, out.image);
      !s)
    return make_error("ApproachSource::read(): frame ", sequence, " ", to_string(CameraId(camera)), ": ",
                      s.error().message);
  out.t_ns = truth.t_ns + (camera == 1 ? static_cast<TimestampNs>(std::llround(options_.skew_ns)) : 0);
  out.clock = ClockDomain::kSim;
  out.t_host_ns = monotonic_now_ns();
  out.sequence = sequence;
  out.camera = static_cast<CameraId>(camera);
  out.exposure_ns = 0;
  ++next_;
  return ReadStatus::kFrame;
}

}  // namespace augrig
