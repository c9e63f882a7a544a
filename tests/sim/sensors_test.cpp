// Sensor models (sim/sensors.hpp): noise-free IMU increments integrate back to the truth, noise
// statistics match the models, the common GPS error is common, outages/latency/RTK switching, camera
// timestamps; everything deterministic per seed.
#include "sim/sensors.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "sim/flight.hpp"
#include "sim/scenario.hpp"

namespace augrig::sim {
namespace {

Scenario builtin(const std::string& name) {
  auto s = builtin_scenario(name);
  EXPECT_TRUE(s) << s.error().message;
  return *s;
}

Flight flight_of(const Scenario& s) {
  auto f = Flight::create(s);
  EXPECT_TRUE(f) << f.error().message;
  return *f;
}

// A body at rest on the Earth, somewhere, with some attitude: the cheap truth for noise statistics.
KinematicState resting(double t) {
  KinematicState s;
  s.t_s = t;
  s.p_ecef_m = nav::ecef_from_geodetic({0.8, 0.2, 300.0});
  s.q_ecef_body = Eigen::Quaterniond(nav::R_ecef_ned(0.8, 0.2) * rotation_from_ypr(0.3, 0.05, -0.02));
  return s;
}

ImuConfig noise_free_imu(double rate_hz) {
  ImuConfig c;
  c.rate_hz = rate_hz;
  c.errors = *imu_preset("noise_free");
  return c;
}

// ---- A careful ECEF strapdown, written here independently of the simulator ---------------------

struct NavState {
  Eigen::Quaterniond q_ecef_body;
  Eigen::Vector3d v_ecef_mps, p_ecef_m;
};

Eigen::Quaterniond exp_rotation(const Eigen::Vector3d& r) {
  const double a = r.norm();
  if (a == 0) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(a, r / a));
}

// Attitude: exact composition C_e_b(t1) = Rz(-w_ie dt) C_e_b(t0) Exp(dtheta). Velocity: the specific
// force increment rotated with the mid-interval attitude, plus gravity and Coriolis at the predicted
// mid-interval state. Position: trapezoid.
void strapdown_step(NavState& x, const nav::ImuSample& s) {
  const double dt = s.dt_s;
  const Eigen::Vector3d W = nav::earth_rate_ecef();
  const Eigen::Quaterniond earth_half(
      Eigen::AngleAxisd(-0.5 * nav::kEarthRate_radps * dt, Eigen::Vector3d::UnitZ()));
  const Eigen::Quaterniond earth(Eigen::AngleAxisd(-nav::kEarthRate_radps * dt, Eigen::Vector3d::UnitZ()));
  const Eigen::Quaterniond q_mid = earth_half * x.q_ecef_body * exp_rotation(0.5 * s.dtheta_rad);
  const Eigen::Vector3d dv_e = q_mid * s.dv_mps;
  const Eigen::Vector3d p_mid = x.p_ecef_m + 0.5 * dt * x.v_ecef_mps;
  const Eigen::Vector3d v_mid =
      x.v_ecef_mps + 0.5 * (dv_e + (nav::gravity_ecef(x.p_ecef_m) - 2.0 * W.cross(x.v_ecef_mps)) * dt);
  const Eigen::Vector3d v1 = x.v_ecef_mps + dv_e + (nav::gravity_ecef(p_mid) - 2.0 * W.cross(v_mid)) * dt;
  x.p_ecef_m += 0.5 * dt * (x.v_ecef_mps + v1);
  x.v_ecef_mps = v1;
  x.q_ecef_body = (earth * x.q_ecef_body * exp_rotation(s.dtheta_rad)).normalized();
}

struct Drift {
  double position_m = 0, velocity_mps = 0, attitude_rad = 0;
};

// Integrates the noise-free IMU of `truth` (shifted to start at t0) for `seconds`; worst errors.
Drift integrate(const TruthFunction& truth, double t0, double seconds, double rate_hz) {
  const TruthFunction shifted = [&](double t) {
    KinematicState s = truth(t0 + t);
    s.t_s = t;
    return s;
  };
  ImuSimulator imu(noise_free_imu(rate_hz), 1, 0);
  const KinematicState s0 = shifted(0);
  NavState x{s0.q_ecef_body, s0.v_ecef_mps, s0.p_ecef_m};
  Drift d;
  for (const nav::ImuSample& s : imu.generate(shifted, seconds)) {
    strapdown_step(x, s);
    const KinematicState tr = shifted(static_cast<double>(s.t_ns) / 1e9);
    d.position_m = std::max(d.position_m, (x.p_ecef_m - tr.p_ecef_m).norm());
    d.velocity_mps = std::max(d.velocity_mps, (x.v_ecef_mps - tr.v_ecef_mps).norm());
    d.attitude_rad =
        std::max(d.attitude_rad, Eigen::AngleAxisd(tr.q_ecef_body.conjugate() * x.q_ecef_body).angle());
  }
  return d;
}

TEST(ImuTest, NoiseFreeIncrementsIntegrateBackToTheTruth) {
  const Flight f = flight_of(builtin("contact-10min-noise-free"));
  const TruthFunction tanker = [&](double t) { return f.tanker(t); };
  const TruthFunction receiver = [&](double t) { return f.receiver(t); };
  // Tanker in its roll-in and turn; receiver in contact with turbulence, during the turn; receiver
  // moving to pre-contact on the straight leg.
  struct Case {
    const char* name;
    const TruthFunction* truth;
    double t0;
  };
  for (const Case& c :
       {Case{"tanker roll-in", &tanker, 85.0}, Case{"receiver contact in turn", &receiver, 150.0},
        Case{"receiver to-pre-contact", &receiver, 25.0}}) {
    const Drift d10 = integrate(*c.truth, c.t0, 10.0, 200.0);
    const Drift d60 = integrate(*c.truth, c.t0, 60.0, 200.0);
    std::printf(
        "%s from t = %.0f s, 200 Hz: 10 s: %.3g m, %.3g m/s, %.3g rad; 60 s: %.3g m, %.3g m/s, %.3g rad\n",
        c.name, c.t0, d10.position_m, d10.velocity_mps, d10.attitude_rad, d60.position_m, d60.velocity_mps,
        d60.attitude_rad);
    EXPECT_LT(d10.position_m, 1e-3) << c.name;
    EXPECT_LT(d10.attitude_rad, 1e-6) << c.name;
    EXPECT_LT(d60.position_m, 0.05) << c.name;
    EXPECT_LT(d60.attitude_rad, 1e-6) << c.name;
  }
}

TEST(ImuTest, AtRestOnTheGroundMeasuresGravityAndEarthRate) {
  Scenario s = builtin("demo-noise-free");
  s.tanker.speed_mps = 0;
  s.tanker.angle_of_attack_rad = 0;
  s.start.h_m = 0;
  const Flight f = flight_of(s);
  const TruthFunction truth = [&](double t) { return f.tanker(t); };
  ImuConfig cfg = noise_free_imu(100);
  cfg.latency_s = 0.002;
  ImuSimulator imu(cfg, 3, s.start_gps_ns);
  const auto samples = imu.generate(truth, 2.0);
  ASSERT_EQ(samples.size(), 200u);
  const KinematicState k = truth(0);
  const double g = nav::gravity_ecef(k.p_ecef_m).norm();
  const Eigen::Vector3d earth_body = k.q_ecef_body.conjugate() * nav::earth_rate_ecef();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const nav::ImuSample& x = samples[i];
    EXPECT_EQ(x.t_ns, s.start_gps_ns + static_cast<TimestampNs>(i + 1) * 10000000);
    EXPECT_EQ(x.arrival_ns, x.t_ns + 2000000);
    EXPECT_DOUBLE_EQ(x.dt_s, 0.01);
    EXPECT_NEAR(x.dv_mps.norm(), g * 0.01, 1e-12);
    // Specific force points up (body -z when level).
    EXPECT_NEAR(x.dv_mps.z(), -g * 0.01, 1e-11);
    EXPECT_LT((x.dtheta_rad - earth_body * 0.01).norm(), 1e-15);
    EXPECT_NEAR(x.dtheta_rad.norm(), nav::kEarthRate_radps * 0.01, 1e-15);
  }
}

TEST(ImuTest, IncrementsMatchTheRatesAndSpecificForce) {
  // Over a short interval the increments approach w_ib dt and f_b dt.
  const Flight f = flight_of(builtin("contact-10min-noise-free"));
  const TruthFunction truth = [&](double t) { return f.receiver(t); };
  const double t0 = 150.0, dt = 1e-4;
  const ImuIncrement inc = exact_imu_increment(truth, t0, t0 + dt);
  const KinematicState mid = truth(t0 + 0.5 * dt);
  EXPECT_LT((inc.dtheta_rad / dt - inertial_rate_body(mid)).norm(), 1e-9);
  EXPECT_LT((inc.dv_mps / dt - specific_force_body(mid)).norm(), 1e-6);
}

struct Stats {
  double mean = 0, sd = 0;
};
Stats stats(const std::vector<double>& v) {
  Stats s;
  for (double x : v) s.mean += x;
  s.mean /= static_cast<double>(v.size());
  for (double x : v) s.sd += (x - s.mean) * (x - s.mean);
  s.sd = std::sqrt(s.sd / static_cast<double>(v.size() - 1));
  return s;
}

TEST(ImuTest, WhiteNoiseHasTheModelsSigma) {
  const TruthFunction truth = resting;
  ImuConfig cfg = noise_free_imu(200);
  cfg.errors.gyro.arw_rad_per_sqrt_s = deg_to_rad(0.1) / 60.0;  // 0.1 deg/sqrt(h)
  cfg.errors.accel.vrw_mps_per_sqrt_s = 0.05 / 60.0;            // 0.05 m/s/sqrt(h)
  ImuSimulator noisy(cfg, 11, 0), clean(noise_free_imu(200), 11, 0);
  const auto a = noisy.generate(truth, 100.0), b = clean.generate(truth, 100.0);
  ASSERT_EQ(a.size(), b.size());
  std::vector<double> g, v;
  const double sdt = std::sqrt(0.005);
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      g.push_back((a[i].dtheta_rad[k] - b[i].dtheta_rad[k]) / sdt);
      v.push_back((a[i].dv_mps[k] - b[i].dv_mps[k]) / sdt);
    }
  }
  const Stats sg = stats(g), sv = stats(v);
  EXPECT_NEAR(sg.sd, cfg.errors.gyro.arw_rad_per_sqrt_s, 0.05 * cfg.errors.gyro.arw_rad_per_sqrt_s);
  EXPECT_NEAR(sv.sd, cfg.errors.accel.vrw_mps_per_sqrt_s, 0.05 * cfg.errors.accel.vrw_mps_per_sqrt_s);
  EXPECT_NEAR(sg.mean, 0.0, 0.05 * cfg.errors.gyro.arw_rad_per_sqrt_s);
}

TEST(ImuTest, BiasProcessesHaveTheirStatistics) {
  const TruthFunction truth = resting;
  // Gauss-Markov: stationary sigma and correlation e^-1 at one tau.
  ImuConfig cfg = noise_free_imu(100);
  cfg.errors.gyro.bias_instability_radps = deg_to_rad(1.0) / 3600.0;
  cfg.errors.gyro.bias_tau_s = 0.5;
  ImuSimulator imu(cfg, 5, 0);
  std::vector<double> b;
  for (int i = 0; i < 100000; ++i) {
    imu.next(truth);
    b.push_back(imu.gyro_bias_radps().x());
  }
  const Stats s = stats(b);
  EXPECT_NEAR(s.sd, cfg.errors.gyro.bias_instability_radps, 0.1 * cfg.errors.gyro.bias_instability_radps);
  double c = 0;
  for (std::size_t i = 50; i < b.size(); ++i) c += (b[i] - s.mean) * (b[i - 50] - s.mean);
  c /= static_cast<double>(b.size() - 50) * s.sd * s.sd;
  EXPECT_NEAR(c, std::exp(-1.0), 0.1);

  // Random walk: variance K^2 t across seeds; turn-on bias: sigma across seeds.
  ImuConfig rw = noise_free_imu(100);
  rw.errors.accel.random_walk_mps2_per_sqrt_s = 1e-3;
  rw.errors.gyro.turn_on_bias_radps = 1e-4;
  std::vector<double> end, turn_on;
  for (std::uint64_t seed = 0; seed < 1000; ++seed) {
    ImuSimulator x(rw, seed, 0);
    for (int i = 0; i < 100; ++i) x.next(truth);  // 1 s
    end.push_back(x.accel_bias_mps2().y());
    turn_on.push_back(x.gyro_bias_radps().z());
  }
  EXPECT_NEAR(stats(end).sd, 1e-3, 0.1e-3);
  EXPECT_NEAR(stats(turn_on).sd, 1e-4, 0.1e-4);
}

TEST(ImuTest, DeterministicPerSeedAndPresets) {
  const TruthFunction truth = resting;
  ImuConfig cfg;  // tactical
  ImuSimulator a(cfg, 42, 0), b(cfg, 42, 0), c(cfg, 43, 0);
  const auto xa = a.generate(truth, 1.0), xb = b.generate(truth, 1.0), xc = c.generate(truth, 1.0);
  ASSERT_EQ(xa.size(), 200u);
  for (std::size_t i = 0; i < xa.size(); ++i) {
    EXPECT_EQ(xa[i].dtheta_rad, xb[i].dtheta_rad);
    EXPECT_EQ(xa[i].dv_mps, xb[i].dv_mps);
  }
  EXPECT_NE(xa[7].dv_mps, xc[7].dv_mps);
  for (const char* p : {"noise_free", "navigation", "tactical", "consumer"}) EXPECT_TRUE(imu_preset(p)) << p;
  EXPECT_FALSE(imu_preset("strategic"));
  const ImuErrorModel tactical = *imu_preset("tactical");
  EXPECT_NEAR(tactical.gyro.arw_rad_per_sqrt_s, deg_to_rad(0.1) / 60.0, 1e-15);
  EXPECT_NEAR(tactical.gyro.bias_instability_radps, deg_to_rad(1.0) / 3600.0, 1e-15);
  EXPECT_NEAR(tactical.accel.bias_instability_mps2, 0.5e-3 * 9.80665, 1e-12);
  EXPECT_NEAR(tactical.accel.vrw_mps_per_sqrt_s, 0.05 / 60.0, 1e-15);
  EXPECT_EQ(*imu_preset("noise_free"), ImuErrorModel{});
}

// The IMU's clock against GPS time (ImuConfig::clock_offset_ns, clock_drift_ppm) moves the stamps
// only: sample k is stamped t_k + offset + round(drift t_k); its increments and its arrival on the
// host (whose clock is GPS time) are those of an IMU on GPS time.
TEST(ImuTest, ClockOffsetAndDriftMoveTheStampsOnly) {
  const TimestampNs start = 1'400'000'000'000'000'000;
  ImuConfig plain;  // tactical
  plain.latency_s = 0.002;
  ImuConfig clocked = plain;
  clocked.clock_offset_ns = 7'000'000;
  clocked.clock_drift_ppm = -20.0;
  ImuSimulator a(plain, 5, start), b(clocked, 5, start);
  const auto xa = a.generate(resting, 30.0), xb = b.generate(resting, 30.0);
  ASSERT_EQ(xa.size(), xb.size());
  ASSERT_EQ(xa.size(), 6000u);
  for (std::size_t i = 0; i < xa.size(); ++i) {
    const TimestampNs t = xa[i].t_ns - start;
    EXPECT_EQ(xb[i].t_ns, xa[i].t_ns + 7'000'000 + std::llround(-20e-6 * static_cast<double>(t))) << i;
    EXPECT_EQ(xb[i].arrival_ns, xa[i].arrival_ns) << i;
    EXPECT_EQ(xb[i].dt_s, xa[i].dt_s);
    EXPECT_EQ(xb[i].dtheta_rad, xa[i].dtheta_rad);
    EXPECT_EQ(xb[i].dv_mps, xa[i].dv_mps);
  }
  EXPECT_EQ(xa.back().arrival_ns, xa.back().t_ns + 2'000'000);
  EXPECT_EQ(xb.back().t_ns - xa.back().t_ns, 7'000'000 - 600'000);  // 30 s at -20 ppm
}

// ---- GPS --------------------------------------------------------------------------------------

// NED error of a fix w.r.t. the true antenna position.
Eigen::Vector3d fix_error_ned(const nav::GpsFix& fix, const KinematicState& truth,
                              const Eigen::Vector3d& lever) {
  const Eigen::Vector3d p_true = truth.p_ecef_m + truth.q_ecef_body * lever;
  const nav::Geodetic g = nav::geodetic_from_ecef(p_true);
  return nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * (nav::ecef_from_geodetic(fix.antenna) - p_true);
}

GpsConfig quiet_gps(double rate_hz) {
  GpsConfig c;
  c.rate_hz = rate_hz;
  c.sigma_horizontal_m = c.sigma_vertical_m = 0;
  c.float_sigma_horizontal_m = c.float_sigma_vertical_m = 0;
  c.fixed_to_float_per_s = 0;
  c.velocity_sigma_mps = 0;
  c.heading_sigma_rad = 0;
  return c;
}

TEST(GpsTest, WhiteNoiseHasTheModelsSigma) {
  GpsConfig cfg = quiet_gps(20);
  cfg.mode = GpsMode::kSingle;
  cfg.sigma_horizontal_m = 1.5;
  cfg.sigma_vertical_m = 3.0;
  cfg.lever_arm_m = {1.0, 0.5, -2.0};
  GpsSimulator gps(cfg, 9, 0, nullptr);
  const auto fixes = gps.generate(resting, 1000.0);
  ASSERT_EQ(fixes.size(), 20001u);
  std::vector<double> n, e, d;
  for (const nav::GpsFix& f : fixes) {
    const Eigen::Vector3d err = fix_error_ned(f, resting(0), cfg.lever_arm_m);
    n.push_back(err.x());
    e.push_back(err.y());
    d.push_back(err.z());
    EXPECT_EQ(f.quality, nav::FixQuality::kSingle);
    ASSERT_TRUE(f.sigma_ned_m);
    EXPECT_EQ(*f.sigma_ned_m, Eigen::Vector3d(1.5, 1.5, 3.0));
  }
  EXPECT_NEAR(stats(n).sd, 1.5, 0.075);
  EXPECT_NEAR(stats(e).sd, 1.5, 0.075);
  EXPECT_NEAR(stats(d).sd, 3.0, 0.15);
  EXPECT_NEAR(stats(d).mean, 0.0, 0.1);
}

TEST(GpsTest, CommonErrorIsTheSameForBothAircraft) {
  const Flight f = flight_of(builtin("demo-noise-free"));
  const TruthFunction tanker = [&](double t) { return f.tanker(t); };
  const TruthFunction receiver = [&](double t) { return f.receiver(t); };
  CommonGpsErrorConfig ce{0.5, 1.0, 60.0};
  auto common = std::make_shared<CommonGpsError>(ce, 77);
  GpsConfig ct = quiet_gps(10), cr = quiet_gps(5);
  ct.lever_arm_m = {5.0, 0.0, -3.5};
  cr.lever_arm_m = {1.0, 0.0, -1.2};
  GpsSimulator gt(ct, 1, 0, common), gr(cr, 2, 0, common);
  // Interleaved requests in different orders must not matter.
  const auto fr = gr.generate(receiver, 28.0);
  const auto ft = gt.generate(tanker, 28.0);
  ASSERT_EQ(ft.size(), 281u);
  ASSERT_EQ(fr.size(), 141u);
  double biggest = 0;
  for (const nav::GpsFix& r : fr) {
    const nav::GpsFix& t = ft[static_cast<std::size_t>(r.t_ns / 100000000)];
    ASSERT_EQ(t.t_ns, r.t_ns);
    const double ts = static_cast<double>(r.t_ns) / 1e9;
    const Eigen::Vector3d et = fix_error_ned(t, tanker(ts), ct.lever_arm_m);
    const Eigen::Vector3d er = fix_error_ned(r, receiver(ts), cr.lever_arm_m);
    EXPECT_LT((et - er).norm(), 1e-6) << ts;
    EXPECT_LT((et - common->ned_m(ts)).norm(), 1e-6) << ts;
    biggest = std::max(biggest, et.norm());
  }
  EXPECT_GT(biggest, 0.1);  // there is an error, and it is common
  // A second object with the same seed is the same realisation; its statistics are the model's.
  CommonGpsError again(ce, 77), other(ce, 78);
  EXPECT_EQ(again.ned_m(12.34), common->ned_m(12.34));
  EXPECT_NE(other.ned_m(12.34), common->ned_m(12.34));
  std::vector<double> n, d;
  for (double t = 0; t < 200000; t += 10) {
    const Eigen::Vector3d e = again.ned_m(t);
    n.push_back(e.x());
    d.push_back(e.z());
  }
  EXPECT_NEAR(stats(n).sd, 0.5, 0.05);
  EXPECT_NEAR(stats(d).sd, 1.0, 0.1);
}

TEST(GpsTest, OutagesLatencyAndTimes) {
  GpsConfig cfg = quiet_gps(10);
  cfg.latency_s = 0.045;
  cfg.outages = {{2.0, 3.5}, {7.25, 7.25}};
  cfg.float_to_fixed_per_s = 0;
  GpsSimulator gps(cfg, 1, 1000000000000, nullptr);
  const auto fixes = gps.generate(resting, 10.0);
  // Epochs 0, 0.1, ..., 10: 101, minus 2.0..3.5 (16 epochs); 7.25 is no epoch.
  EXPECT_EQ(fixes.size(), 101u - 16u);
  bool after_outage_float = false;
  for (const nav::GpsFix& f : fixes) {
    const double t = static_cast<double>(f.t_ns - 1000000000000) / 1e9;
    EXPECT_FALSE(t >= 2.0 - 1e-9 && t <= 3.5 + 1e-9) << t;
    EXPECT_EQ(f.arrival_ns - f.t_ns, 45000000);
    EXPECT_EQ((f.t_ns - 1000000000000) % 100000000, 0);
    if (std::abs(t - 3.6) < 1e-9) after_outage_float = f.quality == nav::FixQuality::kRtkFloat;
  }
  EXPECT_TRUE(after_outage_float);
}

TEST(GpsTest, RtkSwitchesBetweenFixedAndFloat) {
  GpsConfig cfg = quiet_gps(10);
  cfg.sigma_horizontal_m = 0.01;
  cfg.sigma_vertical_m = 0.02;
  cfg.float_sigma_horizontal_m = 0.3;
  cfg.float_sigma_vertical_m = 0.6;
  cfg.fixed_to_float_per_s = 0.5;
  cfg.float_to_fixed_per_s = 0.5;
  GpsSimulator gps(cfg, 4, 0, nullptr);
  const auto fixes = gps.generate(resting, 200.0);
  int fixed = 0, flt = 0, switches = 0;
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    const nav::GpsFix& f = fixes[i];
    ASSERT_TRUE(f.quality == nav::FixQuality::kRtkFixed || f.quality == nav::FixQuality::kRtkFloat);
    const bool is_fixed = f.quality == nav::FixQuality::kRtkFixed;
    (is_fixed ? fixed : flt)++;
    EXPECT_EQ(f.sigma_ned_m->x(), is_fixed ? 0.01 : 0.3);
    EXPECT_EQ(f.sigma_ned_m->z(), is_fixed ? 0.02 : 0.6);
    if (i > 0 && f.quality != fixes[i - 1].quality) ++switches;
  }
  std::printf("RTK: %d fixed, %d float epochs, %d switches\n", fixed, flt, switches);
  EXPECT_EQ(fixes.front().quality, nav::FixQuality::kRtkFixed);  // start_fixed
  EXPECT_GT(fixed, 300);
  EXPECT_GT(flt, 300);
  EXPECT_GT(switches, 20);
}

TEST(GpsTest, VelocityHeadingGeoidAndDeterminism) {
  const Scenario s = builtin("demo-noise-free");
  const Flight f = flight_of(s);
  const TruthFunction tanker = [&](double t) { return f.tanker(t); };
  GpsConfig cfg = quiet_gps(10);
  cfg.heading = true;
  GpsSimulator gps(cfg, 1, s.start_gps_ns, nullptr);
  for (const nav::GpsFix& x : gps.generate(tanker, 5.0)) {
    // The antenna 1.5 m above the body origin flies a hair faster over the curved Earth.
    EXPECT_NEAR(*x.ground_speed_mps, s.tanker.speed_mps, 1e-4);
    EXPECT_NEAR(*x.course_rad, s.tanker.heading_rad, 1e-7);
    // (In the NED frame at the antenna, whose longitude differs by ~2e-8 rad: meridian convergence.)
    EXPECT_NEAR(*x.heading_rad, s.tanker.heading_rad + s.tanker.crab_rad, 1e-7);
    EXPECT_EQ(x.geoid_separation_m, synthetic_geoid_separation_m(x.antenna.lat_rad, x.antenna.lon_rad));
    EXPECT_EQ(x.quality, nav::FixQuality::kRtkFixed);
    EXPECT_EQ(x.satellites, 16);
  }
  // The synthetic geoid is smooth and of a plausible size.
  for (double lat = -1.4; lat <= 1.4; lat += 0.1)
    for (double lon = -3.1; lon <= 3.1; lon += 0.1)
      EXPECT_LT(std::abs(synthetic_geoid_separation_m(lat, lon)), 80.0);

  GpsConfig noisy;  // defaults: RTK with noise
  auto c1 = std::make_shared<CommonGpsError>(CommonGpsErrorConfig{}, 5);
  auto c2 = std::make_shared<CommonGpsError>(CommonGpsErrorConfig{}, 5);
  GpsSimulator a(noisy, 8, 0, c1), b(noisy, 8, 0, c2), c(noisy, 9, 0, c2);
  const auto xa = a.generate(tanker, 10.0), xb = b.generate(tanker, 10.0), xc = c.generate(tanker, 10.0);
  ASSERT_EQ(xa.size(), xb.size());
  for (std::size_t i = 0; i < xa.size(); ++i) {
    EXPECT_EQ(xa[i].antenna.lat_rad, xb[i].antenna.lat_rad);
    EXPECT_EQ(xa[i].antenna.h_m, xb[i].antenna.h_m);
    EXPECT_EQ(xa[i].quality, xb[i].quality);
  }
  EXPECT_NE(xa[3].antenna.h_m, xc[3].antenna.h_m);
}

// Hand-worked convention: with a 4 deg crab to the right (the nose 4 deg clockwise of the track, as
// into a wind from the right), HDT's heading is the Euler yaw of R_ned_body (the nose),
// RMC/VTG's course is the track (the velocity), and they differ by exactly the crab.
TEST(GpsTest, HeadingIsTheNoseYawCourseIsTheTrack) {
  Scenario s = builtin("demo-noise-free");
  s.tanker.heading_rad = deg_to_rad(30.0);
  s.tanker.crab_rad = deg_to_rad(4.0);
  const Flight f = flight_of(s);
  const TruthFunction tanker = [&](double t) { return f.tanker(t); };
  GpsConfig cfg = quiet_gps(10);
  cfg.heading = true;
  GpsSimulator gps(cfg, 1, s.start_gps_ns, nullptr);
  for (const nav::GpsFix& x : gps.generate(tanker, 2.0)) {
    EXPECT_NEAR(rad_to_deg(*x.heading_rad), 34.0, 1e-5);
    EXPECT_NEAR(rad_to_deg(*x.course_rad), 30.0, 1e-5);
    const KinematicState k = f.tanker(ns_to_s(x.t_ns - s.start_gps_ns));
    const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
    const YawPitchRoll e = ypr_from_rotation(nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.R_ecef_body());
    EXPECT_NEAR(rad_to_deg(e.yaw_rad), 34.0, 1e-5);
    EXPECT_NEAR(rad_to_deg(e.pitch_rad), rad_to_deg(s.tanker.angle_of_attack_rad), 1e-5);  // level flight
    EXPECT_NEAR(e.roll_rad, 0.0, 1e-9);
  }
}

// ---- Cameras ----------------------------------------------------------------------------------

TEST(CameraTimingTest, OffsetsJitterDropsAndDeterminism) {
  CameraTimingConfig cfg;
  cfg.fps = 30;
  cfg.clock_offset_ns = {1200000, -500};
  cfg.exposure_offset_ns = {0, 250000};
  const TimestampNs start = 1400000000000000000;
  // Noise-free: exact times.
  auto clean = simulate_camera_timing(cfg, 2, 10.0, 1, start);
  ASSERT_EQ(clean.size(), 2u);
  ASSERT_EQ(clean[0].size(), 301u);
  for (int c = 0; c < 2; ++c) {
    for (const CameraFrameTime& f : clean[static_cast<std::size_t>(c)]) {
      const double nominal = static_cast<double>(f.sequence) / 30.0;
      EXPECT_NEAR(f.t_true_s, nominal + (c == 1 ? 250e-6 : 0.0), 1e-12);
      EXPECT_EQ(f.t_camera_ns,
                start + std::llround(f.t_true_s * 1e9) + cfg.clock_offset_ns[static_cast<std::size_t>(c)]);
      EXPECT_FALSE(f.dropped);
    }
  }
  // Jitter and drops.
  cfg.jitter_ns = 20000;
  cfg.drop_probability = 0.1;
  const auto a = simulate_camera_timing(cfg, 2, 3000.0, 7, start);
  const auto b = simulate_camera_timing(cfg, 2, 3000.0, 7, start);
  const auto c = simulate_camera_timing(cfg, 2, 3000.0, 8, start);
  std::vector<double> jitter;
  std::size_t dropped = 0;
  for (const CameraFrameTime& f : a[0]) {
    jitter.push_back(static_cast<double>(f.t_camera_ns - start - std::llround(f.t_true_s * 1e9) - 1200000));
    dropped += f.dropped ? 1 : 0;
  }
  EXPECT_NEAR(stats(jitter).sd, 20000.0, 1000.0);
  EXPECT_NEAR(static_cast<double>(dropped) / static_cast<double>(a[0].size()), 0.1, 0.01);
  for (std::size_t i = 0; i < a[1].size(); ++i) {
    EXPECT_EQ(a[1][i].t_camera_ns, b[1][i].t_camera_ns);
    EXPECT_EQ(a[1][i].dropped, b[1][i].dropped);
  }
  EXPECT_NE(a[1][5].t_camera_ns, c[1][5].t_camera_ns);
  // The two cameras jitter independently.
  EXPECT_NE(a[0][5].t_camera_ns - a[0][5].t_true_s, a[1][5].t_camera_ns - a[1][5].t_true_s);
}

TEST(SensorLogsTest, WholeDemoScenario) {
  const Scenario s = builtin("demo");
  const Flight f = flight_of(s);
  const SensorLogs logs = simulate_sensors(s, f);
  EXPECT_EQ(logs.tanker_imu.size(), 5600u);
  EXPECT_EQ(logs.receiver_imu.size(), 5600u);
  EXPECT_EQ(logs.tanker_gps.size(), 281u);
  EXPECT_EQ(logs.receiver_gps.size(), 281u);
  ASSERT_EQ(logs.cameras.size(), 2u);
  EXPECT_EQ(logs.cameras[0].size(), 841u);
  EXPECT_EQ(logs.tanker_imu.front().t_ns, s.start_gps_ns + 5000000);
  EXPECT_TRUE(logs.tanker_gps.front().heading_rad.has_value());
  EXPECT_FALSE(logs.receiver_gps.front().heading_rad.has_value());
  // Deterministic.
  const SensorLogs again = simulate_sensors(s, f);
  EXPECT_EQ(again.receiver_imu[1234].dv_mps, logs.receiver_imu[1234].dv_mps);
  EXPECT_EQ(again.receiver_gps[99].antenna.lat_rad, logs.receiver_gps[99].antenna.lat_rad);
}

}  // namespace
}  // namespace augrig::sim
