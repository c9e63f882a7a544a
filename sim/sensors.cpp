// Sensor models (sim/sensors.hpp, docs/SIMULATION.md "Sensor models").
#include "sim/sensors.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include "nav/geodesy.hpp"
#include "sim/scenario.hpp"

namespace augrig::sim {

namespace {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

TimestampNs period_ns_for(double rate_hz) {
  return std::max<TimestampNs>(1, static_cast<TimestampNs>(std::llround(1e9 / rate_hz)));
}

TimestampNs latency_ns(double latency_s) {
  return static_cast<TimestampNs>(std::llround(latency_s * 1e9));
}

double wrap_two_pi(double a) {
  a = std::fmod(a, 2.0 * kPi);
  return a < 0 ? a + 2.0 * kPi : a;
}

// Rotation vector of a unit quaternion (angle in [0, pi]).
Eigen::Vector3d rotation_vector(Eigen::Quaterniond q) {
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d v = q.vec();
  const double n = v.norm();
  if (n == 0) return Eigen::Vector3d::Zero();
  return v * (2.0 * std::atan2(n, q.w()) / n);
}

// One step of a first-order Gauss-Markov process with stationary sigma, exact discretisation.
Eigen::Vector3d gauss_markov_step(const Eigen::Vector3d& x, double sigma, double tau_s, double dt_s,
                                  const Eigen::Vector3d& n) {
  if (!(tau_s > 0)) return sigma * n;
  const double phi = std::exp(-dt_s / tau_s);
  return phi * x + sigma * std::sqrt(std::max(0.0, 1.0 - phi * phi)) * n;
}

// 5-point Gauss-Legendre on [-1, 1].
constexpr std::array<double, 5> kGlNodes = {-0.9061798459386639927976269, -0.5384693101056830910363144, 0.0,
                                            0.5384693101056830910363144, 0.9061798459386639927976269};
constexpr std::array<double, 5> kGlWeights = {0.2369268850561890875142640, 0.4786286704993664680412915,
                                              0.5688888888888888888888889, 0.4786286704993664680412915,
                                              0.2369268850561890875142640};

}  // namespace

// ---- Random numbers ---------------------------------------------------------------------------

std::uint64_t derive_seed(std::uint64_t seed, std::string_view stream) {
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a
  for (const char ch : stream) {
    h ^= static_cast<unsigned char>(ch);
    h *= 1099511628211ull;
  }
  return splitmix64(splitmix64(seed) ^ h);
}

double Rng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  const double u1 = uniform(), u2 = uniform();
  const double r = std::sqrt(-2.0 * std::log(u1));
  spare_ = r * std::sin(2.0 * kPi * u2);
  has_spare_ = true;
  return r * std::cos(2.0 * kPi * u2);
}

// ---- IMU --------------------------------------------------------------------------------------

Expected<ImuErrorModel> imu_preset(std::string_view name) {
  constexpr double kMg = 9.80665e-3;
  const auto deg_per_sqrt_h = [](double v) { return deg_to_rad(v) / 60.0; };
  const auto deg_per_h = [](double v) { return deg_to_rad(v) / 3600.0; };
  ImuErrorModel m;
  if (name == "noise_free") return m;
  if (name == "tactical") {
    m.gyro = {deg_per_sqrt_h(0.1), deg_per_h(1.0), 300.0, deg_per_h(1.0) / 60.0, deg_per_h(3.0)};
    m.accel = {0.05 / 60.0, 0.5 * kMg, 300.0, 0.05 * kMg / 60.0, 1.0 * kMg};
    return m;
  }
  if (name == "navigation") {
    // Navigation grade, as in a tanker's embedded GPS/INS (EGI): ring-laser gyros, servo accelerometers.
    m.gyro = {deg_per_sqrt_h(0.002), deg_per_h(0.003), 3600.0, deg_per_h(0.001) / 60.0, deg_per_h(0.005)};
    m.accel = {0.005 / 60.0, 0.025 * kMg, 3600.0, 0.001 * kMg / 60.0, 0.05 * kMg};
    return m;
  }
  if (name == "consumer") {
    m.gyro = {deg_per_sqrt_h(0.5), deg_per_h(10.0), 100.0, deg_per_h(20.0) / 60.0, deg_per_h(500.0)};
    m.accel = {0.1 / 60.0, 2.0 * kMg, 100.0, 1.0 * kMg / 60.0, 20.0 * kMg};
    return m;
  }
  return make_error("imu_preset(): unknown preset '", std::string(name),
                    "'; expected one of noise_free, navigation, tactical, consumer");
}

Eigen::Vector3d specific_force_body(const KinematicState& s) {
  const Eigen::Vector3d f_e =
      s.a_ecef_mps2 + 2.0 * nav::earth_rate_ecef().cross(s.v_ecef_mps) - nav::gravity_ecef(s.p_ecef_m);
  return s.q_ecef_body.conjugate() * f_e;
}

Eigen::Vector3d inertial_rate_body(const KinematicState& s) {
  return s.w_eb_body_radps + s.q_ecef_body.conjugate() * nav::earth_rate_ecef();
}

ImuIncrement exact_imu_increment(const TruthFunction& truth, const KinematicState& s0,
                                 const KinematicState& s1) {
  ImuIncrement inc;
  const double dt = s1.t_s - s0.t_s;
  // C_i_e(t) = Rz(w_ie t): the body's rotation w.r.t. inertial space over the interval is
  // C_b_e(t0) Rz(w_ie dt) C_e_b(t1).
  const Eigen::Quaterniond earth(Eigen::AngleAxisd(nav::kEarthRate_radps * dt, Eigen::Vector3d::UnitZ()));
  inc.dtheta_rad = rotation_vector(s0.q_ecef_body.conjugate() * earth * s1.q_ecef_body);
  const double mid = 0.5 * (s0.t_s + s1.t_s), half = 0.5 * dt;
  for (std::size_t i = 0; i < kGlNodes.size(); ++i) {
    inc.dv_mps += (kGlWeights[i] * half) * specific_force_body(truth(mid + half * kGlNodes[i]));
  }
  return inc;
}

ImuIncrement exact_imu_increment(const TruthFunction& truth, double t0_s, double t1_s) {
  return exact_imu_increment(truth, truth(t0_s), truth(t1_s));
}

ImuSimulator::ImuSimulator(const ImuConfig& config, std::uint64_t seed, TimestampNs start_gps_ns)
    : config_(config), start_ns_(start_gps_ns), period_ns_(period_ns_for(config.rate_hz)), rng_(seed) {
  const GyroErrors& g = config_.errors.gyro;
  const AccelErrors& a = config_.errors.accel;
  gyro_turn_on_ = g.turn_on_bias_radps * rng_.normal3();
  accel_turn_on_ = a.turn_on_bias_mps2 * rng_.normal3();
  gyro_gm_ = g.bias_instability_radps * rng_.normal3();  // stationary from the start
  accel_gm_ = a.bias_instability_mps2 * rng_.normal3();
  gyro_rw_.setZero();
  accel_rw_.setZero();
}

nav::ImuSample ImuSimulator::next(const TruthFunction& truth) {
  if (!last_) last_ = truth(0.0);
  ++k_;
  const TimestampNs t_ns = k_ * period_ns_;
  const KinematicState s1 = truth(static_cast<double>(t_ns) / 1e9);
  const ImuIncrement inc = exact_imu_increment(truth, *last_, s1);
  last_ = s1;

  const double dt = period_s(), sdt = std::sqrt(dt);
  const GyroErrors& g = config_.errors.gyro;
  const AccelErrors& a = config_.errors.accel;
  // The same draws in the same order whatever the sigmas, so one error term does not reshuffle the
  // others' realisations.
  gyro_gm_ = gauss_markov_step(gyro_gm_, g.bias_instability_radps, g.bias_tau_s, dt, rng_.normal3());
  accel_gm_ = gauss_markov_step(accel_gm_, a.bias_instability_mps2, a.bias_tau_s, dt, rng_.normal3());
  gyro_rw_ += g.rate_random_walk_radps_per_sqrt_s * sdt * rng_.normal3();
  accel_rw_ += a.random_walk_mps2_per_sqrt_s * sdt * rng_.normal3();
  gyro_bias_ = gyro_turn_on_ + gyro_gm_ + gyro_rw_;
  accel_bias_ = accel_turn_on_ + accel_gm_ + accel_rw_;
  const Eigen::Vector3d n_g = rng_.normal3(), n_a = rng_.normal3();

  nav::ImuSample s;
  // Stamped by the IMU's clock (offset and drift from GPS time); it arrives on the host's (GPS time).
  s.t_ns = start_ns_ + t_ns + config_.clock_offset_ns +
           std::llround(config_.clock_drift_ppm * 1e-6 * static_cast<double>(t_ns));
  s.dt_s = dt;
  s.dtheta_rad = inc.dtheta_rad + gyro_bias_ * dt + g.arw_rad_per_sqrt_s * sdt * n_g;
  s.dv_mps = inc.dv_mps + accel_bias_ * dt + a.vrw_mps_per_sqrt_s * sdt * n_a;
  s.arrival_ns = start_ns_ + t_ns + latency_ns(config_.latency_s);
  return s;
}

std::vector<nav::ImuSample> ImuSimulator::generate(const TruthFunction& truth, double t_end_s) {
  std::vector<nav::ImuSample> out;
  const TimestampNs end_ns = s_to_ns(t_end_s);
  while ((k_ + 1) * period_ns_ <= end_ns) out.push_back(next(truth));
  return out;
}

// ---- GPS --------------------------------------------------------------------------------------

double synthetic_geoid_separation_m(double lat_rad, double lon_rad) {
  return 35.0 * std::sin(2.0 * lat_rad) * std::cos(lon_rad) +
         20.0 * std::cos(3.0 * lat_rad) * std::sin(2.0 * lon_rad + 0.7) + 10.0 * std::sin(lat_rad) + 5.0;
}

CommonGpsError::CommonGpsError(const CommonGpsErrorConfig& config, std::uint64_t seed)
    : config_(config), rng_(seed), step_s_(std::clamp(config.tau_s / 50.0, 0.05, 1.0)) {}

Eigen::Vector3d CommonGpsError::ned_m(double t_s) {
  const Eigen::Vector3d sigma(config_.sigma_horizontal_m, config_.sigma_horizontal_m,
                              config_.sigma_vertical_m);
  const double x = std::max(t_s, 0.0) / step_s_;
  const std::size_t i = static_cast<std::size_t>(x);
  const double phi = config_.tau_s > 0 ? std::exp(-step_s_ / config_.tau_s) : 0.0;
  const double q = std::sqrt(std::max(0.0, 1.0 - phi * phi));
  // Second order: a first-order Gauss-Markov process `drive_` smoothed by a first-order lag of the
  // same time constant. The lag's output has half the drive's variance (scaled back by sqrt 2) and,
  // unlike a first-order process, a velocity: sigma / tau, not sigma sqrt(2 / step). Real common-mode
  // errors (orbit, atmosphere, the base station) wander slowly and smoothly.
  if (grid_.empty()) {
    drive_ = sigma.cwiseProduct(rng_.normal3());
    grid_.push_back(sigma.cwiseProduct(rng_.normal3()) / std::sqrt(2.0));
  }
  while (grid_.size() < i + 2) {
    const Eigen::Vector3d lag = phi * grid_.back() + (1.0 - phi) * drive_;
    drive_ = phi * drive_ + q * sigma.cwiseProduct(rng_.normal3());
    grid_.push_back(lag);
  }
  const double f = x - static_cast<double>(i);
  return std::sqrt(2.0) * ((1.0 - f) * grid_[i] + f * grid_[i + 1]);
}

GpsSimulator::GpsSimulator(const GpsConfig& config, std::uint64_t seed, TimestampNs start_gps_ns,
                           std::shared_ptr<CommonGpsError> common)
    : config_(config),
      start_ns_(start_gps_ns),
      period_ns_(period_ns_for(config.rate_hz)),
      rng_(seed),
      common_(std::move(common)),
      fixed_(config.start_fixed) {
  if (config.own_error.sigma_horizontal_m > 0 || config.own_error.sigma_vertical_m > 0)
    own_.emplace(config.own_error, derive_seed(seed, "own_error"));
}

std::optional<nav::GpsFix> GpsSimulator::next(const TruthFunction& truth) {
  const TimestampNs t_rel_ns = k_ * period_ns_;
  const double t = static_cast<double>(t_rel_ns) / 1e9;
  const double dt = static_cast<double>(period_ns_) / 1e9;
  const bool first = k_ == 0;
  ++k_;
  // Fixed draws per epoch, outage or not: chain, position, velocity, heading.
  const double u = rng_.uniform();
  const Eigen::Vector3d n_pos = rng_.normal3();
  const double n_vn = rng_.normal(), n_ve = rng_.normal(), n_hdg = rng_.normal();

  const bool rtk = config_.mode == GpsMode::kRtk;
  if (rtk && !first) {
    const double rate = fixed_ ? config_.fixed_to_float_per_s : config_.float_to_fixed_per_s;
    if (u < 1.0 - std::exp(-rate * dt)) fixed_ = !fixed_;
  }
  const bool outage = std::any_of(config_.outages.begin(), config_.outages.end(),
                                  [t](const GpsOutage& o) { return t >= o.t0_s && t <= o.t1_s; });
  if (outage) {
    fixed_ = false;  // an RTK receiver comes back from an outage in float
    return std::nullopt;
  }

  const KinematicState s = truth(t);
  const Eigen::Matrix3d C = s.R_ecef_body();
  const Eigen::Vector3d p_ant = s.p_ecef_m + C * config_.lever_arm_m;
  const nav::Geodetic g = nav::geodetic_from_ecef(p_ant);
  const Eigen::Matrix3d R_en = nav::R_ecef_ned(g.lat_rad, g.lon_rad);

  const bool use_float = rtk && !fixed_;
  const double sh = use_float ? config_.float_sigma_horizontal_m : config_.sigma_horizontal_m;
  const double sv = use_float ? config_.float_sigma_vertical_m : config_.sigma_vertical_m;
  Eigen::Vector3d e_ned(sh * n_pos.x(), sh * n_pos.y(), sv * n_pos.z());
  if (common_) e_ned += common_->ned_m(t);
  if (own_) e_ned += own_->ned_m(t);

  nav::GpsFix fix;
  fix.t_ns = start_ns_ + t_rel_ns;
  fix.arrival_ns = fix.t_ns + latency_ns(config_.latency_s);
  fix.antenna = nav::geodetic_from_ecef(p_ant + R_en * e_ned);
  fix.quality =
      !rtk ? nav::FixQuality::kSingle : (fixed_ ? nav::FixQuality::kRtkFixed : nav::FixQuality::kRtkFloat);
  fix.satellites = config_.satellites;
  fix.hdop = config_.hdop;
  fix.geoid_separation_m = synthetic_geoid_separation_m(fix.antenna.lat_rad, fix.antenna.lon_rad);
  // The receiver's own error budget covers its own wandering error, not the common one.
  fix.sigma_ned_m = Eigen::Vector3d(std::hypot(sh, config_.own_error.sigma_horizontal_m),
                                    std::hypot(sh, config_.own_error.sigma_horizontal_m),
                                    std::hypot(sv, config_.own_error.sigma_vertical_m));

  const Eigen::Vector3d v_ant = s.v_ecef_mps + C * s.w_eb_body_radps.cross(config_.lever_arm_m);
  const Eigen::Vector3d v_ned = R_en.transpose() * v_ant;
  const double vn = v_ned.x() + config_.velocity_sigma_mps * n_vn;
  const double ve = v_ned.y() + config_.velocity_sigma_mps * n_ve;
  fix.ground_speed_mps = std::hypot(vn, ve);
  fix.course_rad = wrap_two_pi(std::atan2(ve, vn));
  if (config_.heading) {
    const Eigen::Vector3d x_ned = R_en.transpose() * C.col(0);
    fix.heading_rad = wrap_two_pi(std::atan2(x_ned.y(), x_ned.x()) + config_.heading_sigma_rad * n_hdg);
  }
  return fix;
}

std::vector<nav::GpsFix> GpsSimulator::generate(const TruthFunction& truth, double t_end_s) {
  std::vector<nav::GpsFix> out;
  const TimestampNs end_ns = s_to_ns(t_end_s);
  while (k_ * period_ns_ <= end_ns) {
    if (auto f = next(truth)) out.push_back(*f);
  }
  return out;
}

// ---- Cameras ----------------------------------------------------------------------------------

std::vector<std::vector<CameraFrameTime>> simulate_camera_timing(const CameraTimingConfig& config,
                                                                 int cameras, double duration_s,
                                                                 std::uint64_t seed,
                                                                 TimestampNs start_gps_ns) {
  std::vector<std::vector<CameraFrameTime>> out(static_cast<std::size_t>(std::max(cameras, 0)));
  if (!(config.fps > 0) || duration_s < 0) return out;
  const auto frames = static_cast<std::uint64_t>(std::floor(duration_s * config.fps + 1e-9)) + 1;
  const auto at = [](const auto& v, std::size_t i) { return i < v.size() ? static_cast<double>(v[i]) : 0.0; };
  for (std::size_t c = 0; c < out.size(); ++c) {
    Rng rng(derive_seed(seed, "camera/" + std::to_string(c)));
    const double offset_ns = at(config.clock_offset_ns, c);
    const double drift = at(config.clock_drift_ppm, c) * 1e-6;
    const double exposure_s = at(config.exposure_offset_ns, c) * 1e-9;
    out[c].reserve(frames);
    for (std::uint64_t i = 0; i < frames; ++i) {
      const double n = rng.normal(), u = rng.uniform();
      CameraFrameTime f;
      f.sequence = i;
      f.t_true_s = static_cast<double>(i) / config.fps + exposure_s;
      f.t_camera_ns = start_gps_ns + std::llround(f.t_true_s * 1e9) + std::llround(offset_ns) +
                      std::llround(drift * f.t_true_s * 1e9) + std::llround(config.jitter_ns * n);
      f.dropped = u < config.drop_probability;
      out[c].push_back(f);
    }
  }
  return out;
}

// ---- A whole scenario -------------------------------------------------------------------------

SensorLogs simulate_sensors(const Scenario& sc, const Flight& flight) {
  SensorLogs logs;
  const TruthFunction tanker = [&flight](double t) { return flight.tanker(t); };
  const TruthFunction receiver = [&flight](double t) { return flight.receiver(t); };
  ImuSimulator tanker_imu(sc.sensors.tanker.imu, derive_seed(sc.seed, "tanker/imu"), sc.start_gps_ns);
  ImuSimulator receiver_imu(sc.sensors.receiver.imu, derive_seed(sc.seed, "receiver/imu"), sc.start_gps_ns);
  logs.tanker_imu = tanker_imu.generate(tanker, sc.duration_s);
  logs.receiver_imu = receiver_imu.generate(receiver, sc.duration_s);
  auto common =
      std::make_shared<CommonGpsError>(sc.sensors.common_gps_error, derive_seed(sc.seed, "common_gps"));
  GpsSimulator tanker_gps(sc.sensors.tanker.gps, derive_seed(sc.seed, "tanker/gps"), sc.start_gps_ns, common);
  GpsSimulator receiver_gps(sc.sensors.receiver.gps, derive_seed(sc.seed, "receiver/gps"), sc.start_gps_ns,
                            common);
  logs.tanker_gps = tanker_gps.generate(tanker, sc.duration_s);
  logs.receiver_gps = receiver_gps.generate(receiver, sc.duration_s);
  logs.cameras = simulate_camera_timing(sc.sensors.cameras, static_cast<int>(sc.rig.cameras.size()),
                                        sc.duration_s, derive_seed(sc.seed, "cameras"), sc.start_gps_ns);
  return logs;
}

}  // namespace augrig::sim
