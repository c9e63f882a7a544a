// The online camera clocks of `augrig run --camera-clock online`: a simulated flight whose cameras'
// clocks are off by known amounts (+3.7 ms, and -2.4 ms drifting -3 ppm) is rendered frame by frame
// into the online estimator, with the truth's gyro rates (plus a tactical gyro's noise) as the live
// nav would give them. Within 60 s of manoeuvring each offset is within 1 ms, inside 3 of its
// reported 1-sigmas, and nothing is applied before that 1-sigma is below the threshold. Straight and
// level, it stays "not observable" and applies nothing. The worker never blocks the caller.
#include "pipeline/camera_clock_online.hpp"

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/synthetic_scene.hpp"

namespace augrig::pipeline {
namespace {

constexpr std::array<std::int64_t, 2> kOffsetNs = {3'700'000, -2'400'000};
constexpr std::array<double, 2> kDriftPpm = {0, -3};

struct FlightRun {
  sim::Scenario sc;
  std::unique_ptr<sim::Flight> flight;
  std::vector<std::vector<sim::CameraFrameTime>> times;
};

// The demo scenario, at 480x360 with a little radial distortion: a 45 deg bank racetrack with
// short legs (roll-ins and roll-outs within the minute), or straight and level without turbulence.
FlightRun make_flight(bool racetrack, double duration_s) {
  FlightRun f;
  f.sc = *sim::builtin_scenario("demo");
  f.sc.duration_s = duration_s;
  if (racetrack) {
    f.sc.tanker.pattern = sim::TankerPattern::kRacetrack;
    f.sc.tanker.speed_mps = 120;
    f.sc.tanker.bank_rad = deg_to_rad(45);
    f.sc.tanker.leg_length_m = 600;
    f.sc.tanker.roll_in_s = 4;
  } else {
    f.sc.tanker.pattern = sim::TankerPattern::kStraight;
    f.sc.receiver.turbulence = {};
  }
  for (RigCamera& c : f.sc.rig.cameras) {
    c.model = CameraModel::pinhole_from_hfov(480, 360, deg_to_rad(56));
    c.model.distortion = DistortionModel::kRadTan;
    c.model.coeffs = {-0.05, 0.01, 0, 0, 0};
  }
  sim::CameraTimingConfig timing = f.sc.sensors.cameras;
  timing.clock_offset_ns = {kOffsetNs[0], kOffsetNs[1]};
  timing.clock_drift_ppm = {kDriftPpm[0], kDriftPpm[1]};
  timing.jitter_ns = 20e3;
  f.flight = std::make_unique<sim::Flight>(*sim::Flight::create(f.sc));
  f.times = sim::simulate_camera_timing(timing, 2, duration_s, f.sc.seed, f.sc.start_gps_ns);
  return f;
}

// The truth's rate w.r.t. the Earth at 200 Hz with a tactical gyro's noise (0.1 deg/sqrt(h)) and a
// 1 deg/h bias, as gyro increments stamped at their ends on GPS time.
void feed_rates(const FlightRun& f, TankerRates& rates) {
  const double dt = 0.005, arw = deg_to_rad(0.1) / 60.0, bias = deg_to_rad(1.0) / 3600.0;
  sim::Rng rng(99);
  for (double t = -1.0; t <= f.sc.duration_s + 1.0; t += dt) {
    const Eigen::Vector3d w = f.flight->tanker(t - 0.5 * dt).w_eb_body_radps +
                              Eigen::Vector3d::Constant(bias) + arw / std::sqrt(dt) * rng.normal3();
    rates.add_increment(f.sc.start_gps_ns + s_to_ns(t), dt, w * dt);
  }
}

nav::GroundMotionFunction truth_ground(const FlightRun& f) {
  return [&f](TimestampNs t_ns) -> std::optional<nav::GroundMotion> {
    const double t = ns_to_s(t_ns - f.sc.start_gps_ns);
    const SkyState sky = sim::sky_at(f.sc, *f.flight, t);
    const sim::KinematicState k = f.flight->tanker(t);
    const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
    return nav::GroundMotion{sky.R_ned_body, nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.v_ecef_mps,
                             sky.altitude_m};
  };
}

// The true offset (camera time minus GPS time) of camera c at its stamp t_camera_ns.
double true_offset_s(const FlightRun& f, int c, TimestampNs t_camera_ns) {
  const double t_true = ns_to_s(t_camera_ns - f.sc.start_gps_ns - kOffsetNs[static_cast<std::size_t>(c)]);
  return ns_to_s(kOffsetNs[static_cast<std::size_t>(c)]) +
         kDriftPpm[static_cast<std::size_t>(c)] * 1e-6 * t_true;
}

// Per camera, what the estimator said after each of its fits.
struct FitSeen {
  double t_s = 0;  // scenario time of the frame after which it was seen
  CameraClockOnlineStatus status;
  double applied_error_s = 0;  // the applied estimate against the truth at that frame
};

struct Outcome {
  std::array<std::vector<FitSeen>, 2> fits;
  std::array<CameraClockOnlineStatus, 2> last;
  std::array<double, 2> last_error_s{};
  std::array<bool, 2> prior_used_before_applied{true, true};
  double seconds = 0;
};

// Every 2nd frame pair (min_interval_s 0.05 at 30 fps) rendered and offered to both cameras'
// estimators, synchronously (the result then does not depend on this machine's speed).
Outcome run_flight(const FlightRun& f) {
  auto rates = std::make_shared<TankerRates>();
  feed_rates(f, *rates);
  CameraClockOnlineOptions opt;
  opt.synchronous = true;
  std::array<std::unique_ptr<CameraClockOnline>, 2> est;
  for (int c = 0; c < 2; ++c) {
    const RigCamera& rc = f.sc.rig.cameras[static_cast<std::size_t>(c)];
    // The prior: no offset configured (0), as a camera whose clock nobody calibrated.
    est[static_cast<std::size_t>(c)] =
        std::make_unique<CameraClockOnline>(c, c == 0 ? "left" : "right", rc.model,
                                            rc.T_body_cam.R().transpose(), 0, rates, truth_ground(f), opt);
  }
  auto renderer = SyntheticSceneRenderer::create(f.sc.rig);
  EXPECT_TRUE(renderer) << (renderer ? "" : renderer.error().message);
  Outcome out;
  if (!renderer) return out;
  SensorOptions sensor;
  sensor.format = PixelFormat::kBayerRG8;
  sensor.noise_sigma = 2.0;
  const auto start = std::chrono::steady_clock::now();
  Image img;
  for (int c = 0; c < 2; ++c) {
    const auto cs = static_cast<std::size_t>(c);
    for (const sim::CameraFrameTime& ft : f.times[cs]) {
      if (ft.dropped || ft.sequence % 2 != 0) continue;  // every 2nd frame: the decimation's choice
      SensorOptions so = sensor;
      so.noise_seed = ft.sequence * 2 + cs + 1;
      const std::uint64_t fits_before = est[cs]->status().fits;
      const bool applied_before = est[cs]->applied();
      if (!applied_before && est[cs]->offset_ns(ft.t_camera_ns) != 0)
        out.prior_used_before_applied[cs] = false;
      const Status st = (*renderer)->render(c, sim::sky_at(f.sc, *f.flight, ft.t_true_s),
                                            f.flight->T_tanker_receiver(ft.t_true_s), true, so, img);
      EXPECT_TRUE(st) << (st ? "" : st.error().message);
      est[cs]->offer(ft.t_camera_ns, img.cview());
      const CameraClockOnlineStatus s = est[cs]->status();
      if (s.fits == fits_before) continue;
      FitSeen seen{ft.t_true_s, s, 0};
      if (s.applied)
        seen.applied_error_s = s.applied->offset_at_s(ft.t_camera_ns) - true_offset_s(f, c, ft.t_camera_ns);
      out.fits[cs].push_back(seen);
      std::printf("  t %5.1f s %s%s\n", ft.t_true_s, s.text().c_str(),
                  s.applied ? (" error " + std::to_string(seen.applied_error_s * 1e3) + " ms").c_str() : "");
    }
    out.last[cs] = est[cs]->status();
    const TimestampNs t_end = f.times[cs].back().t_camera_ns;
    out.last_error_s[cs] = ns_to_s(est[cs]->offset_ns(t_end)) - true_offset_s(f, c, t_end);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

TEST(CameraClockOnline, ManoeuvringFlightConvergesWithinOneMillisecondInSixtySeconds) {
  const FlightRun f = make_flight(true, 60);
  const Outcome o = run_flight(f);
  std::printf("  %.1f s for both cameras\n", o.seconds);
  for (std::size_t c = 0; c < 2; ++c) {
    SCOPED_TRACE("camera " + std::to_string(c));
    const CameraClockOnlineStatus& s = o.last[c];
    ASSERT_EQ(s.state, CameraClockState::kApplied) << s.text();
    ASSERT_TRUE(s.applied);
    EXPECT_LE(std::abs(o.last_error_s[c]), 1e-3) << s.text();
    // Honest: the true error within 3 of the reported 1-sigmas, at the end and at every fit applied.
    EXPECT_LE(std::abs(o.last_error_s[c]), 3 * s.applied->offset_sigma_s) << s.text();
    EXPECT_TRUE(o.prior_used_before_applied[c]);
    double t_converged = -1;
    for (const FitSeen& seen : o.fits[c]) {
      if (!seen.status.applied) continue;
      // Applied only when confident.
      EXPECT_LE(seen.status.applied->offset_sigma_s, 0.5e-3 + 1e-12);
      EXPECT_LE(std::abs(seen.applied_error_s), 3 * seen.status.applied->offset_sigma_s)
          << seen.status.text();
      if (t_converged < 0 && std::abs(seen.applied_error_s) < 1e-3) t_converged = seen.t_s;
    }
    std::printf(
        "  camera %zu: applied and within 1 ms from t %.1f s; at the end error %+.3f ms, 1-sigma %.3f ms "
        "(%s)\n",
        c, t_converged, o.last_error_s[c] * 1e3, s.applied->offset_sigma_s * 1e3,
        nav::describe_sigma(*s.applied).c_str());
    EXPECT_GE(t_converged, 0);
    EXPECT_GT(s.frames_tracked, 800u);
    EXPECT_EQ(s.frames_skipped_busy, 0u);
  }
}

TEST(CameraClockOnline, StraightAndLevelStaysNotObservableAndAppliesNothing) {
  const FlightRun f = make_flight(false, 30);
  const Outcome o = run_flight(f);
  for (std::size_t c = 0; c < 2; ++c) {
    SCOPED_TRACE("camera " + std::to_string(c));
    const CameraClockOnlineStatus& s = o.last[c];
    EXPECT_EQ(s.state, CameraClockState::kNotObservable) << s.text();
    EXPECT_FALSE(s.applied);
    EXPECT_FALSE(s.reason.empty());
    EXPECT_TRUE(o.prior_used_before_applied[c]);
    EXPECT_GE(s.fits, 4u);
    for (const FitSeen& seen : o.fits[c]) EXPECT_FALSE(seen.status.applied) << seen.status.text();
    EXPECT_NE(s.text().find("not observable"), std::string::npos) << s.text();
  }
}

// ---- without rendering --------------------------------------------------------------------------

TEST(CameraClockOnline, NeverBlocksTheCallerAndCountsWhatItSkips) {
  // No rates ever arrive: each frame waits for them (rate_wait_s) and the queue of 2 fills.
  auto rates = std::make_shared<TankerRates>();
  CameraClockOnlineOptions opt;
  opt.queue_frames = 2;
  opt.rate_wait_s = 0.3;
  const CameraModel model = CameraModel::pinhole_from_hfov(160, 120, deg_to_rad(56));
  CameraClockOnline est(0, "left", model, Eigen::Matrix3d::Identity(), 1'000'000, rates, nullptr, opt);
  Image img(160, 120, PixelFormat::kMono8);
  const auto t0 = std::chrono::steady_clock::now();
  int taken = 0;
  for (int k = 0; k < 10; ++k) taken += est.offer(1'000'000'000 + k * 100'000'000LL, img.cview());
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(s, 0.25);  // ten offers, none waited for the worker
  const CameraClockOnlineStatus st = est.status();
  EXPECT_EQ(st.frames_offered, 10u);
  EXPECT_EQ(static_cast<std::uint64_t>(taken), st.frames_taken);
  EXPECT_EQ(st.frames_taken + st.frames_skipped_busy, 10u);
  EXPECT_GE(st.frames_skipped_busy, 6u);
  // Decimation: a frame closer than min_interval_s to the last taken is passed over, not counted as skipped.
  est.wait_idle();
  EXPECT_TRUE(est.offer(3'000'000'000, img.cview()));
  EXPECT_FALSE(est.offer(3'010'000'000, img.cview()));
  est.wait_idle();
  EXPECT_EQ(est.status().frames_skipped_busy, st.frames_skipped_busy);
  // Nothing applied: the prior is the offset.
  EXPECT_FALSE(est.applied());
  EXPECT_EQ(est.offset_ns(5'000'000'000), 1'000'000);
  EXPECT_EQ(est.status().state, CameraClockState::kCollecting);
}

TEST(TankerRates, IncrementsAtTheirMiddleInterpolatedAndGapsUnknown) {
  TankerRates r;
  r.add_increment(1'010'000'000, 0.01, Eigen::Vector3d(0.01, 0, 0));  // 1 rad/s at 1.005 s
  r.add_increment(1'020'000'000, 0.01, Eigen::Vector3d(0.03, 0, 0));  // 3 rad/s at 1.015 s
  r.add_increment(1'200'000'000, 0.01, Eigen::Vector3d(0.05, 0, 0));  // after a 180 ms gap
  r.add_increment(1'190'000'000, 0.01, Eigen::Vector3d(0.05, 0, 0));  // out of order: refused
  ASSERT_TRUE(r.at(1'010'000'000));
  EXPECT_NEAR(r.at(1'010'000'000)->x(), 2.0, 1e-9);
  EXPECT_FALSE(r.at(1'100'000'000));  // inside the gap
  EXPECT_FALSE(r.at(1'000'000'000));  // before the first
  EXPECT_EQ(r.newest_ns(), 1'195'000'000);
  const nav::AngularRateFunction snap = r.snapshot(1'006'000'000, 1'014'000'000);
  r.add_increment(1'210'000'000, 0.01, Eigen::Vector3d(0.07, 0, 0));
  ASSERT_TRUE(snap(1'010'000'000));
  EXPECT_NEAR(snap(1'010'000'000)->x(), 2.0, 1e-9);
}

TEST(CameraClocks, HostTimedFramesWaitForTheNavClockAndDiagnosticsNameEveryCamera) {
  const Rig rig = Rig::paper_default();
  std::optional<TimestampNs> nav_clock;
  CameraClocks clocks(
      rig, {},
      [&](TimestampNs h) -> std::optional<TimestampNs> {
        return nav_clock ? std::optional<TimestampNs>(h - *nav_clock) : std::nullopt;
      },
      nullptr);
  EXPECT_TRUE(clocks.host_timed());
  StereoFrame f;
  f.left.image = Image(rig.cameras[0].model.width_px, rig.cameras[0].model.height_px, PixelFormat::kMono8);
  f.right.image = Image(rig.cameras[1].model.width_px, rig.cameras[1].model.height_px, PixelFormat::kMono8);
  clocks.offer(f, 5'000'000'000, 5'000'100'000);
  std::vector<CameraClockOnlineStatus> st = clocks.status();
  ASSERT_EQ(st.size(), 2u);
  EXPECT_EQ(st[0].frames_offered, 0u);
  EXPECT_NE(st[0].text().find("no frame with a nav clock yet"), std::string::npos) << st[0].text();
  nav_clock = 40'000'000;  // the GPS receiver's output latency, as host_to_nav() leaves it
  clocks.offer(f, 5'100'000'000, 5'100'100'000);
  clocks.wait_idle();
  st = clocks.status();
  EXPECT_EQ(st[0].frames_offered, 1u);
  EXPECT_NEAR(st[0].prior_offset_s, 0.040, 1e-12);
  EXPECT_FALSE(clocks.to_gps(0, 5'100'000'000));  // nothing applied: the caller maps as before
  const auto kv = clocks.diagnostics();
  auto value = [&](const std::string& k) {
    for (const auto& [key, v] : kv)
      if (key == k) return v;
    return std::string("(missing)");
  };
  EXPECT_EQ(value("camera0_clock_applied"), "0");
  EXPECT_EQ(value("camera1_clock_state"), "collecting");
  EXPECT_EQ(value("camera0_clock_offset_ms"), "nan");
  EXPECT_EQ(st[1].hud_text(),
            "right  collecting: until the first fit, after 5 s of frames; prior +40.000 ms");
  EXPECT_EQ(value("camera1_clock_prior_offset_ms"), "40.0000");
  EXPECT_NE(value("camera0_clock_sigma_ms"), "(missing)");
}

}  // namespace
}  // namespace augrig::pipeline
