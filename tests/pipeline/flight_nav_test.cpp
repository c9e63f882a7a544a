// Flight nav on simulated flights: the accuracy the issue asks for, end to end from the simulator's
// logs (written and read back in their real formats) through nav::fuse() to the receiver's pose in
// the tanker body frame and each camera. Truth comes from sim::Flight, an independent analytic model.
#include "pipeline/flight_nav.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>

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
  auto edge = parse_aircraft_config("imu_time_offset_ns: -5e17\n", "<ok>");
  ASSERT_TRUE(edge) << edge.error().message;
  EXPECT_EQ(edge->imu_time_offset_ns, -500'000'000'000'000'000);
  auto missing = load_aircraft_logs("/nonexistent/tanker");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("/nonexistent/tanker: not a folder"), std::string::npos);
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
