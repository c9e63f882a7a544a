// Sensor models of a simulated flight (docs/SIMULATION.md, "Sensor models"): a strapdown IMU whose
// noise-free increments are exact to the truth, a GPS receiver (RTK fixed/float, an error common to
// both aircraft, latency, outages, velocity and dual-antenna heading) and the cameras' timestamps.
// All of it is deterministic for a seed: the engines are std::mt19937_64 (defined by the standard)
// and the normal deviates come from our own Box-Muller, not std::normal_distribution.
//
// Time: sensor samples carry t_ns = start_gps_ns + round(t_s * 1e9), ClockDomain::kGps, where t_s is
// the scenario time. The simulated host clock is GPS time: arrival_ns = t_ns + latency.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/image.hpp"
#include "nav/types.hpp"
#include "sim/flight.hpp"

namespace augrig::sim {

struct Scenario;

// ---- Random numbers ---------------------------------------------------------------------------

// A seed for the named stream of a scenario seed (splitmix64 of the seed and an FNV-1a hash of the
// name), so every sensor and axis draws from its own, reproducible engine.
std::uint64_t derive_seed(std::uint64_t seed, std::string_view stream);

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}
  // Uniform in the open interval (0, 1), 53 random bits.
  double uniform() { return (static_cast<double>(engine_() >> 11) + 0.5) * 0x1.0p-53; }
  // Standard normal deviate (Box-Muller; the second deviate of each pair is kept for the next call).
  double normal();
  Eigen::Vector3d normal3() {
    const double x = normal(), y = normal(), z = normal();
    return {x, y, z};
  }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0;
};

// The truth a sensor samples: a body's kinematic state at scenario time t_s.
using TruthFunction = std::function<KinematicState(double t_s)>;

// ---- IMU --------------------------------------------------------------------------------------

// Gyro errors, SI, per axis (independent). All zero: noise-free.
struct GyroErrors {
  double arw_rad_per_sqrt_s = 0;                 // angle random walk (white rate noise density)
  double bias_instability_radps = 0;             // 1-sigma of the first-order Gauss-Markov bias
  double bias_tau_s = 300;                       // its correlation time
  double rate_random_walk_radps_per_sqrt_s = 0;  // random-walk bias
  double turn_on_bias_radps = 0;                 // 1-sigma of the constant bias drawn at start
  bool operator==(const GyroErrors&) const = default;
};

// Accelerometer errors, SI, per axis (independent). All zero: noise-free.
struct AccelErrors {
  double vrw_mps_per_sqrt_s = 0;  // velocity random walk (white specific-force noise density)
  double bias_instability_mps2 = 0;
  double bias_tau_s = 300;
  double random_walk_mps2_per_sqrt_s = 0;  // acceleration (bias) random walk
  double turn_on_bias_mps2 = 0;
  bool operator==(const AccelErrors&) const = default;
};

struct ImuErrorModel {
  GyroErrors gyro;
  AccelErrors accel;
  bool operator==(const ImuErrorModel&) const = default;
};

// "noise_free", "navigation" (a tanker's EGI: gyro 0.003 deg/h, accel 25 ug), "tactical" (gyro: ARW 0.1
// deg/sqrt(h), bias instability 1 deg/h; accel: VRW 0.05 m/s/sqrt(h), bias instability 0.5 mg) or "consumer"
// (MEMS). docs/SIMULATION.md lists them.
Expected<ImuErrorModel> imu_preset(std::string_view name);

struct ImuConfig {
  double rate_hz = 200.0;  // 100 to 400 Hz
  double latency_s = 0.0;  // arrival_ns = true GPS time + latency (the host clock is GPS time)
  // The IMU's own clock against GPS time: a sample's stamp is its true GPS time + clock_offset_ns +
  // clock_drift_ppm 1e-6 x the time since the scenario start. 0: stamped on GPS time.
  std::int64_t clock_offset_ns = 0;
  double clock_drift_ppm = 0;
  ImuErrorModel errors = *imu_preset("tactical");
  bool operator==(const ImuConfig&) const = default;
};

struct ImuIncrement {
  Eigen::Vector3d dtheta_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d dv_mps = Eigen::Vector3d::Zero();
};

// Exact noise-free increments over (t0, t1] of a body whose IMU sits at its origin along its axes:
//   dtheta = rotation vector of C_b(t0)_b(t1) = C_b_e(t0) * Rz(w_ie (t1 - t0)) * C_e_b(t1), the body's
//            rotation w.r.t. inertial space over the interval (Earth rotation included);
//   dv     = integral of f_b = C_b_e (a_e + 2 w_ie x v_e - g_e(p)) over the interval, 5-point
//            Gauss-Legendre on the truth (g_e: normal gravity incl. centrifugal, nav/geodesy.hpp).
ImuIncrement exact_imu_increment(const TruthFunction& truth, double t0_s, double t1_s);
ImuIncrement exact_imu_increment(const TruthFunction& truth, const KinematicState& s0,
                                 const KinematicState& s1);
// Specific force in body axes at one state: C_b_e (a_e + 2 w_ie x v_e - g_e(p)).
Eigen::Vector3d specific_force_body(const KinematicState& s);
// Body rate w.r.t. inertial space in body axes: w_eb + C_b_e w_ie.
Eigen::Vector3d inertial_rate_body(const KinematicState& s);

// One aircraft's IMU. Sample k (k = 1, 2, ...) covers (t_{k-1}, t_k], t_k = k * period, with the
// period rounded to whole ns; it is stamped t_k + clock_offset_ns + round(clock_drift_ppm 1e-6 t_k)
// (dt_s stays the nominal period). Each sample adds to the exact increments
//   dtheta += b_g dt + ARW sqrt(dt) n,   dv += b_a dt + VRW sqrt(dt) n   (n ~ N(0, I) per sample),
// where each bias = turn-on constant + Gauss-Markov (exact discretisation) + random walk, updated
// once per sample before use.
class ImuSimulator {
 public:
  ImuSimulator(const ImuConfig& config, std::uint64_t seed, TimestampNs start_gps_ns);
  nav::ImuSample next(const TruthFunction& truth);
  // All further samples with t_k <= t_end_s.
  std::vector<nav::ImuSample> generate(const TruthFunction& truth, double t_end_s);
  double period_s() const { return static_cast<double>(period_ns_) / 1e9; }
  // The biases used by the last sample.
  const Eigen::Vector3d& gyro_bias_radps() const { return gyro_bias_; }
  const Eigen::Vector3d& accel_bias_mps2() const { return accel_bias_; }

 private:
  ImuConfig config_;
  TimestampNs start_ns_ = 0, period_ns_ = 0;
  std::int64_t k_ = 0;  // samples emitted
  Rng rng_;
  Eigen::Vector3d gyro_turn_on_, accel_turn_on_;
  Eigen::Vector3d gyro_gm_, accel_gm_, gyro_rw_, accel_rw_;
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero(), accel_bias_ = Eigen::Vector3d::Zero();
  std::optional<KinematicState> last_;  // truth at t_{k}
};

// ---- GPS --------------------------------------------------------------------------------------

// A smooth synthetic geoid (undulation N, metres, between about -60 and +70): heights above MSL are
// h_ellipsoidal - N. NMEA writers output MSL and this separation.
double synthetic_geoid_separation_m(double lat_rad, double lon_rad);

// The slow GPS error common to both aircraft (satellite orbit/clock, atmosphere, base station):
// a second-order Gauss-Markov process per NED axis (a first-order one smoothed by a lag of the same
// time constant), stationary from t = 0, with 1-sigma `sigma_*` and velocity of order sigma / tau.
struct CommonGpsErrorConfig {
  double sigma_horizontal_m = 0.3;  // per horizontal axis
  double sigma_vertical_m = 0.6;
  double tau_s = 600.0;
  bool operator==(const CommonGpsErrorConfig&) const = default;
};

// One realisation of the common error, shared (std::shared_ptr) by the GPS simulators of both
// aircraft, so both see identical values at equal times whatever order they ask in. It is the
// process on a grid (step tau/50, clamped to [0.05, 1] s), linearly interpolated, grown
// on demand (not thread-safe).
class CommonGpsError {
 public:
  CommonGpsError(const CommonGpsErrorConfig& config, std::uint64_t seed);
  // Error (north, east, down), metres, at scenario time t_s (clamped to >= 0).
  Eigen::Vector3d ned_m(double t_s);

 private:
  CommonGpsErrorConfig config_;
  Rng rng_;
  double step_s_ = 1.0;
  std::vector<Eigen::Vector3d> grid_;                // the smoothed process / sqrt(2), on the grid
  Eigen::Vector3d drive_ = Eigen::Vector3d::Zero();  // the first-order process driving it
};

enum class GpsMode { kSingle, kRtk };

struct GpsOutage {
  double t0_s = 0, t1_s = 0;  // no fixes for epochs with t0 <= t <= t1
  bool operator==(const GpsOutage&) const = default;
};

struct GpsConfig {
  double rate_hz = 10.0;                                          // 1 to 20 Hz
  Eigen::Vector3d lever_arm_m = Eigen::Vector3d(0.0, 0.0, -1.5);  // antenna, body FRD
  double latency_s = 0.05;                                        // arrival_ns = t_ns + latency
  GpsMode mode = GpsMode::kRtk;
  double sigma_horizontal_m = 0.01;  // white noise per horizontal axis: RTK fixed (kSingle: single)
  double sigma_vertical_m = 0.02;
  double float_sigma_horizontal_m = 0.25;  // RTK float
  double float_sigma_vertical_m = 0.5;
  double fixed_to_float_per_s = 0.002;  // Markov chain rates (per-epoch probability 1 - exp(-rate dt))
  double float_to_fixed_per_s = 0.1;
  bool start_fixed = true;
  std::vector<GpsOutage> outages;    // scenario times; after an outage an RTK receiver is in float
  double velocity_sigma_mps = 0.02;  // per horizontal axis, on the ground velocity
  bool heading = false;              // dual-antenna heading (HDT) of the body x axis
  double heading_sigma_rad = deg_to_rad(0.1);
  int satellites = 16;
  double hdop = 0.7;
  // This receiver's own slowly wandering error (the common error's process, own realisation): the
  // part of single-point errors two receivers do not share (satellites tracked, multipath, the
  // receiver); its sigma is in the reported accuracy. Zero by default.
  CommonGpsErrorConfig own_error{0.0, 0.0, 600.0};
  bool operator==(const GpsConfig&) const = default;
};

// One aircraft's GPS receiver. Epoch k (k = 0, 1, ...) at t_k = k * period (rounded to ns). The fix is
// at the antenna p + C_e_b lever_arm, plus common(t_k) + the white noise of the current state, in
// the local NED; ground speed/course from the antenna's true velocity plus noise; heading of the
// body x axis plus noise. sigma_ned_m reports the white-noise sigmas of the current state (what the
// receiver's own estimator knows; the common error is invisible to it).
class GpsSimulator {
 public:
  // `common` may be null (no common error).
  GpsSimulator(const GpsConfig& config, std::uint64_t seed, TimestampNs start_gps_ns,
               std::shared_ptr<CommonGpsError> common);
  // The next epoch's fix, or nullopt inside an outage (the epoch passes all the same).
  std::optional<nav::GpsFix> next(const TruthFunction& truth);
  // All further fixes with t_k <= t_end_s.
  std::vector<nav::GpsFix> generate(const TruthFunction& truth, double t_end_s);
  double next_epoch_s() const { return static_cast<double>(k_ * period_ns_) / 1e9; }
  bool rtk_fixed() const { return fixed_; }

 private:
  GpsConfig config_;
  TimestampNs start_ns_ = 0, period_ns_ = 0;
  std::int64_t k_ = 0;
  Rng rng_;
  std::shared_ptr<CommonGpsError> common_;
  std::optional<CommonGpsError> own_;  // config.own_error, when it has a sigma
  bool fixed_ = true;
  bool in_outage_ = false;
};

// ---- Cameras ----------------------------------------------------------------------------------

struct CameraTimingConfig {
  double fps = 30.0;
  // Per camera (index as in the rig; missing entries 0): the camera clock's offset from GPS time and
  // its drift, and the shift of the true mid-exposure from the nominal frame time.
  std::vector<std::int64_t> clock_offset_ns;
  std::vector<double> clock_drift_ppm;
  std::vector<std::int64_t> exposure_offset_ns;
  // What the rig's calibration says the offsets are (the poses from the live nav map frames with
  // them until `run --camera-clock online` applies its own estimate); empty: the true offsets above
  // (a calibrated rig). assumed_clock_offsets_ns() gives the values in use.
  std::vector<std::int64_t> clock_offset_assumed_ns;
  double jitter_ns = 0.0;         // 1-sigma Gaussian timestamp jitter
  double drop_probability = 0.0;  // per frame, independent
  // For the image renderer (not used by the timing model).
  PixelFormat format = PixelFormat::kRGB8;  // RGB or a Bayer mosaic
  double noise_sigma = 0.0;                 // additive Gaussian (read) noise, digital numbers
  // The camera's response to the whole image (sim/camera_sensor.hpp): Gaussian PSF (pixels), shot
  // noise (variance per DN of signal), exposure x gain, tone curve. Defaults: none.
  double psf_sigma_px = 0.0;
  double noise_a = 0.0;
  double gain = 1.0;
  double gamma = 1.0;
  // The exposure time (0: an instant). A boom physically in the scene (FlightSource's physical
  // boom) is integrated over it (motion blur); the frames carry it (Frame::exposure_ns).
  double exposure_ms = 0.0;
  bool operator==(const CameraTimingConfig&) const = default;

  // The calibrated offsets, one per camera (`cameras` of them, missing ones 0).
  std::vector<std::int64_t> assumed_clock_offsets_ns(std::size_t cameras) const {
    std::vector<std::int64_t> v = clock_offset_assumed_ns.empty() ? clock_offset_ns : clock_offset_assumed_ns;
    v.resize(cameras, 0);
    return v;
  }
};

struct CameraFrameTime {
  std::uint64_t sequence = 0;
  double t_true_s = 0;          // true mid-exposure, scenario time
  TimestampNs t_camera_ns = 0;  // the camera's timestamp (its own clock, ClockDomain::kDevice)
  bool dropped = false;
};

// Frames with nominal time sequence / fps in [0, duration_s]; per camera c:
//   t_true_s    = sequence / fps + exposure_offset_ns[c] 1e-9
//   t_camera_ns = start_gps_ns + round(t_true_s 1e9) + clock_offset_ns[c]
//                 + round(clock_drift_ppm[c] 1e-6 t_true_s 1e9) + round(jitter_ns n)
std::vector<std::vector<CameraFrameTime>> simulate_camera_timing(const CameraTimingConfig& config,
                                                                 int cameras, double duration_s,
                                                                 std::uint64_t seed,
                                                                 TimestampNs start_gps_ns);

// ---- A whole scenario -------------------------------------------------------------------------

struct SensorLogs {
  std::vector<nav::ImuSample> tanker_imu, receiver_imu;
  std::vector<nav::GpsFix> tanker_gps, receiver_gps;
  std::vector<std::vector<CameraFrameTime>> cameras;  // one list per rig camera
};

// Every sensor of a scenario over [0, duration], seeded from scenario.seed (streams "tanker/imu",
// "receiver/imu", "tanker/gps", "receiver/gps", "common_gps", "cameras").
SensorLogs simulate_sensors(const Scenario& scenario, const Flight& flight);

}  // namespace augrig::sim
