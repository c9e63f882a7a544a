// The moving baseline in the relative navigation: the rover's UBX log read back onto GPS time, and
// on a simulated two-aircraft flight (racetrack turns, approach and contact, turbulence) the
// receiver's position relative to the tanker against the simulator's truth (sim::Flight), with the
// absolute GPS of both aircraft degraded to metres (single point, each wandering on its own) or at
// RTK, with the moving baseline and without.
#include "pipeline/baseline_nav.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "pipeline/flight_nav.hpp"
#include "sim/flight.hpp"
#include "sim/moving_baseline.hpp"
#include "sim/scenario.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

constexpr TimestampNs kWeekNs = 604800LL * 1'000'000'000LL;

void write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

nav::UbxRelPosNed relposned(std::uint32_t itow_ms) {
  nav::UbxRelPosNed m;
  m.itow_ms = itow_ms;
  m.rel_pos_ned_m = {-20.0, 1.0, 8.0};
  m.acc_ned_m = {0.01, 0.01, 0.015};
  m.gnss_fix_ok = m.diff_soln = m.rel_pos_valid = m.is_moving = true;
  m.carr_soln = 2;
  return m;
}

// Times of week become GPS times in the week of the reference, and go on into the next week when
// the log crosses its end; damaged bytes are counted and said, the good frames kept.
TEST(RoverLog, TimesOfWeekResolveAcrossTheWeeksEnd) {
  const std::string dir = test::output_dir("baseline_nav_rover_log");
  const TimestampNs week = 2300 * kWeekNs;
  std::vector<std::uint8_t> bytes;
  for (std::uint32_t ms : {604799000u, 604799800u, 600u, 1400u}) {
    const auto f = nav::encode_nav_relposned(relposned(ms));
    bytes.insert(bytes.end(), f.begin(), f.end());
  }
  bytes.insert(bytes.begin() + 10, {0x00, 0x11});  // garbage inside the first frame: it is lost
  write_bytes(dir + "/rover.ubx", bytes);
  // The reference (the GPS logs' first fix) a little before the log's first epoch.
  auto log = load_rover_log(dir + "/rover.ubx", week + 604790LL * 1'000'000'000LL);
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->measurements.size(), 3u);
  EXPECT_EQ(log->measurements[0].t_ns, week + 604799800LL * 1'000'000);
  EXPECT_EQ(log->measurements[1].t_ns, week + kWeekNs + 600LL * 1'000'000);
  EXPECT_EQ(log->measurements[2].t_ns, week + kWeekNs + 1400LL * 1'000'000);
  EXPECT_EQ(log->counts.bad_checksums, 1u);
  EXPECT_GT(log->counts.skipped_bytes, 0u);
  EXPECT_NE(log->summary().find("3 NAV-RELPOSNED"), std::string::npos) << log->summary();
  EXPECT_NE(log->summary().find("1 bad checksums"), std::string::npos) << log->summary();
  EXPECT_TRUE(log->measurements[0].valid);
  EXPECT_EQ(log->measurements[0].carr_soln, 2);
}

TEST(RoverLog, ALogWithoutBaselinesOrNotUbxIsAnErrorNamingTheFile) {
  const std::string dir = test::output_dir("baseline_nav_rover_log_bad");
  write_bytes(dir + "/pvt.ubx", nav::encode_nav_pvt(nav::UbxNavPvt{}));
  auto a = load_rover_log(dir + "/pvt.ubx", 0);
  ASSERT_FALSE(a);
  EXPECT_NE(a.error().message.find(dir + "/pvt.ubx: no NAV-RELPOSNED"), std::string::npos) << a.error().message;
  write_bytes(dir + "/text.ubx", {'h', 'e', 'l', 'l', 'o', '\n'});
  auto b = load_rover_log(dir + "/text.ubx", 0);
  ASSERT_FALSE(b);
  EXPECT_NE(b.error().message.find("text.ubx"), std::string::npos) << b.error().message;
  auto c = load_rover_log(dir + "/missing.ubx", 0);
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("missing.ubx"), std::string::npos) << c.error().message;
}

// A racetrack with a turn, approach, contact and disconnect in turbulence; both aircraft with a
// tactical IMU. `absolute`: "single" (white 0.4/0.7 m, and each receiver's own error wandering
// by 1/1.6 m over two minutes, on top of the common error) or "rtk" (1/2 cm).
sim::Scenario scenario(const std::string& absolute) {
  const bool single = absolute == "single";
  const std::string gps_noise =
      single ? "mode: single, sigma_horizontal_m: 0.4, sigma_vertical_m: 0.7, "
               "own_error: {sigma_horizontal_m: 1.0, sigma_vertical_m: 1.6, tau_s: 120}"
             : "mode: rtk, sigma_horizontal_m: 0.01, sigma_vertical_m: 0.02";
  const std::string text = R"(augrig_scenario: 1
name: moving-baseline
duration_s: 100
seed: 11
start: {utc: "2024-06-01T12:00:00Z", lat_deg: 51.0, lon_deg: -1.0, alt_m: 7000}
rig: paper_default
tanker: {pattern: racetrack, heading_deg: 90, speed_mps: 170, bank_deg: 25, leg_length_m: 4000, turn: right,
         roll_in_s: 5, angle_of_attack_deg: 3}
receiver:
  contact: {elevation_deg: 30, azimuth_deg: 0, extension_m: 3.5}
  phases:
    - {name: observation, duration_s: 15, offset_m: [-30, 2, 12]}
    - {name: to-pre-contact, duration_s: 15, offset_m: [-15, 0, 4]}
    - {name: pre-contact, duration_s: 10}
    - {name: to-contact, duration_s: 15, offset_m: [0, 0, 0]}
    - {name: contact, duration_s: 30, attached: true}
    - {name: disconnect, duration_s: 15, offset_m: [-3, 0, 1.5]}
  turbulence: {sigma_m: [0.2, 0.15, 0.2], sigma_deg: [0.5, 0.4, 0.4], length_scale_m: 500}
sensors:
  tanker:
    imu: {preset: tactical, rate_hz: 200}
    gps: {rate_hz: 10, lever_arm_m: [5.0, 0.0, -3.5], latency_s: 0.03, heading: true, )" +
                           gps_noise + R"(}
  receiver:
    imu: {preset: tactical, rate_hz: 200}
    gps: {rate_hz: 10, lever_arm_m: [1.0, 0.0, -1.2], latency_s: 0.03, )" +
                           gps_noise + R"(}
  common_gps_error: {sigma_horizontal_m: 0.5, sigma_vertical_m: 1.0, tau_s: 600}
  moving_baseline: {rate_hz: 5, outages: [[70, 74]]}
  cameras: {fps: 30}
)";
  auto s = sim::parse_scenario(text, "<moving-baseline test>");
  EXPECT_TRUE(s) << s.error().message;
  return *s;
}

struct RelativeErrors {
  double rms_m = 0, max_m = 0;  // receiver body origin relative to the tanker's, ECEF, 3D
  double within_1sigma = 0;     // share of epochs whose 3D error is inside the reported 3D sigma
  std::size_t epochs = 0, corrected = 0;
};

// Relative position error at 30 Hz from 5 s on (the filters' start-up), with the moving baseline
// (when given) correcting the two solutions.
RelativeErrors relative_errors(const sim::Scenario& sc, const sim::Flight& flight, const nav::NavTrajectory& tk,
                               const nav::NavTrajectory& rx, const BaselineNav* baseline) {
  RelativeErrors e;
  double sq = 0;
  std::size_t inside = 0;
  for (double t = 5.0; t <= sc.duration_s - 1.0; t += 1.0 / 30) {
    const TimestampNs t_ns = sc.start_gps_ns + static_cast<TimestampNs>(std::llround(t * 1e9));
    auto a = tk.at(t_ns);
    auto b = rx.at(t_ns);
    if (!a || !b) continue;
    if (baseline && baseline->correct(t_ns, *a, *b)) ++e.corrected;
    const sim::KinematicState ta = flight.tanker(t), tb = flight.receiver(t);
    const Eigen::Vector3d err = (b->p_ecef_m - a->p_ecef_m) - (tb.p_ecef_m - ta.p_ecef_m);
    const Eigen::Matrix3d P = a->P.block<3, 3>(nav::kErrPos, nav::kErrPos) + b->P.block<3, 3>(nav::kErrPos, nav::kErrPos);
    sq += err.squaredNorm();
    e.max_m = std::max(e.max_m, err.norm());
    inside += err.norm() <= std::sqrt(P.trace()) ? 1 : 0;
    ++e.epochs;
  }
  e.rms_m = std::sqrt(sq / static_cast<double>(e.epochs));
  e.within_1sigma = static_cast<double>(inside) / static_cast<double>(e.epochs);
  return e;
}

struct Flown {
  RelativeErrors without, with;
  nav::BaselineFusionReport report;
};

// Simulates the flight, writes the rover's log and reads it back, fuses both aircraft and the
// baseline, and measures the relative position without and with it.
Flown fly(const std::string& absolute) {
  const sim::Scenario sc = scenario(absolute);
  const sim::Flight flight = *sim::Flight::create(sc);
  const sim::SensorLogs logs = sim::simulate_sensors(sc, flight);
  const std::string dir = test::output_dir("baseline_nav_" + absolute);
  EXPECT_TRUE(sim::write_relposned_ubx(dir + "/rover.ubx", sim::simulate_moving_baseline(sc, flight)));
  auto rover = load_rover_log(dir + "/rover.ubx", logs.receiver_gps.front().t_ns);
  EXPECT_TRUE(rover) << rover.error().message;
  const nav::InsConfig tk_cfg = ins_config_for(sc.sensors.tanker), rx_cfg = ins_config_for(sc.sensors.receiver);
  auto tk = nav::fuse(logs.tanker_imu, logs.tanker_gps, tk_cfg);
  auto rx = nav::fuse(logs.receiver_imu, logs.receiver_gps, rx_cfg);
  EXPECT_TRUE(tk && rx);
  auto baseline = BaselineNav::fuse(rover->measurements, *tk, *rx, tk_cfg.lever_arm_body_m, rx_cfg.lever_arm_body_m);
  EXPECT_TRUE(baseline) << baseline.error().message;
  Flown f;
  f.without = relative_errors(sc, flight, *tk, *rx, nullptr);
  f.with = relative_errors(sc, flight, *tk, *rx, &*baseline);
  f.report = baseline->report();
  std::printf("%s GPS: relative position without the baseline %.1f mm RMS (max %.1f, %.0f %% within 1 sigma); "
              "with it %.1f mm RMS (max %.1f, %.0f %% within 1 sigma), %zu of %zu epochs corrected\n  %s\n",
              absolute.c_str(), 1e3 * f.without.rms_m, 1e3 * f.without.max_m, 100 * f.without.within_1sigma,
              1e3 * f.with.rms_m, 1e3 * f.with.max_m, 100 * f.with.within_1sigma, f.with.corrected, f.with.epochs,
              f.report.summary().c_str());
  return f;
}

// The issue's goal: with the baseline at 1 cm and the absolute GPS of both aircraft metres off,
// the relative position within 1.5 cm RMS; with RTK as well, better than either alone.
TEST(BaselineNav, CentimetreRelativePositionFromMetresOffAbsoluteGps) {
  const Flown single = fly("single");
  EXPECT_GT(single.without.rms_m, 1.0) << "the absolute GPS alone is metres off";
  EXPECT_LT(single.with.rms_m, 0.015);
  EXPECT_EQ(single.with.corrected, single.with.epochs) << "the 4 s outage is bridged";
  EXPECT_GT(single.with.within_1sigma, 0.5) << "the sigma reported with the baseline is honest";
  EXPECT_GT(single.report.sigma_scale, 3.0)
      << "the single-point solutions' sigma (white noise averaged) is seen to be optimistic";

  const Flown rtk = fly("rtk");
  EXPECT_LT(rtk.with.rms_m, rtk.without.rms_m) << "both: better than RTK alone";
  EXPECT_LT(rtk.with.rms_m, single.with.rms_m) << "both: better than the baseline alone";
  EXPECT_LE(rtk.report.sigma_scale, 2.0) << "RTK solutions' sigma holds";
  EXPECT_GT(rtk.with.within_1sigma, 0.5) << "the sigma reported with both is honest";
}

// The moving-baseline antennas need not be the GPS antennas (aircraft.yaml
// moving_baseline_antenna_m): fused with the antennas the vectors join, the relative position is
// right; with the GPS antennas instead it is off by the difference.
TEST(BaselineNav, ItsOwnAntennasWhereTheyAreNotTheGpsAntennas) {
  const sim::Scenario sc = scenario("rtk");
  const sim::Flight flight = *sim::Flight::create(sc);
  const sim::SensorLogs logs = sim::simulate_sensors(sc, flight);
  sim::MovingBaselineConfig mb = *sc.sensors.moving_baseline;
  mb.base_lever_arm_m = Eigen::Vector3d(-8.0, 1.0, 1.5);   // the tanker's base antenna: aft and below
  mb.rover_lever_arm_m = Eigen::Vector3d(3.0, -0.5, -1.0);  // the receiver's rover antenna: forward
  sim::MovingBaselineSimulator simulator(mb, 21, sc.start_gps_ns);
  const auto epochs = simulator.generate([&](double t) { return flight.tanker(t); },
                                         [&](double t) { return flight.receiver(t); }, sc.duration_s);
  std::vector<nav::BaselineMeasurement> ms;
  for (const sim::MovingBaselineEpoch& e : epochs)
    ms.push_back({e.t_gps_ns, e.arrival_ns, e.message.rel_pos_ned_m, e.message.acc_ned_m, e.message.carr_soln,
                  e.message.rel_pos_valid});
  nav::InsConfig tk_cfg = ins_config_for(sc.sensors.tanker), rx_cfg = ins_config_for(sc.sensors.receiver);
  auto tk = nav::fuse(logs.tanker_imu, logs.tanker_gps, tk_cfg);
  auto rx = nav::fuse(logs.receiver_imu, logs.receiver_gps, rx_cfg);
  ASSERT_TRUE(tk && rx);
  tk_cfg.baseline_antenna_body_m = mb.base_lever_arm_m;
  rx_cfg.baseline_antenna_body_m = mb.rover_lever_arm_m;
  auto own = BaselineNav::fuse(ms, *tk, *rx, tk_cfg.baseline_antenna(), rx_cfg.baseline_antenna());
  auto gps = BaselineNav::fuse(ms, *tk, *rx, tk_cfg.lever_arm_body_m, rx_cfg.lever_arm_body_m);
  ASSERT_TRUE(own && gps);
  const RelativeErrors with_own = relative_errors(sc, flight, *tk, *rx, &*own);
  const RelativeErrors with_gps = relative_errors(sc, flight, *tk, *rx, &*gps);
  std::printf("own antennas %.1f mm RMS; the GPS antennas instead %.1f mm\n", 1e3 * with_own.rms_m,
              1e3 * with_gps.rms_m);
  EXPECT_LT(with_own.rms_m, 0.006);
  EXPECT_GT(with_gps.rms_m, 0.02) << "the vectors measure other antennas";
}

}  // namespace
}  // namespace augrig::pipeline
