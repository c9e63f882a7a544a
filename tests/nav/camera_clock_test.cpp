// Camera clock from the images: the fit recovers a known offset and drift from exact rotations, and
// from frames the simulator renders through a manoeuvring flight (a 20 ms offset to <= 1 ms within
// 60 s, its 1-sigma consistent); with no angular motion it says unobservable. The reported 1-sigma
// covers a clock error along each manoeuvre's own signal (the error within 2.5 of it).
#include "nav/camera_clock.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <utility>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "nav/logs.hpp"
#include "render/image_file.hpp"
#include "render/rig.hpp"
#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/synthetic_scene.hpp"

namespace augrig::nav {
namespace {

// ---- fit only -----------------------------------------------------------------------------------

// A body rate of sinusoids (manoeuvres and turbulence) and its exact integral.
struct Sines {
  struct Term {
    double amp, freq_hz, phase;
    int axis;
  };
  std::vector<Term> terms{{0.05, 0.13, 0.3, 0}, {0.03, 0.71, 1.1, 1}, {0.02, 1.9, 2.0, 2},
                          {0.04, 0.37, 0.7, 2}, {0.01, 3.1, 0.1, 0},  {0.02, 0.23, 2.5, 1}};
  Eigen::Vector3d rate(double t) const {
    Eigen::Vector3d w(0.001, -0.002, 0.0005);  // a constant: gyro bias, Earth rate
    for (const Term& x : terms) w(x.axis) += x.amp * std::sin(2 * kPi * x.freq_hz * t + x.phase);
    return w;
  }
  Eigen::Vector3d integral(double t0, double t1) const {
    Eigen::Vector3d a = Eigen::Vector3d(0.001, -0.002, 0.0005) * (t1 - t0);
    for (const Term& x : terms) {
      const double k = 2 * kPi * x.freq_hz;
      a(x.axis) += x.amp * (std::cos(k * t0 + x.phase) - std::cos(k * t1 + x.phase)) / k;
    }
    return a;
  }
};

constexpr TimestampNs kGps0 = 1'400'000'000'000'000'000;

Eigen::Matrix3d some_R_cam_body() {
  return R_body_cam_from_mount_ypr(kPi, deg_to_rad(-25), 0).transpose();
}

// Frames at 30 fps on GPS time; the camera stamps t_cam = t_gps + offset + drift (t_gps - t0).
std::vector<FrameRotation> exact_rotations(const Sines& s, const Eigen::Matrix3d& R_cam_body, double offset_s,
                                           double drift_ppm, double duration_s) {
  std::vector<FrameRotation> out;
  const int n = static_cast<int>(duration_s * 30);
  auto stamp = [&](double t) { return kGps0 + s_to_ns(t + offset_s + drift_ppm * 1e-6 * t); };
  for (int k = 0; k < n; ++k) {
    const double t0 = k / 30.0, t1 = (k + 1) / 30.0;
    FrameRotation r;
    r.t0_camera_ns = stamp(t0);
    r.t1_camera_ns = stamp(t1);
    r.rotvec_cam_rad = R_cam_body * s.integral(t0, t1);
    r.inliers = r.features = 100;
    out.push_back(r);
  }
  return out;
}

// The body rate of a signal (Sines, Pulses) on GPS time, as the fit asks for it.
template <typename Signal>
AngularRateFunction rate_of(const Signal& s) {
  return [s](TimestampNs t_ns) -> std::optional<Eigen::Vector3d> { return s.rate(ns_to_s(t_ns - kGps0)); };
}

TEST(CameraClockFit, RecoversOffsetFromExactRotations) {
  const Sines s;
  const Eigen::Matrix3d R = some_R_cam_body();
  CameraClockOptions o;
  o.estimate_drift = false;
  const auto est = fit_camera_clock(exact_rotations(s, R, 0.020, 0, 60), R, rate_of(s), o);
  ASSERT_TRUE(est) << est.error().message;
  ASSERT_TRUE(est->observable) << est->reason;
  EXPECT_NEAR(est->offset_s, 0.020, 2e-6);
  EXPECT_LT(est->offset_sigma_s, 1e-5);
  EXPECT_LE(std::abs(est->offset_s - 0.020), 2.5 * est->offset_sigma_s);
  // Motion all through: many blocks to compare, so no floor.
  EXPECT_GE(est->effective_blocks, 3);
  EXPECT_TRUE(std::isnan(est->offset_sigma_floor_s));
  EXPECT_NE(est->sigma_source, CameraClockEstimate::SigmaSource::kFloor);
  EXPECT_NEAR(est->scale, 1.0, 1e-3);
  EXPECT_GT(est->explained, 0.999);
  EXPECT_FALSE(est->drift_observable);
}

TEST(CameraClockFit, RecoversOffsetAndDrift) {
  const Sines s;
  const Eigen::Matrix3d R = some_R_cam_body();
  const double drift_ppm = 40;
  const auto rot = exact_rotations(s, R, -0.0437, drift_ppm, 120);
  const auto est = fit_camera_clock(rot, R, rate_of(s));
  ASSERT_TRUE(est) << est.error().message;
  ASSERT_TRUE(est->observable) << est->reason;
  ASSERT_TRUE(est->drift_observable);
  EXPECT_NEAR(est->drift_ppm, drift_ppm, 0.1);
  EXPECT_LE(std::abs(est->drift_ppm - drift_ppm), 2.5 * est->drift_sigma_ppm);
  const double t_ref = ns_to_s(est->reference_camera_ns - kGps0);
  const double offset_at_ref = -0.0437 + drift_ppm * 1e-6 * (t_ref + 0.0437) / (1 + drift_ppm * 1e-6);
  EXPECT_LE(std::abs(est->offset_s - offset_at_ref), 2.5 * est->offset_sigma_s);
  // The offset at any frame: t_gps = t_cam - offset_at(t_cam).
  for (const FrameRotation& r : {rot.front(), rot[rot.size() / 2], rot.back()}) {
    const double t_gps = ns_to_s(r.t0_camera_ns - kGps0) - est->offset_at_s(r.t0_camera_ns);
    const double truth = (ns_to_s(r.t0_camera_ns - kGps0) + 0.0437) / (1 + drift_ppm * 1e-6);
    EXPECT_NEAR(t_gps, truth, 3e-6);
  }
}

// Roll pulses (a roll-in's rate, sin^2 over 4 s) of alternating sign, each at its own place, and
// their exact integral. Each pulse's rotations can carry a clock error of their own: what the
// images did in the rendered flights (docs/CLOCK_OFFSETS.md, "Limits"), and what neither the
// residuals nor their autocorrelation show.
struct Pulses {
  std::vector<double> start_s;  // each pulse over [start, start + 4 s]
  std::vector<double> bias_s;   // its rotations' clock error
  double amp = 0.3, len = 4;
  Eigen::Vector3d constant{0.001, -0.002, 0.0005};
  double roll(double t) const {  // the integral of the roll rate from 0 to t
    double a = 0;
    for (std::size_t m = 0; m < start_s.size(); ++m) {
      const double u = std::clamp(t - start_s[m], 0.0, len), sign = m % 2 == 0 ? 1 : -1;
      a += sign * amp * (u / 2 - len / (4 * kPi) * std::sin(2 * kPi * u / len));
    }
    return a;
  }
  Eigen::Vector3d rate(double t) const {
    Eigen::Vector3d w = constant;
    for (std::size_t m = 0; m < start_s.size(); ++m) {
      const double u = t - start_s[m], sign = m % 2 == 0 ? 1 : -1;
      if (u > 0 && u < len) w.x() += sign * amp * std::pow(std::sin(kPi * u / len), 2);
    }
    return w;
  }
  Eigen::Vector3d integral(double t0, double t1) const {
    return constant * (t1 - t0) + Eigen::Vector3d(roll(t1) - roll(t0), 0, 0);
  }
  double bias_at(double t) const {  // the clock error of the pulse within 3 s of t
    for (std::size_t m = 0; m < start_s.size(); ++m)
      if (std::abs(t - (start_s[m] + len / 2)) < len / 2 + 3) return bias_s[m];
    return 0;
  }
};

// 15 fps over [a, b] of GPS time, camera stamps offset_s ahead; a little noise (1e-5 rad).
std::vector<FrameRotation> pulse_rotations(const Pulses& p, const Eigen::Matrix3d& R_cam_body,
                                           double offset_s, double a, double b) {
  std::vector<FrameRotation> out;
  sim::Rng rng(11);
  for (double t0 = a; t0 + 1 / 15.0 <= b; t0 += 1 / 15.0) {
    const double t1 = t0 + 1 / 15.0, e = p.bias_at(0.5 * (t0 + t1));
    FrameRotation r;
    r.t0_camera_ns = kGps0 + s_to_ns(t0 + offset_s);
    r.t1_camera_ns = kGps0 + s_to_ns(t1 + offset_s);
    r.rotvec_cam_rad = R_cam_body * p.integral(t0 - e, t1 - e) + 1e-5 * rng.normal3();
    r.inliers = r.features = 100;
    out.push_back(r);
  }
  return out;
}

// The reported 1-sigma covers a clock error along each manoeuvre's own signal, which the fit's own
// 1-sigma (residuals, Newey-West) does not: with one manoeuvre by the floor, with many by the
// jackknife over blocks of time, with a manoeuvre cut by the data's start by a larger floor.
TEST(CameraClockFit, SigmaCoversAClockErrorAlongEachManoeuvre) {
  const Eigen::Matrix3d R = some_R_cam_body();
  const double offset = 0.020;
  // One pulse, 0.4 ms off.
  {
    const Pulses p{{4.0}, {0.4e-3}};
    const auto est = fit_camera_clock(pulse_rotations(p, R, offset, 0, 12), R, rate_of(p));
    ASSERT_TRUE(est) << est.error().message;
    ASSERT_TRUE(est->observable) << est->reason;
    const double err = est->offset_s - offset;
    EXPECT_NEAR(err, 0.4e-3, 0.05e-3);
    EXPECT_GT(std::abs(err), 2.5 * est->offset_sigma_fit_s);  // the fit's own 1-sigma does not cover it
    EXPECT_LE(std::abs(err), 2.5 * est->offset_sigma_s);
    EXPECT_EQ(est->sigma_source, CameraClockEstimate::SigmaSource::kFloor);
    EXPECT_NEAR(est->offset_sigma_s, 0.5e-3, 0.1e-3);
    EXPECT_FALSE(est->edge_cut);
    EXPECT_NE(describe_sigma(*est).find("floor"), std::string::npos) << describe_sigma(*est);
  }
  // Twelve pulses 11 s apart, each off by its own error (1-sigma 0.4 ms), drift fitted.
  {
    Pulses p;
    sim::Rng rng(5);
    for (int m = 0; m < 12; ++m) {
      p.start_s.push_back(5.0 + 11.0 * m);
      p.bias_s.push_back(0.4e-3 * rng.normal());
    }
    const auto est = fit_camera_clock(pulse_rotations(p, R, offset, 0, 136), R, rate_of(p));
    ASSERT_TRUE(est) << est.error().message;
    ASSERT_TRUE(est->observable) << est->reason;
    const double err = est->offset_s - offset;
    std::printf(
        "12 pulses: error %.4f ms, 1-sigma %.4f ms (fit %.4f, jackknife %.4f), %d blocks, %.1f effective, "
        "drift %.2f +- %.2f ppm (fit %.2f)\n",
        err * 1e3, est->offset_sigma_s * 1e3, est->offset_sigma_fit_s * 1e3,
        est->offset_sigma_jackknife_s * 1e3, est->jackknife_blocks, est->effective_blocks, est->drift_ppm,
        est->drift_sigma_ppm, est->drift_sigma_fit_ppm);
    EXPECT_LE(std::abs(err), 2.5 * est->offset_sigma_s);
    // The pulses' scatter shows in the jackknife, beyond what the residuals' 2 s of lags see.
    EXPECT_EQ(est->sigma_source, CameraClockEstimate::SigmaSource::kJackknife);
    EXPECT_GT(est->offset_sigma_jackknife_s, 1.2 * est->offset_sigma_fit_s);
    EXPECT_GE(est->jackknife_refits, 10);
    if (est->drift_observable) {
      EXPECT_LE(std::abs(est->drift_ppm), 2.5 * est->drift_sigma_ppm);
    }
  }
  // The data start in the middle of a pulse: one-sided, so a larger floor.
  {
    const Pulses p{{-2.0, 20.0}, {0.4e-3, -0.2e-3}};
    const auto est = fit_camera_clock(pulse_rotations(p, R, offset, 0, 30), R, rate_of(p));
    ASSERT_TRUE(est) << est.error().message;
    ASSERT_TRUE(est->observable) << est->reason;
    EXPECT_TRUE(est->edge_cut);
    EXPECT_EQ(est->sigma_source, CameraClockEstimate::SigmaSource::kFloor);
    EXPECT_LE(std::abs(est->offset_s - offset), 2.5 * est->offset_sigma_s);
    EXPECT_GT(est->offset_sigma_s, 0.5e-3);
  }
}

TEST(CameraClockFit, NoMotionIsUnobservable) {
  Sines s;
  s.terms.clear();  // constant rate: nothing to align
  const Eigen::Matrix3d R = some_R_cam_body();
  auto rot = exact_rotations(s, R, 0.020, 0, 60);
  // A little measurement noise, as images give.
  std::uint64_t seed = 7;
  sim::Rng rng(seed);
  for (FrameRotation& r : rot) r.rotvec_cam_rad += 1e-5 * rng.normal3();
  const auto est = fit_camera_clock(rot, R, rate_of(s));
  ASSERT_TRUE(est) << est.error().message;
  EXPECT_FALSE(est->observable);
  EXPECT_FALSE(est->reason.empty());
  EXPECT_TRUE(std::isnan(est->offset_s));
}

TEST(CameraClockFit, ClearErrors) {
  const Sines s;
  const Eigen::Matrix3d R = some_R_cam_body();
  auto few = exact_rotations(s, R, 0.0, 0, 0.5);
  auto e = fit_camera_clock(few, R, rate_of(s));
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("nav::estimate_camera_clock(): "), std::string::npos);
  // No rate data where the frames are.
  e = fit_camera_clock(exact_rotations(s, R, 0.0, 0, 10), R,
                       [](TimestampNs) -> std::optional<Eigen::Vector3d> { return std::nullopt; });
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("inside the angular-rate data"), std::string::npos);
}

// ---- frames from a frame index ----------------------------------------------------------------

TEST(CameraClockFrames, OneCameraInTimeOrderReadOnDemand) {
  const std::string dir = std::string(AUGRIG_TEST_OUTPUT_DIR) + "/camera_clock_frames";
  std::filesystem::create_directories(dir + "/left");
  FrameIndex index;
  for (int k = 0; k < 4; ++k) {
    Image img(8, 6, PixelFormat::kMono8);
    for (int y = 0; y < 6; ++y)
      for (int x = 0; x < 8; ++x) img.row(y)[x] = static_cast<std::uint8_t>(10 * k + x);
    const std::string file = "left/" + std::to_string(k) + ".png";
    ASSERT_TRUE(write_png_file(dir + "/" + file, img));
    index.rows.push_back({static_cast<std::uint64_t>(k), 0, 1000 - 100 * k, file});  // stamps decrease with k
    index.rows.push_back({static_cast<std::uint64_t>(k), 1, 5000, "right/missing.png"});
  }
  const auto frames = camera_clock_frames(index, 0, dir, std::nullopt, 2);
  ASSERT_EQ(frames.size(), 2u);  // sequences 0 and 2
  EXPECT_EQ(frames[0].t_camera_ns, 800);
  EXPECT_EQ(frames[1].t_camera_ns, 1000);
  const auto img = frames[0].image();
  ASSERT_TRUE(img) << img.error().message;
  EXPECT_EQ(img->row(0)[1], 21);
  const auto missing = camera_clock_frames(index, 1, dir)[0].image();
  EXPECT_FALSE(missing);
}

// ---- rendered frames ----------------------------------------------------------------------------

struct Rendered {
  double offset_true_s = 0;
  Expected<CameraClockEstimate> est = Error{"not run"};
  double seconds = 0;
};

// `racetrack`: a 45 deg bank racetrack with short legs (three roll-ins or roll-outs in 60 s); else
// straight and level. Camera 0 at 480x360 with a little radial distortion, 20 ms clock offset,
// 20 us jitter, BayerRG8 with noise. Truth rates plus a tactical gyro's noise and bias.
Rendered run_rendered(bool racetrack, double duration_s, int every, bool with_ground) {
  sim::Scenario sc = *sim::builtin_scenario("demo");
  sc.duration_s = duration_s;
  if (racetrack) {
    sc.tanker.pattern = sim::TankerPattern::kRacetrack;
    sc.tanker.speed_mps = 120;
    sc.tanker.bank_rad = deg_to_rad(45);
    sc.tanker.leg_length_m = 600;
    sc.tanker.roll_in_s = 4;
  } else {
    sc.tanker.pattern = sim::TankerPattern::kStraight;
    sc.receiver.turbulence = {};
  }
  for (RigCamera& c : sc.rig.cameras) {
    c.model = CameraModel::pinhole_from_hfov(480, 360, deg_to_rad(56));
    c.model.distortion = DistortionModel::kRadTan;
    c.model.coeffs = {-0.05, 0.01, 0, 0, 0};
  }
  sim::CameraTimingConfig timing = sc.sensors.cameras;
  timing.clock_offset_ns = {20'000'000, 0};
  timing.clock_drift_ppm = {0, 0};
  timing.jitter_ns = 20e3;
  const sim::Flight flight = *sim::Flight::create(sc);
  const auto times = sim::simulate_camera_timing(timing, 1, duration_s, sc.seed, sc.start_gps_ns);
  auto renderer = SyntheticSceneRenderer::create(sc.rig);
  EXPECT_TRUE(renderer) << (renderer ? "" : renderer.error().message);
  Rendered out;
  out.offset_true_s = 0.020;
  if (!renderer) return out;
  SensorOptions sensor;
  sensor.format = PixelFormat::kBayerRG8;
  sensor.noise_sigma = 2.0;

  std::vector<CameraClockFrame> frames;
  for (const sim::CameraFrameTime& ft : times[0]) {
    if (ft.dropped || ft.sequence % static_cast<std::uint64_t>(every) != 0) continue;
    frames.push_back({ft.t_camera_ns, [&, t = ft.t_true_s, seq = ft.sequence]() -> Expected<Image> {
                        Image img;
                        SensorOptions so = sensor;
                        so.noise_seed = seq + 1;
                        const Status st = (*renderer)->render(0, sim::sky_at(sc, flight, t),
                                                              flight.T_tanker_receiver(t), true, so, img);
                        if (!st) return st.error();
                        return img;
                      }});
  }
  // Gyro: truth (w.r.t. the Earth) at 200 Hz plus a tactical gyro's white noise (0.1 deg/sqrt(h))
  // and a 1 deg/h bias, linearly interpolated.
  const double dt = 0.005, t_begin = -1.0;
  const double arw = deg_to_rad(0.1) / 60.0, bias = deg_to_rad(1.0) / 3600.0;
  sim::Rng rng(99);
  std::vector<Eigen::Vector3d> gyro;
  for (double t = t_begin; t <= duration_s + 1.0; t += dt)
    gyro.push_back(flight.tanker(t).w_eb_body_radps + Eigen::Vector3d::Constant(bias) + arw / std::sqrt(dt) * rng.normal3());
  const TimestampNs t0_ns = sc.start_gps_ns;
  AngularRateFunction omega = [&gyro, t0_ns, dt, t_begin](TimestampNs t_ns) -> std::optional<Eigen::Vector3d> {
    const double f = (ns_to_s(t_ns - t0_ns) - t_begin) / dt;
    if (!(f >= 0) || f + 1 >= static_cast<double>(gyro.size())) return std::nullopt;
    const auto i = static_cast<std::size_t>(f);
    const double a = f - static_cast<double>(i);
    return (1 - a) * gyro[i] + a * gyro[i + 1];
  };
  GroundMotionFunction ground = nullptr;
  if (with_ground) {
    ground = [&](TimestampNs t_ns) -> std::optional<GroundMotion> {
      const double t = ns_to_s(t_ns - t0_ns);
      const SkyState sky = sim::sky_at(sc, flight, t);
      const sim::KinematicState k = flight.tanker(t);
      const Geodetic g = geodetic_from_ecef(k.p_ecef_m);
      return GroundMotion{sky.R_ned_body, R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.v_ecef_mps, sky.altitude_m};
    };
  }
  const Eigen::Matrix3d R_cam_body = sc.rig.cameras[0].T_body_cam.R().transpose();
  const auto start = std::chrono::steady_clock::now();
  out.est = estimate_camera_clock(frames, sc.rig.cameras[0].model, R_cam_body, omega, {}, ground);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

void print(const char* what, const Rendered& r) {
  if (!r.est) return;
  const CameraClockEstimate& e = *r.est;
  std::printf(
      "%s: observable %d (%s) offset %.4f ms (error %.4f ms) sigma %.4f ms (fit %.4f, jackknife %.4f, "
      "floor %.4f: %s), drift %.2f +- %.2f ppm (fit %.2f), scale %.5f, rms %.2e rad/s, explained %.4f, "
      "intervals %d of %d frames, %.1f s\n",
      what, e.observable, e.reason.c_str(), e.offset_s * 1e3, (e.offset_s - r.offset_true_s) * 1e3,
      e.offset_sigma_s * 1e3, e.offset_sigma_fit_s * 1e3, e.offset_sigma_jackknife_s * 1e3,
      e.offset_sigma_floor_s * 1e3, describe_sigma(e).c_str(), e.drift_ppm, e.drift_sigma_ppm,
      e.drift_sigma_fit_ppm, e.scale, e.residual_rms_radps, e.explained, e.intervals_used, e.frames,
      r.seconds);
}

TEST(CameraClockRendered, RecoversTwentyMillisecondsWithinOneInSixtySeconds) {
  const Rendered r = run_rendered(true, 60, 2, true);
  ASSERT_TRUE(r.est) << r.est.error().message;
  print("racetrack, parallax removed", r);
  ASSERT_TRUE(r.est->observable) << r.est->reason;
  const double err = r.est->offset_s - r.offset_true_s;
  EXPECT_LE(std::abs(err), 1e-3);
  EXPECT_GT(r.est->offset_sigma_s, 0);
  EXPECT_LE(r.est->offset_sigma_s, 1e-3);
  EXPECT_LE(std::abs(err), 2.5 * r.est->offset_sigma_s);  // the 1-sigma is consistent with the error
  if (r.est->drift_observable) {
    EXPECT_LE(std::abs(r.est->drift_ppm), 2.5 * r.est->drift_sigma_ppm);  // truth 0
  }
}

TEST(CameraClockRendered, StraightAndLevelIsUnobservable) {
  const Rendered r = run_rendered(false, 30, 2, true);
  ASSERT_TRUE(r.est) << r.est.error().message;
  print("straight and level", r);
  EXPECT_FALSE(r.est->observable);
  EXPECT_TRUE(std::isnan(r.est->offset_s));
}

}  // namespace
}  // namespace augrig::nav
