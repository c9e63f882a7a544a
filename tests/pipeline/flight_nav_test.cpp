// Flight nav on simulated flights: the accuracy the issue asks for, end to end from the simulator's
// logs (written and read back in their real formats) through nav::fuse() to the receiver's pose in
// the tanker body frame and each camera. Truth comes from sim::Flight, an independent analytic model.
#include "pipeline/flight_nav.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

#include <gtest/gtest.h>

#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

struct Errors {
  double rel_pos_rms_m = 0, rel_pos_max_m = 0;  // receiver origin relative to the tanker's, ECEF
  double body_pos_rms_m = 0;                    // ... in the tanker body frame (attitude errors included)
  double att_max_deg = 0;                       // relative attitude
  double cam_pos_rms_m = 0;                     // receiver in the left camera
  double baseline_rel_pos_rms_m = 0;            // GPS fixes interpolated, lever arms removed with truth
  std::size_t frames = 0;
  double t_max_s = 0;  // when the largest relative position error occurred
};

// Linear interpolation of one aircraft's antenna fixes to t, lever arm removed with the true attitude
// (which favours the baseline): what a system without an INS would have.
Eigen::Vector3d interpolated_origin(const std::vector<nav::GpsFix>& fixes, TimestampNs t,
                                    const Eigen::Vector3d& lever_arm,
                                    const Eigen::Matrix3d& R_ecef_body_true) {
  auto it = std::lower_bound(fixes.begin(), fixes.end(), t,
                             [](const nav::GpsFix& f, TimestampNs x) { return f.t_ns < x; });
  if (it == fixes.begin()) it = fixes.begin() + 1;
  if (it == fixes.end()) it = fixes.end() - 1;
  const nav::GpsFix& b = *it;
  const nav::GpsFix& a = *(it - 1);
  const double w = static_cast<double>(t - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  const Eigen::Vector3d pa = nav::ecef_from_geodetic(a.antenna), pb = nav::ecef_from_geodetic(b.antenna);
  return pa + w * (pb - pa) - R_ecef_body_true * lever_arm;
}

// Simulates `name`, writes and reads back its logs, fuses both aircraft and measures the relative pose
// at every camera frame after `skip_s` (the filter's start-up).
Errors fly(sim::Scenario scenario, const std::string& tag, double skip_s, TimestampNs gps_offset_ns = 0,
           bool configure_offset = false) {
  const sim::Flight flight = *sim::Flight::create(scenario);
  sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
  // A stream clock error: GPS time tags late by gps_offset_ns (the fixes say t + offset).
  for (auto* fixes : {&logs.tanker_gps, &logs.receiver_gps})
    for (nav::GpsFix& f : *fixes) f.t_ns += gps_offset_ns;
  const std::string dir = test::output_dir("flight_nav_" + tag);
  nav::InsConfig tk_cfg = ins_config_for(scenario.sensors.tanker);
  nav::InsConfig rx_cfg = ins_config_for(scenario.sensors.receiver);
  if (configure_offset) tk_cfg.gps_time_offset_ns = rx_cfg.gps_time_offset_ns = -gps_offset_ns;
  EXPECT_TRUE(write_aircraft_logs(dir + "/tanker", logs.tanker_imu, logs.tanker_gps, tk_cfg));
  EXPECT_TRUE(write_aircraft_logs(dir + "/receiver", logs.receiver_imu, logs.receiver_gps, rx_cfg));
  auto tk = load_aircraft_logs(dir + "/tanker");
  auto rx = load_aircraft_logs(dir + "/receiver");
  EXPECT_TRUE(tk && rx);
  auto tk_nav = nav::fuse(tk->imu, tk->gps, tk->config);
  auto rx_nav = nav::fuse(rx->imu, rx->gps, rx->config);
  EXPECT_TRUE(tk_nav && rx_nav);
  std::vector<TimestampNs> offsets = scenario.sensors.cameras.clock_offset_ns;
  offsets.resize(2, 0);
  const RelativeNav rel(*tk_nav, *rx_nav, scenario.rig, scenario.boom, flight.receptacle_m(), offsets);

  Errors e;
  double s_rel = 0, s_body = 0, s_cam = 0, s_base = 0;
  for (const sim::FrameTruth& t : sim::frame_truths(scenario, flight, logs.cameras)) {
    if (t.camera != 0 || t.t_true_s < skip_s) continue;
    auto p = rel.at(0, t.t_camera_ns);
    if (!p) continue;
    const sim::KinematicState tk_true = flight.tanker(t.t_true_s), rx_true = flight.receiver(t.t_true_s);
    auto tk_est = rel.tanker().at(p->t_nav_ns);
    auto rx_est = rel.receiver().at(p->t_nav_ns);
    const Eigen::Vector3d d_true = rx_true.p_ecef_m - tk_true.p_ecef_m;
    const double d_rel = ((rx_est->p_ecef_m - tk_est->p_ecef_m) - d_true).norm();
    const double d_body = (p->body.T_a_receiver.translation_m - t.T_body_receiver.translation_m).norm();
    const double d_cam = (p->camera.T_a_receiver.translation_m - t.T_cam_receiver.translation_m).norm();
    const double d_att =
        rad_to_deg(p->body.T_a_receiver.rotation.angularDistance(t.T_body_receiver.rotation));
    const TimestampNs t_fix = t.t_gps_ns + gps_offset_ns;  // the baseline sees the same clock error
    const Eigen::Vector3d base =
        interpolated_origin(logs.receiver_gps, t_fix, scenario.sensors.receiver.gps.lever_arm_m,
                            rx_true.R_ecef_body()) -
        interpolated_origin(logs.tanker_gps, t_fix, scenario.sensors.tanker.gps.lever_arm_m,
                            tk_true.R_ecef_body());
    const double d_base = (base - d_true).norm();
    ++e.frames;
    s_rel += d_rel * d_rel, s_body += d_body * d_body, s_cam += d_cam * d_cam, s_base += d_base * d_base;
    if (d_rel > e.rel_pos_max_m) e.rel_pos_max_m = d_rel, e.t_max_s = t.t_true_s;
    e.att_max_deg = std::max(e.att_max_deg, d_att);
  }
  const double n = std::max<std::size_t>(e.frames, 1);
  e.rel_pos_rms_m = std::sqrt(s_rel / n), e.body_pos_rms_m = std::sqrt(s_body / n);
  e.cam_pos_rms_m = std::sqrt(s_cam / n), e.baseline_rel_pos_rms_m = std::sqrt(s_base / n);
  std::printf(
      "[%s] %zu frames: relative position RMS %.2f mm (max %.2f mm at %.1f s), in the tanker body %.2f mm, "
      "in the "
      "left camera %.2f mm; relative attitude max %.5f deg; GPS-interpolation baseline %.2f mm\n",
      tag.c_str(), e.frames, 1e3 * e.rel_pos_rms_m, 1e3 * e.rel_pos_max_m, e.t_max_s, 1e3 * e.body_pos_rms_m,
      1e3 * e.cam_pos_rms_m, e.att_max_deg, 1e3 * e.baseline_rel_pos_rms_m);
  return e;
}

TEST(FlightNav, NoiseFreeTenMinuteFlightIsExactToAMillimetre) {
  const Errors e = fly(*sim::builtin_scenario("contact-10min-noise-free"), "noise_free", 60.0);
  ASSERT_GT(e.frames, 15000u);
  EXPECT_LE(e.rel_pos_max_m, 1e-3);
  EXPECT_LE(e.body_pos_rms_m, 1e-3);
  EXPECT_LE(e.att_max_deg, 1e-3);
}

TEST(FlightNav, RtkAndTacticalImuBeatGpsInterpolationByHalf) {
  const Errors e = fly(*sim::builtin_scenario("contact-10min"), "rtk_tactical", 30.0);
  ASSERT_GT(e.frames, 15000u);
  EXPECT_LE(e.rel_pos_rms_m, 0.03);
  EXPECT_LE(e.rel_pos_rms_m, 0.5 * e.baseline_rel_pos_rms_m);
}

TEST(FlightNav, TenMillisecondGpsClockOffsetShowsAndVanishesWhenConfigured) {
  sim::Scenario s = *sim::builtin_scenario("demo-noise-free");
  const Errors clean = fly(s, "offset_none", 5.0);
  const Errors wrong = fly(s, "offset_uncorrected", 5.0, 10'000'000, false);
  const Errors fixed = fly(s, "offset_configured", 5.0, 10'000'000, true);
  // 10 ms at 160 m/s puts each fix 1.6 m along track; the two aircraft share the error, so what is
  // left in the relative pose comes from their different motion and attitudes, still far above 1 mm.
  EXPECT_GT(wrong.body_pos_rms_m, 20 * clean.body_pos_rms_m);
  EXPECT_GT(wrong.body_pos_rms_m, 5e-3);
  EXPECT_LE(fixed.body_pos_rms_m, 1.5 * clean.body_pos_rms_m + 1e-4);
}

// A folder named aircraft.yaml used to read as an empty file (the defaults, exit 0).
TEST(FlightNav, AircraftYamlThatIsADirectoryIsAnError) {
  const std::string dir = test::output_dir("flight_nav_yaml_dir");
  std::filesystem::create_directories(dir + "/aircraft.yaml");
  auto cfg = load_aircraft_config(dir + "/aircraft.yaml");
  ASSERT_FALSE(cfg);
  EXPECT_EQ(cfg.error().message,
            "aircraft::load(): " + dir + "/aircraft.yaml: is a directory, expected a file");
  auto logs = load_aircraft_logs(dir);  // aircraft.yaml is read first (it may give the leap seconds)
  ASSERT_FALSE(logs);
  EXPECT_NE(logs.error().message.find("aircraft.yaml: is a directory, expected a file"), std::string::npos)
      << logs.error().message;
  std::filesystem::remove(dir + "/aircraft.yaml");
  std::ofstream(dir + "/aircraft.yaml") << "lever_arm_m: [0, 0, -1]\n";
  std::filesystem::create_directories(dir + "/gps.nmea");
  logs = load_aircraft_logs(dir);
  ASSERT_FALSE(logs);
  EXPECT_NE(logs.error().message.find("gps.nmea: is a directory, expected a file"), std::string::npos)
      << logs.error().message;
}

TEST(FlightNav, AircraftConfigRoundTripAndErrors) {
  nav::InsConfig c;
  c.lever_arm_body_m = {5, -0.25, -3.5};
  c.gps_time_offset_ns = -12345;
  c.use_heading = false;
  auto back = parse_aircraft_config(aircraft_config_to_yaml(c), "<test>");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->lever_arm_body_m, c.lever_arm_body_m);
  EXPECT_EQ(back->gps_time_offset_ns, -12345);
  EXPECT_FALSE(back->use_heading);
  EXPECT_NEAR(back->imu.gyro_arw_rad_psqrts, c.imu.gyro_arw_rad_psqrts, 1e-15);
  const std::pair<const char*, const char*> bad[] = {
      {"lever_arm: [1, 2, 3]\n", "<bad>:1:1: key 'lever_arm'"},
      {"lever_arm_m: [1, 2]\n", "key 'lever_arm_m'"},
      {"imu: {gyro_arw_deg_per_sqrt_h: -1}\n", "key 'imu.gyro_arw_deg_per_sqrt_h': expected a number >= 0"},
      {"heading: {use: maybe}\n", "key 'heading.use'"},
      {"gps: [1, 2]\n", "key 'gps'"},
  };
  for (const auto& [text, expect] : bad) {
    auto r = parse_aircraft_config(text, "<bad>");
    ASSERT_FALSE(r) << text;
    EXPECT_NE(r.error().message.find(expect), std::string::npos) << r.error().message;
  }
  // Values beyond their documented ranges: 1e30 ns used to wrap around in the cast to int64.
  const std::pair<const char*, const char*> out_of_range[] = {
      {"imu_time_offset_ns: 1e30\n",
       "<bad>:1:21: key 'imu_time_offset_ns': expected a time offset in -5e17..5e17"},
      {"gps_time_offset_ns: -6e17\n", "<bad>:1:21: key 'gps_time_offset_ns': expected a time offset in"},
      {"lever_arm_m: [0, 1e300, 0]\n", "key 'lever_arm_m': expected each component within +-1000 m"},
      {"imu: {gyro_bias_deg_per_h: 1e300}\n", "key 'imu.gyro_bias_deg_per_h': expected a number >= 0 and <="},
      {"gps: {rtk_float_m: 1e300}\n", "key 'gps.rtk_float_m': expected a sigma >= 0 m and <="},
      {"heading: {offset_deg: 1e300}\n",
       "key 'heading.offset_deg': expected an angle in degrees within +-360"},
  };
  for (const auto& [text, expect] : out_of_range) {
    auto r = parse_aircraft_config(text, "<bad>");
    ASSERT_FALSE(r) << text;
    EXPECT_NE(r.error().message.find(expect), std::string::npos) << r.error().message;
  }
  // The moving-baseline antenna: the GPS antenna unless given; written back when given; bounded.
  EXPECT_FALSE(back->baseline_antenna_body_m);
  EXPECT_EQ(back->baseline_antenna(), c.lever_arm_body_m);
  nav::InsConfig mb = c;
  mb.baseline_antenna_body_m = Eigen::Vector3d(-2.0, 0.5, -1.0);
  auto mb_back = parse_aircraft_config(aircraft_config_to_yaml(mb), "<test>");
  ASSERT_TRUE(mb_back) << mb_back.error().message;
  EXPECT_EQ(mb_back->baseline_antenna(), Eigen::Vector3d(-2.0, 0.5, -1.0));
  EXPECT_EQ(mb_back->lever_arm_body_m, c.lever_arm_body_m);
  auto mb_bad = parse_aircraft_config("moving_baseline_antenna_m: [0, 2000, 0]\n", "<bad>");
  ASSERT_FALSE(mb_bad);
  EXPECT_NE(mb_bad.error().message.find("key 'moving_baseline_antenna_m': expected each component within +-1000 m"),
            std::string::npos)
      << mb_bad.error().message;
  auto edge = parse_aircraft_config("imu_time_offset_ns: -5e17\n", "<ok>");
  ASSERT_TRUE(edge) << edge.error().message;
  EXPECT_EQ(edge->imu_time_offset_ns, -500'000'000'000'000'000);
  // The IMU clock states (imu_clock): written back when set, bounded.
  nav::InsConfig k;
  k.imu_clock.estimate = true;
  k.imu_clock.offset_sigma_s = 0.02;
  k.imu_clock.drift_sigma = 50e-6;
  k.imu_clock.drift_random_walk_psqrts = 1e-8;
  auto kb = parse_aircraft_config(aircraft_config_to_yaml(k), "<test>");
  ASSERT_TRUE(kb) << kb.error().message;
  EXPECT_TRUE(kb->imu_clock.estimate);
  EXPECT_NEAR(kb->imu_clock.offset_sigma_s, 0.02, 1e-15);
  EXPECT_NEAR(kb->imu_clock.drift_sigma, 50e-6, 1e-18);
  EXPECT_NEAR(kb->imu_clock.drift_random_walk_psqrts, 1e-8, 1e-20);
  EXPECT_EQ(aircraft_config_to_yaml(c).find("imu_clock"), std::string::npos);  // not set: not written
  const std::pair<const char*, const char*> bad_clock[] = {
      {"imu_clock: {estimate: true, offset_sigma_ms: 0}\n",
       "<bad>:1:46: key 'imu_clock.offset_sigma_ms': expected a sigma in ms > 0 and <= 10000, got '0'"},
      {"imu_clock: {estimate: yes please}\n", "key 'imu_clock.estimate'"},
      {"imu_clock: {estmate: true}\n", "key 'imu_clock.estmate'"},
      {"imu_clock: {drift_sigma_ppm: -5}\n", "key 'imu_clock.drift_sigma_ppm': expected a sigma in ppm > 0"},
      {"imu_clock: true\n", "key 'imu_clock'"},
  };
  for (const auto& [text, expect] : bad_clock) {
    auto r = parse_aircraft_config(text, "<bad>");
    ASSERT_FALSE(r) << text;
    EXPECT_NE(r.error().message.find(expect), std::string::npos) << r.error().message;
  }
  auto missing = load_aircraft_logs("/nonexistent/tanker");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("/nonexistent/tanker: not a folder"), std::string::npos);
}

// ---- Timing honesty (issue 20 §3) ----------------------------------------------------------------

// Both aircraft fused from `tk` and `rx` (smoothed or forward only) against the simulator's truth at
// every frame; `converging` gets, per compared frame, whether RelativeNav flags it, `t_s` its scenario time.
PoseErrorStats fuse_against_truth(const sim::Scenario& scenario, const sim::Flight& flight,
                                  const sim::SensorLogs& logs, const AircraftLogs& tk, const AircraftLogs& rx,
                                  bool smooth, nav::FusionReport* tk_report = nullptr,
                                  nav::FusionReport* rx_report = nullptr, std::vector<bool>* converging = nullptr,
                                  std::vector<double>* t_s = nullptr, std::vector<bool>* within = nullptr,
                                  double from_s = -1e9) {
  auto tk_nav = nav::fuse(tk.imu, tk.gps, tk.config, smooth);
  auto rx_nav = nav::fuse(rx.imu, rx.gps, rx.config, smooth);
  EXPECT_TRUE(tk_nav && rx_nav);
  if (!tk_nav || !rx_nav) return {};
  if (tk_report) *tk_report = tk_nav->report();
  if (rx_report) *rx_report = rx_nav->report();
  std::vector<TimestampNs> offsets = scenario.sensors.cameras.clock_offset_ns;
  offsets.resize(2, 0);
  const RelativeNav rel(*tk_nav, *rx_nav, scenario.rig, scenario.boom, flight.receptacle_m(), offsets);
  std::vector<nav::CameraPoseRow> est, truth;
  for (const sim::FrameTruth& t : sim::frame_truths(scenario, flight, logs.cameras)) {
    if (t.t_true_s < from_s) continue;
    auto p = rel.at(t.camera, t.t_camera_ns);
    if (!p) continue;
    est.push_back(p->row(t.sequence, t.camera, t.t_camera_ns));
    truth.push_back(sim::pose_row(t));
    if (converging) converging->push_back(rel.converging(p->t_nav_ns));
    if (t_s) t_s->push_back(t.t_true_s);
    if (within) {
      const double d = (p->camera.T_a_receiver.translation_m - t.T_cam_receiver.translation_m).norm();
      within->push_back(d <= p->camera.sigma_position_m());
    }
  }
  return compare_poses(est, truth);
}

sim::Scenario scenario_from(const std::string& builtin, const std::string& utc) {
  sim::Scenario s = *sim::builtin_scenario(builtin);
  s.start_gps_ns = *sim::gps_ns_from_utc(utc);
  return s;
}

// A flight recorded in 2016, when GPS - UTC was 17 s: the simulated receivers write UTC as real
// ones did, and the reader takes the 17 s from the table for the log's date, so the logs fuse to the
// truth. Given 18 s (as every log was read before), each fix is placed 1 s late: metres of error,
// most of the receiver's fixes gated, and a sigma of millimetres. The loader says so naming the file
// and line, and the GPS innovations say the sigma does not hold.
TEST(FlightNav, PreTwentySeventeenLogFusesWithTheLeapSecondsOfItsDate) {
  const sim::Scenario scenario = scenario_from("demo", "2016-06-01T12:00:00Z");
  const sim::Flight flight = *sim::Flight::create(scenario);
  const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
  const std::string dir = test::output_dir("flight_nav_2016");
  ASSERT_TRUE(write_aircraft_logs(dir + "/tanker", logs.tanker_imu, logs.tanker_gps,
                                  ins_config_for(scenario.sensors.tanker)));
  ASSERT_TRUE(write_aircraft_logs(dir + "/receiver", logs.receiver_imu, logs.receiver_gps,
                                  ins_config_for(scenario.sensors.receiver)));
  {
    std::ifstream in(dir + "/tanker/gps.nmea");
    std::string first;
    std::getline(in, first);
    EXPECT_NE(first.find("GNGGA,120000.000,"), std::string::npos) << first;  // scenario time 0 is 12:00:00 UTC
  }
  // Nothing given: the table's 17 s for 2016-06-01.
  auto tk = load_aircraft_logs(dir + "/tanker");
  auto rx = load_aircraft_logs(dir + "/receiver");
  ASSERT_TRUE(tk && rx) << (tk ? rx.error().message : tk.error().message);
  EXPECT_EQ(tk->leap_seconds.applied, (std::map<int, std::size_t>{{17, logs.tanker_gps.size()}}));
  EXPECT_EQ(rx->leap_seconds.from_table, logs.receiver_gps.size());
  EXPECT_TRUE(tk->warnings.empty() && rx->warnings.empty());
  EXPECT_EQ(tk->leap_seconds_source, "");
  for (std::size_t i = 0; i < logs.tanker_gps.size(); ++i) ASSERT_EQ(tk->gps[i].t_ns, logs.tanker_gps[i].t_ns) << i;
  nav::FusionReport tk_rep, rx_rep;
  const PoseErrorStats right = fuse_against_truth(scenario, flight, logs, *tk, *rx, true, &tk_rep, &rx_rep);
  const InnovationCheck right_check = check_innovations("receiver", rx_rep);
  std::printf("[2016, GPS-UTC 17 s from the table] %s\n  %s\n", describe(right).c_str(), right_check.summary.c_str());
  EXPECT_LT(right.pos_rms_m, 0.015);
  EXPECT_TRUE(right_check.judged && right_check.consistent);
  EXPECT_TRUE(check_innovations("tanker", tk_rep).consistent);

  // 18 s given (--leap-seconds): warned with the file and the first fix's line; the fusion is metres off.
  AircraftLoadOptions o18;
  o18.leap_seconds = 18;
  auto tk18 = load_aircraft_logs(dir + "/tanker", o18);
  auto rx18 = load_aircraft_logs(dir + "/receiver", o18);
  ASSERT_TRUE(tk18 && rx18);
  ASSERT_EQ(rx18->warnings.size(), 1u);
  EXPECT_EQ(rx18->warnings[0], dir + "/receiver/gps.nmea:1: GPS-UTC 18 s given, but it was 17 s on 2016-06-01 (the "
                                     "leap-second table): the fix times are 1 s late (" +
                                     std::to_string(logs.receiver_gps.size()) + " of " +
                                     std::to_string(logs.receiver_gps.size()) + " fixes; given by --leap-seconds)");
  const PoseErrorStats wrong = fuse_against_truth(scenario, flight, logs, *tk18, *rx18, true, &tk_rep, &rx_rep);
  const InnovationCheck wrong_check = check_innovations("receiver", rx_rep);
  std::printf("[2016, GPS-UTC 18 s given] %s; receiver fixes %zu used, %zu gated\n  %s\n  %s\n",
              describe(wrong).c_str(), rx_rep.fixes_used, rx_rep.fixes_rejected, wrong_check.summary.c_str(),
              wrong_check.warning.c_str());
  EXPECT_GT(wrong.pos_rms_m, 0.5);
  EXPECT_LT(wrong.within_1sigma, 0.05);
  EXPECT_GT(rx_rep.fixes_rejected, rx_rep.fixes / 2);
  EXPECT_TRUE(wrong_check.judged && wrong_check.optimistic);
  EXPECT_EQ(wrong_check.warning.rfind("receiver: GPS innovations are ", 0), 0u) << wrong_check.warning;
  EXPECT_NE(wrong_check.warning.find("the reported sigma is optimistic; check the lever arm"), std::string::npos);

  // The same from aircraft.yaml; --leap-seconds overrides it, and says so.
  nav::InsConfig cfg = ins_config_for(scenario.sensors.receiver);
  cfg.gps_leap_seconds = 18;
  std::ofstream(dir + "/receiver/aircraft.yaml") << aircraft_config_to_yaml(cfg);
  auto yaml18 = load_aircraft_logs(dir + "/receiver");
  ASSERT_TRUE(yaml18);
  EXPECT_EQ(yaml18->leap_seconds_source, "aircraft.yaml gps_leap_seconds");
  ASSERT_EQ(yaml18->warnings.size(), 1u);
  EXPECT_NE(yaml18->warnings[0].find("gps.nmea:1: GPS-UTC 18 s given, but it was 17 s on 2016-06-01"),
            std::string::npos)
      << yaml18->warnings[0];
  EXPECT_NE(yaml18->warnings[0].find("given by aircraft.yaml gps_leap_seconds"), std::string::npos);
  AircraftLoadOptions o17;
  o17.leap_seconds = 17;
  auto overridden = load_aircraft_logs(dir + "/receiver", o17);
  ASSERT_TRUE(overridden);
  ASSERT_EQ(overridden->warnings.size(), 1u);
  EXPECT_EQ(overridden->warnings[0],
            "--leap-seconds 17 overrides " + dir + "/receiver/aircraft.yaml's gps_leap_seconds 18");
  EXPECT_EQ(overridden->gps[0].t_ns, logs.receiver_gps[0].t_ns);
}

// Without aircraft.yaml the lever arm, noise and offsets are unknown: an error naming the folder and
// the file, unless the defaults are asked for. With them the demo's receiver is metres off (the
// antennas are 1.6 m and 6 m from the IMUs) and no frame lies within the reported sigma.
TEST(FlightNav, MissingAircraftYamlIsAnErrorUnlessTheDefaultsAreAskedFor) {
  const sim::Scenario scenario = *sim::builtin_scenario("demo");
  const sim::Flight flight = *sim::Flight::create(scenario);
  const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
  const std::string dir = test::output_dir("flight_nav_no_yaml");
  for (const char* who : {"tanker", "receiver"}) {
    const bool tanker = std::string(who) == "tanker";
    ASSERT_TRUE(write_aircraft_logs(dir + "/" + who, tanker ? logs.tanker_imu : logs.receiver_imu,
                                    tanker ? logs.tanker_gps : logs.receiver_gps, nav::InsConfig{}));
    fs::remove(dir + "/" + who + "/aircraft.yaml");
  }
  auto missing = load_aircraft_logs(dir + "/tanker");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().message.rfind("aircraft::load_logs(): " + dir + "/tanker: no aircraft.yaml (expected " +
                                              dir + "/tanker/aircraft.yaml: the antenna lever arm",
                                          0),
            0u)
      << missing.error().message;
  EXPECT_NE(missing.error().message.find("--default-aircraft"), std::string::npos);
  AircraftLoadOptions o;
  o.allow_default_config = true;
  auto tk = load_aircraft_logs(dir + "/tanker", o);
  auto rx = load_aircraft_logs(dir + "/receiver", o);
  ASSERT_TRUE(tk && rx);
  EXPECT_TRUE(tk->default_config && rx->default_config);
  ASSERT_EQ(tk->notes.size(), 1u);
  EXPECT_NE(tk->notes[0].find("no " + dir + "/tanker/aircraft.yaml: the defaults are used"), std::string::npos);
  const PoseErrorStats s = fuse_against_truth(scenario, flight, logs, *tk, *rx, true);
  std::printf("[demo, no aircraft.yaml, defaults] %s\n", describe(s).c_str());
  EXPECT_GT(s.pos_rms_m, 1.0);
  EXPECT_EQ(s.within_1sigma, 0.0);
  // A folder that has aircraft.yaml uses it, defaults allowed or not.
  std::ofstream(dir + "/tanker/aircraft.yaml") << aircraft_config_to_yaml(ins_config_for(scenario.sensors.tanker));
  auto with = load_aircraft_logs(dir + "/tanker", o);
  ASSERT_TRUE(with);
  EXPECT_FALSE(with->default_config);
  EXPECT_EQ(with->config.lever_arm_body_m, scenario.sensors.tanker.gps.lever_arm_m);
}

// The NIS check in plain words: consistent on the correctly configured demo; a GPS noise told 5x too
// small makes the innovations several times larger than predicted (optimistic), 10x too large the
// reverse (pessimistic); a handful of fixes is not judged.
TEST(FlightNav, InnovationCheckSaysWhetherTheReportedSigmaHolds) {
  const sim::Scenario scenario = *sim::builtin_scenario("demo");
  const sim::Flight flight = *sim::Flight::create(scenario);
  const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
  const nav::InsConfig right = ins_config_for(scenario.sensors.receiver);  // GST sigmas: 1 cm
  auto run = [&](const nav::InsConfig& cfg) {
    auto t = nav::fuse(logs.receiver_imu, logs.receiver_gps, cfg);
    EXPECT_TRUE(t) << t.error().message;
    return check_innovations("receiver", t->report());
  };
  const InnovationCheck ok = run(right);
  std::printf("  %s\n", ok.summary.c_str());
  EXPECT_TRUE(ok.judged && ok.consistent && !ok.optimistic);
  EXPECT_TRUE(ok.warning.empty());
  EXPECT_NE(ok.summary.find(": consistent with the filter's sigma"), std::string::npos);
  nav::InsConfig small = right;
  small.gps.use_gst = false;  // the configured sigma instead of the receiver's GST
  small.gps.rtk_fixed_m = 0.002;
  small.gps.floor_m = 0.001;
  const InnovationCheck opt = run(small);
  std::printf("  %s\n  %s\n", opt.summary.c_str(), opt.warning.c_str());
  EXPECT_TRUE(opt.judged && !opt.consistent && opt.optimistic);
  EXPECT_EQ(opt.warning.rfind("receiver: GPS innovations are ", 0), 0u) << opt.warning;
  EXPECT_NE(opt.warning.find("x larger than the filter's sigma predicts"), std::string::npos);
  nav::InsConfig large = right;
  large.gps.use_gst = false;
  large.gps.rtk_fixed_m = 0.1;
  const InnovationCheck pes = run(large);
  std::printf("  %s\n  %s\n", pes.summary.c_str(), pes.warning.c_str());
  EXPECT_TRUE(pes.judged && !pes.consistent && !pes.optimistic);
  EXPECT_NE(pes.warning.find("the reported sigma is pessimistic"), std::string::npos);
  nav::FusionReport few;
  few.innovations.count = 5;
  few.innovations.scale = 9;
  EXPECT_FALSE(check_innovations("tanker", few).judged);
}

// Forward only (what a real-time filter knows), the sigma is optimistic while the filters still
// learn their attitude: pooled over eight demo flights, the frames between 1.5 and 5 s lie within
// their 1-sigma far less often than a consistent sigma's ~61-68 % (the share of a 3-D error inside
// sqrt(trace P)). Every such frame is flagged converging; the frames after convergence are close
// to nominal.
TEST(FlightNav, ForwardOnlySigmaIsFlaggedWhileTheFiltersConverge) {
  std::size_t early = 0, early_in = 0, early_flagged = 0, flagged = 0, flagged_in = 0, settled = 0, settled_in = 0;
  std::size_t smoothed_early = 0, smoothed_early_in = 0, smoothed_late = 0, smoothed_late_in = 0;
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    sim::Scenario scenario = *sim::builtin_scenario("demo");
    scenario.seed = seed;
    const sim::Flight flight = *sim::Flight::create(scenario);
    const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
    AircraftLogs tk, rx;
    tk.imu = logs.tanker_imu, tk.gps = logs.tanker_gps, tk.config = ins_config_for(scenario.sensors.tanker);
    rx.imu = logs.receiver_imu, rx.gps = logs.receiver_gps, rx.config = ins_config_for(scenario.sensors.receiver);
    std::vector<bool> converging, within;
    std::vector<double> t_s;
    nav::FusionReport tk_rep, rx_rep;
    fuse_against_truth(scenario, flight, logs, tk, rx, false, &tk_rep, &rx_rep, &converging, &t_s, &within);
    ASSERT_TRUE(tk_rep.converged && rx_rep.converged) << "seed " << seed;
    std::printf("  seed %d: the tanker's filter converged %.1f s after the start, the receiver's %.1f s\n",
                static_cast<int>(seed), ns_to_s(tk_rep.converged_ns - scenario.start_gps_ns),
                ns_to_s(rx_rep.converged_ns - scenario.start_gps_ns));
    for (std::size_t i = 0; i < t_s.size(); ++i) {
      if (t_s[i] >= 1.5 && t_s[i] < 5.0) {
        ++early, early_in += within[i], early_flagged += converging[i];
      }
      if (t_s[i] < 1.5) continue;
      if (converging[i]) {
        ++flagged, flagged_in += within[i];
      } else {
        ++settled, settled_in += within[i];
      }
    }
    std::vector<bool> sm_within;
    std::vector<double> sm_t;
    fuse_against_truth(scenario, flight, logs, tk, rx, true, nullptr, nullptr, nullptr, &sm_t, &sm_within);
    for (std::size_t i = 0; i < sm_t.size(); ++i) {
      if (sm_t[i] >= 1.5 && sm_t[i] < 5.0) ++smoothed_early, smoothed_early_in += sm_within[i];
      if (sm_t[i] >= 10.0) ++smoothed_late, smoothed_late_in += sm_within[i];
    }
  }
  const double f_early = static_cast<double>(early_in) / early, f_flagged = static_cast<double>(flagged_in) / flagged,
               f_settled = static_cast<double>(settled_in) / settled,
               f_smoothed = static_cast<double>(smoothed_early_in) / smoothed_early;
  std::printf(
      "  forward only, 8 flights: 1.5-5 s %.0f %% within the 1-sigma (%zu frames, %zu flagged converging); all "
      "flagged frames after 1.5 s %.0f %% (%zu), the frames after convergence %.0f %% (%zu); smoothed, 1.5-5 s "
      "%.0f %%, from 10 s %.0f %%\n",
      100 * f_early, early, early_flagged, 100 * f_flagged, flagged, 100 * f_settled, settled, 100 * f_smoothed,
      100.0 * static_cast<double>(smoothed_late_in) / static_cast<double>(smoothed_late));
  EXPECT_LT(f_early, 0.45);         // optimistic: a consistent sigma holds ~61-68 %
  EXPECT_EQ(early_flagged, early);  // ... and every one of those frames says so
  EXPECT_GT(f_settled, 0.5);
  EXPECT_GT(f_settled, f_flagged + 0.1);
  EXPECT_GT(settled, flagged);
}

// ---- The IMU clock (issue 20 §2) --------------------------------------------------------------------

// 80 s behind a tanker rolling into a racetrack turn after 1.5 km (30 deg bank), the receiver joining
// and going to contact in turbulence; RTK 1 cm, the tanker's navigation-grade IMU stamping -4 ms and
// drifting 20 ppm from GPS time, the receiver's tactical IMU 7 ms ahead of it.
constexpr const char* kClockScenario = R"(augrig_scenario: 1
name: imu-clock
duration_s: 80
seed: 3
start: {utc: "2024-06-01T12:00:00Z", lat_deg: 51.0, lon_deg: -1.0, alt_m: 7000}
rig: paper_default
tanker: {pattern: racetrack, heading_deg: 90, speed_mps: 170, bank_deg: 30, leg_length_m: 1500, roll_in_s: 4,
         angle_of_attack_deg: 3}
receiver:
  contact: {elevation_deg: 30, azimuth_deg: 0, extension_m: 3.5}
  phases:
    - {name: observation, duration_s: 15, offset_m: [-30, 2, 12]}
    - {name: to-pre-contact, duration_s: 20, offset_m: [-15, 0, 4]}
    - {name: pre-contact, duration_s: 10}
    - {name: to-contact, duration_s: 15, offset_m: [0, 0, 0]}
    - {name: contact, duration_s: 20, attached: true}
  turbulence: {sigma_m: [0.2, 0.15, 0.2], sigma_deg: [0.5, 0.4, 0.4], length_scale_m: 500}
sensors:
  tanker:
    imu: {preset: navigation, rate_hz: 200, clock_offset_ns: -4000000, clock_drift_ppm: 20}
    gps: {rate_hz: 10, lever_arm_m: [5.0, 0.0, -3.5], latency_s: 0.03, heading: true}
  receiver:
    imu: {preset: tactical, rate_hz: 200, clock_offset_ns: 7000000}
    gps: {rate_hz: 10, lever_arm_m: [1.0, 0.0, -1.2], latency_s: 0.03}
  common_gps_error: {sigma_horizontal_m: 0.3, sigma_vertical_m: 0.6, tau_s: 600}
  cameras: {fps: 30, clock_offset_ns: [1200000, 1250000], jitter_ns: 20000}
)";

// The simulated IMU clocks estimated online from the logs as `augrig sim` writes them (aircraft.yaml
// with imu_clock, as ins_config_for sets it for an IMU off GPS time): the smoothed offset within 1 ms
// and its 1-sigma, the forward filters' consistent with theirs, and the receiver's pose in the camera
// as accurate as when both IMUs stamp on GPS time; left unestimated, the offsets show.
TEST(FlightNav, ImuClockOffsetsAreEstimatedAndApplied) {
  auto parsed = sim::parse_scenario(kClockScenario, "imu_clock.yaml");
  ASSERT_TRUE(parsed) << parsed.error().message;
  const sim::Scenario scenario = *parsed;
  sim::Scenario on_gps_time = scenario;
  for (sim::AircraftSensors* a : {&on_gps_time.sensors.tanker, &on_gps_time.sensors.receiver})
    a->imu.clock_offset_ns = 0, a->imu.clock_drift_ppm = 0;
  const sim::Flight flight = *sim::Flight::create(scenario);
  const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
  const sim::SensorLogs ref_logs = sim::simulate_sensors(on_gps_time, flight);
  // Through the files: aircraft.yaml carries imu_clock.
  const std::string dir = test::output_dir("flight_nav_imu_clock");
  ASSERT_TRUE(write_aircraft_logs(dir + "/tanker", logs.tanker_imu, logs.tanker_gps,
                                  ins_config_for(scenario.sensors.tanker)));
  ASSERT_TRUE(write_aircraft_logs(dir + "/receiver", logs.receiver_imu, logs.receiver_gps,
                                  ins_config_for(scenario.sensors.receiver)));
  auto tk = load_aircraft_logs(dir + "/tanker");
  auto rx = load_aircraft_logs(dir + "/receiver");
  ASSERT_TRUE(tk && rx);
  ASSERT_TRUE(tk->config.imu_clock.estimate && rx->config.imu_clock.estimate);

  const std::pair<const char*, const sim::ImuConfig*> imus[] = {{"tanker", &scenario.sensors.tanker.imu},
                                                                {"receiver", &scenario.sensors.receiver.imu}};
  auto true_clock_s = [&](const sim::ImuConfig& imu, TimestampNs t_gps) {
    return 1e-9 * static_cast<double>(imu.clock_offset_ns) +
           1e-6 * imu.clock_drift_ppm * ns_to_s(t_gps - scenario.start_gps_ns);
  };
  for (int a = 0; a < 2; ++a) {
    const AircraftLogs& l = a ? *rx : *tk;
    const sim::ImuConfig& imu = *imus[a].second;
    auto fwd = nav::fuse(l.imu, l.gps, l.config, false);
    auto smo = nav::fuse(l.imu, l.gps, l.config, true);
    ASSERT_TRUE(fwd && smo);
    double worst_after_60 = 0, worst_z = 0;
    for (double t = 60.0; t <= 79.0; t += 0.5) {
      const auto s = fwd->at(scenario.start_gps_ns + s_to_ns(t));
      ASSERT_TRUE(s) << s.error().message;
      const double e = std::abs(s->imu_clock_offset_s - true_clock_s(imu, s->t_ns));
      worst_after_60 = std::max(worst_after_60, e);
      worst_z = std::max(worst_z, e / std::sqrt(s->clock.P_cc(0, 0)));
    }
    const auto at60 = fwd->at(scenario.start_gps_ns + s_to_ns(60.0));
    const nav::FusionReport& r = smo->report();
    const double err = r.imu_clock_offset_s - true_clock_s(imu, r.imu_clock_t_ns);
    std::printf(
        "  %s: forward at 60 s %+.3f ms (1-sigma %.3f ms), worst error 60-79 s %.3f ms; %s; error %+.3f ms\n",
        imus[a].first, 1e3 * at60->imu_clock_offset_s, 1e3 * std::sqrt(at60->clock.P_cc(0, 0)),
        1e3 * worst_after_60, describe_imu_clock(imus[a].first, r).c_str(), 1e3 * err);
    // A racetrack's steady turn and the receiver's turbulence tell the clock less than the S-turns in
    // nav/ins_test.cpp: forward, the offset is known to its (consistent) 1-sigma of 1.5-2 ms at 60 s.
    EXPECT_LT(worst_z, 3.0) << imus[a].first;
    EXPECT_LE(worst_after_60, 3e-3) << imus[a].first;
    EXPECT_LE(std::abs(err), 1e-3) << imus[a].first;
    EXPECT_LE(std::abs(err), 3.0 * r.imu_clock_offset_sigma_s) << imus[a].first;
    EXPECT_LE(std::abs(r.imu_clock_drift_s_per_s - 1e-6 * imu.clock_drift_ppm), 3.0 * r.imu_clock_drift_sigma)
        << imus[a].first;
  }
  // The receiver in the camera at every frame from 10 s on (the filters' start-up left out: the
  // clock's prior widens the first position along track).
  AircraftLogs tk_ref, rx_ref, tk_off = *tk, rx_off = *rx;
  tk_ref.imu = ref_logs.tanker_imu, tk_ref.gps = ref_logs.tanker_gps;
  rx_ref.imu = ref_logs.receiver_imu, rx_ref.gps = ref_logs.receiver_gps;
  tk_ref.config = ins_config_for(on_gps_time.sensors.tanker);
  rx_ref.config = ins_config_for(on_gps_time.sensors.receiver);
  tk_off.config.imu_clock.estimate = rx_off.config.imu_clock.estimate = false;
  const auto from_10s = [&](const sim::Scenario& sc, const sim::SensorLogs& lg, const AircraftLogs& t,
                            const AircraftLogs& r) {
    return fuse_against_truth(sc, flight, lg, t, r, true, nullptr, nullptr, nullptr, nullptr, nullptr, 10.0);
  };
  const PoseErrorStats ref = from_10s(on_gps_time, ref_logs, tk_ref, rx_ref);
  const PoseErrorStats on = from_10s(scenario, logs, *tk, *rx);
  const PoseErrorStats off = from_10s(scenario, logs, tk_off, rx_off);
  std::printf("  IMUs on GPS time: %s\n  IMU clocks estimated: %s\n  IMU clocks not estimated: %s\n",
              describe(ref).c_str(), describe(on).c_str(), describe(off).c_str());
  ASSERT_GT(on.matched, 4000u);
  EXPECT_LE(on.pos_rms_m, 1.2 * ref.pos_rms_m);
  EXPECT_LE(on.att_rms_deg, 1.2 * ref.att_rms_deg);
  EXPECT_GT(off.pos_rms_m, 2.0 * on.pos_rms_m);
  // The pose sigma is that at the frame's GPS time (the offset's uncertainty mapped onto it): neither
  // hiding the errors nor covering all of them (a consistent 3-D sigma holds about 61-68 %).
  EXPECT_GT(on.within_1sigma, 0.5);
  EXPECT_LT(on.within_1sigma, 0.95);
}

TEST(FlightNav, ComparePosesMatchesBySequenceAndCamera) {
  nav::CameraPoseRow a;
  a.sequence = 1, a.camera = 0, a.z_m = 10, a.sigma_pos_m = 0.1;
  nav::CameraPoseRow b = a;
  b.camera = 1;
  nav::CameraPoseRow ta = a, tb = b;
  ta.z_m = 10.05;  // 5 cm off: inside the 10 cm sigma
  tb.x_m = 0.3;    // 30 cm off: outside
  const PoseErrorStats s = compare_poses({a, b}, {tb, ta});
  EXPECT_EQ(s.matched, 2u);
  EXPECT_NEAR(s.pos_max_m, 0.3, 1e-12);
  EXPECT_NEAR(s.pos_rms_m, std::sqrt((0.05 * 0.05 + 0.09) / 2), 1e-12);
  EXPECT_DOUBLE_EQ(s.within_1sigma, 0.5);
}

}  // namespace
}  // namespace augrig::pipeline
