// augrig nav through the real binary, on what augrig sim wrote: poses against truth, stream clock
// offsets, the report of bad log lines, and errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "nav/logs.hpp"
#include "render/rig.hpp"
#include "sim/scenario.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::augrig_binary;
using test::output_dir;
using test::run_command;

Expected<Rig> load_rig_arg_for_test() {
  auto sc = sim::builtin_scenario("demo");
  if (!sc) return sc.error();
  return sc->rig;
}

int augrig(const std::string& args, std::string* output = nullptr) {
  return test::run_augrig(args, output);
}

// One simulated dataset per test process (CTest runs each test in its own process, in parallel,
// so each gets its own folder).
const std::string& dataset() {
  static const std::string dir = [] {
    const std::string d =
        output_dir(std::string("cmd_nav_dataset_") + testing::UnitTest::GetInstance()->current_test_info()->name());
    std::string log;
    EXPECT_EQ(augrig("sim --scenario demo --no-images --out " + d, &log), 0) << log;
    return d;
  }();
  return dir;
}

std::string nav_args(const std::string& d, const std::string& out, const std::string& tanker = "",
                     const std::string& frames = "") {
  return "nav --tanker " + (tanker.empty() ? d + "/tanker" : tanker) + " --receiver " + d + "/receiver --rig " + d +
         "/rig.yaml --frames " + (frames.empty() ? d + "/frames/index.csv" : frames) + " --out " + out;
}

double rms_error_mm(const std::string& estimate, const std::string& truth) {
  auto e = nav::read_camera_pose_csv(estimate);
  auto t = nav::read_camera_pose_csv(truth);
  EXPECT_TRUE(e && t);
  double s = 0;
  std::size_t n = 0;
  for (std::size_t i = 0, j = 0; i < e->rows.size(); ++i) {
    while (j < t->rows.size() && (t->rows[j].sequence < e->rows[i].sequence ||
                                  (t->rows[j].sequence == e->rows[i].sequence && t->rows[j].camera < e->rows[i].camera)))
      ++j;
    if (j == t->rows.size()) break;
    const auto& a = e->rows[i];
    const auto& b = t->rows[j];
    if (a.sequence != b.sequence || a.camera != b.camera) continue;
    const double d = std::hypot(a.x_m - b.x_m, a.y_m - b.y_m, a.z_m - b.z_m);
    s += d * d, ++n;
  }
  EXPECT_GT(n, 1000u);
  return 1e3 * std::sqrt(s / std::max<std::size_t>(n, 1));
}

TEST(CmdNav, PosesMatchTruthWithTheCameraClockOffsetsAndNotWithout) {
  const std::string d = dataset();
  const std::string out = output_dir("cmd_nav_out");
  std::string log;
  ASSERT_EQ(augrig(nav_args(d, out + "/poses.csv") + " --camera-offset-ns 1200000,1250000 --truth " + d +
                       "/truth/poses.csv --solutions " + out + "/solutions",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("Against truth"), std::string::npos) << log;
  const double good = rms_error_mm(out + "/poses.csv", d + "/truth/poses.csv");
  EXPECT_LT(good, 15.0) << log;
  EXPECT_TRUE(fs::exists(out + "/solutions/tanker.csv"));
  // Without the offsets the camera times are 1.2 ms off: the receiver moves relative to the tanker
  // only slowly, so the error grows but stays small; the tanker's own motion cancels.
  ASSERT_EQ(augrig(nav_args(d, out + "/poses_no_offset.csv"), &log), 0) << log;
  const double off = rms_error_mm(out + "/poses_no_offset.csv", d + "/truth/poses.csv");
  EXPECT_GE(off, good - 0.5);
  // Forward only (what a real-time filter knows) is worse than smoothed.
  ASSERT_EQ(augrig(nav_args(d, out + "/poses_fwd.csv") + " --camera-offset-ns 1200000,1250000 --forward-only", &log),
            0)
      << log;
  EXPECT_GT(rms_error_mm(out + "/poses_fwd.csv", d + "/truth/poses.csv"), good);
}

TEST(CmdNav, MalformedLogLinesAreReportedAndSkipped) {
  const std::string d = dataset();
  const std::string bad = output_dir("cmd_nav_bad_lines");
  fs::copy(d + "/tanker", bad + "/tanker", fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  {
    std::ofstream f(bad + "/tanker/gps.nmea", std::ios::app);
    f << "$GNGGA,garbage*00\r\n\x01\x02 binary junk\r\n";
  }
  std::string log;
  ASSERT_EQ(augrig(nav_args(d, bad + "/poses.csv", bad + "/tanker"), &log), 0)
      << log;
  EXPECT_NE(log.find("tanker gps.nmea: 2 malformed lines"), std::string::npos) << log;
  EXPECT_NE(log.find("gps.nmea:"), std::string::npos) << log;
}

TEST(CmdNav, FixedAndScriptedBoomModes) {
  const std::string d = dataset();
  const std::string dir = output_dir("cmd_nav_boom");
  std::string log;
  ASSERT_EQ(augrig(nav_args(d, dir + "/fixed.csv") + " --boom fixed:30,-2,4", &log), 0) << log;
  auto fixed = nav::read_camera_pose_csv(dir + "/fixed.csv");
  ASSERT_TRUE(fixed);
  for (const auto& r : fixed->rows) {
    EXPECT_NEAR(r.boom_elevation_deg, 30.0, 1e-9);
    EXPECT_NEAR(r.boom_azimuth_deg, -2.0, 1e-9);
    EXPECT_NEAR(r.boom_extension_m, 4.0, 1e-12);
  }
  {
    std::ofstream f(dir + "/script.csv");
    f << "t_s,elevation_deg,azimuth_deg,extension_m\n0,25,0,1\n20,35,5,4\n";
  }
  ASSERT_EQ(augrig(nav_args(d, dir + "/script.csv.out") + " --boom script:" + dir + "/script.csv", &log), 0) << log;
  auto scripted = nav::read_camera_pose_csv(dir + "/script.csv.out");
  ASSERT_TRUE(scripted);
  EXPECT_NEAR(scripted->rows.front().boom_elevation_deg, 25.0, 0.01);
  EXPECT_NEAR(scripted->rows.back().boom_extension_m, 4.0, 1e-12);  // held after the script's end
  // Outside the rig's limits (elevation 20..40 deg): clamped.
  ASSERT_EQ(augrig(nav_args(d, dir + "/clamped.csv") + " --boom fixed:60,0,1", &log), 0) << log;
  EXPECT_NEAR(nav::read_camera_pose_csv(dir + "/clamped.csv")->rows.front().boom_elevation_deg, 40.0, 1e-9);
  EXPECT_EQ(augrig(nav_args(d, dir + "/x.csv") + " --boom wiggle", &log), 2);
  EXPECT_EQ(augrig(nav_args(d, dir + "/x.csv") + " --boom script:/nonexistent.csv", &log), 1);
  EXPECT_NE(log.find("/nonexistent.csv"), std::string::npos) << log;
}

// A capture-only rig (no boom section) has no boom to articulate: the poses carry no boom columns
// (whoever augments with them flies its own boom) and are the same poses as with the full rig;
// --boom still says what the boom does.
TEST(CmdNav, CaptureOnlyRigWritesNoBoomColumns) {
  const std::string d = dataset();
  const std::string dir = output_dir("cmd_nav_capture_only");
  auto rig = load_rig(d + "/rig.yaml");
  ASSERT_TRUE(rig) << rig.error().message;
  rig->boom.configured = false;
  std::ofstream(dir + "/capture.yaml") << rig_to_yaml(*rig);
  std::string log;
  ASSERT_EQ(augrig(nav_args(d, dir + "/full.csv"), &log), 0) << log;
  const std::string args = "nav --tanker " + d + "/tanker --receiver " + d + "/receiver --rig " + dir +
                           "/capture.yaml --frames " + d + "/frames/index.csv --out ";
  ASSERT_EQ(augrig(args + dir + "/capture.csv", &log), 0) << log;
  auto full = nav::read_camera_pose_csv(dir + "/full.csv");
  auto capture = nav::read_camera_pose_csv(dir + "/capture.csv");
  ASSERT_TRUE(full && capture);
  ASSERT_EQ(full->rows.size(), capture->rows.size());
  for (std::size_t i = 0; i < full->rows.size(); ++i) {
    const auto &a = full->rows[i], &b = capture->rows[i];
    EXPECT_TRUE(std::isfinite(a.boom_elevation_deg));
    EXPECT_TRUE(std::isnan(b.boom_elevation_deg) && std::isnan(b.boom_azimuth_deg) && std::isnan(b.boom_extension_m));
    EXPECT_EQ(a.t_ns, b.t_ns);
    EXPECT_NEAR(a.x_m, b.x_m, 1e-9) << "the same poses (the rig written and read back: to 1e-14)";
    EXPECT_NEAR(a.z_m, b.z_m, 1e-9);
  }
  ASSERT_EQ(augrig(args + dir + "/fixed.csv --boom fixed:30,0,4", &log), 0) << log;
  EXPECT_NEAR(nav::read_camera_pose_csv(dir + "/fixed.csv")->rows.front().boom_elevation_deg, 30.0, 1e-9);
}

std::string read_all(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A flight flown in 2016, when GPS - UTC was 17 s: augrig sim writes the UTC a receiver did, nav
// takes the 17 s from the table for the log's date and says so; --leap-seconds 18 (what every log
// was read with before) is warned about naming the file and line, and the GPS innovations say the
// sigma does not hold.
TEST(CmdNav, LeapSecondsOfALogFrom2016) {
  const std::string dir = output_dir("cmd_nav_2016");
  auto text = sim::builtin_scenario_text("demo");
  ASSERT_TRUE(text);
  std::string yaml = *text;
  const std::string from = "2024-06-01T12:00:00Z";
  ASSERT_NE(yaml.find(from), std::string::npos);
  yaml.replace(yaml.find(from), from.size(), "2016-06-01T12:00:00Z");
  std::ofstream(dir + "/demo2016.yaml") << yaml;
  std::string log;
  ASSERT_EQ(augrig("sim --scenario " + dir + "/demo2016.yaml --no-images --out " + dir + "/d", &log), 0) << log;
  const std::string d = dir + "/d";
  const std::string args = nav_args(d, dir + "/poses.csv") + " --camera-offset-ns 1200000,1250000";
  const std::string args18 = nav_args(d, dir + "/poses18.csv") + " --camera-offset-ns 1200000,1250000";
  ASSERT_EQ(augrig(args, &log), 0) << log;
  EXPECT_NE(log.find("tanker gps.nmea: GPS-UTC 17 s (the leap-second table for the UTC date 2016-06-01)\n"),
            std::string::npos)
      << log;
  EXPECT_EQ(log.find("warning"), std::string::npos) << log;
  EXPECT_NE(log.find("receiver GPS innovations: 280 fixes"), std::string::npos) << log;
  EXPECT_LT(rms_error_mm(dir + "/poses.csv", d + "/truth/poses.csv"), 15.0);
  EXPECT_NE(read_all(dir + "/poses.csv").find("# gps_minus_utc_s: tanker GPS-UTC 17 s (the leap-second table"),
            std::string::npos);

  ASSERT_EQ(augrig(args18 + " --leap-seconds 18", &log), 0) << log;
  EXPECT_NE(log.find("tanker gps.nmea: GPS-UTC 18 s (given), by --leap-seconds\n"), std::string::npos) << log;
  EXPECT_NE(log.find("warning: receiver: " + d +
                     "/receiver/gps.nmea:1: GPS-UTC 18 s given, but it was 17 s on 2016-06-01 (the leap-second "
                     "table): the fix times are 1 s late"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("warning: receiver: GPS innovations are "), std::string::npos) << log;
  EXPECT_NE(log.find("the reported sigma is optimistic"), std::string::npos) << log;
  EXPECT_GT(rms_error_mm(dir + "/poses18.csv", d + "/truth/poses.csv"), 500.0);
  EXPECT_NE(read_all(dir + "/poses18.csv").find("# sigma_consistency: tanker consistent"), std::string::npos);
  EXPECT_NE(read_all(dir + "/poses18.csv").find("receiver optimistic"), std::string::npos);
  EXPECT_EQ(augrig(args + " --leap-seconds eighteen", &log), 2);
  EXPECT_NE(log.find("leap-seconds"), std::string::npos) << log;
}

TEST(CmdNav, MissingAircraftYamlIsAnErrorUnlessTheDefaultsAreAskedFor) {
  const std::string d = dataset();
  const std::string dir = output_dir("cmd_nav_no_yaml");
  fs::copy(d + "/tanker", dir + "/tanker", fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  fs::remove(dir + "/tanker/aircraft.yaml");
  std::string log;
  EXPECT_EQ(augrig(nav_args(d, dir + "/p.csv", dir + "/tanker"), &log), 1);
  EXPECT_NE(log.find("augrig nav: " + dir + "/tanker: no aircraft.yaml (expected " + dir + "/tanker/aircraft.yaml"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("--default-aircraft"), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(dir + "/p.csv"));
  ASSERT_EQ(augrig(nav_args(d, dir + "/p.csv", dir + "/tanker") + " --default-aircraft --truth " + d +
                       "/truth/poses.csv",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("note: tanker: no " + dir + "/tanker/aircraft.yaml: the defaults are used"), std::string::npos)
      << log;
  EXPECT_EQ(log.find("note: receiver"), std::string::npos) << log;  // the receiver's file is there
  EXPECT_GT(rms_error_mm(dir + "/p.csv", d + "/truth/poses.csv"), 1000.0);  // the tanker's 6 m lever arm
}

// --forward-only: the rows before both filters converged are counted, written in the pose file's
// metadata and, against the truth, compared apart; the smoothed run says nothing of it.
TEST(CmdNav, ForwardOnlySaysWhichRowsAreConverging) {
  const std::string d = dataset();
  const std::string dir = output_dir("cmd_nav_converging");
  std::string log;
  ASSERT_EQ(augrig(nav_args(d, dir + "/fwd.csv") + " --forward-only --camera-offset-ns 1200000,1250000 --truth " + d +
                       "/truth/poses.csv",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("Converging: "), std::string::npos) << log;
  EXPECT_NE(log.find(" rows before both forward filters converged (their sigma is optimistic): t_nav_ns < "),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("\n  converging: "), std::string::npos) << log;
  EXPECT_NE(log.find("\n  converged:  "), std::string::npos) << log;
  EXPECT_NE(read_all(dir + "/fwd.csv").find("# converging: "), std::string::npos);
  ASSERT_EQ(augrig(nav_args(d, dir + "/smoothed.csv"), &log), 0) << log;
  EXPECT_EQ(log.find("Converging"), std::string::npos) << log;
  EXPECT_NE(log.find("tanker GPS innovations: 280 fixes"), std::string::npos) << log;
  EXPECT_NE(log.find("consistent with the filter's sigma"), std::string::npos) << log;
  EXPECT_EQ(read_all(dir + "/smoothed.csv").find("# converging"), std::string::npos);
}

// Single-point GPS on both aircraft and the rover's moving-baseline log in the receiver folder:
// nav picks the log up by itself, says what it read and used, and the poses come out centimetres
// right instead of metres; a damaged log is read around its damage; a missing one is an error.
TEST(CmdNav, MovingBaselineFromTheRoverLog) {
  const std::string d = output_dir("cmd_nav_moving_baseline");
  std::string log;
  ASSERT_EQ(augrig("sim --scenario " + test::data_path("scenarios/moving_baseline.yaml") + " --no-images --out " + d,
                   &log),
            0)
      << log;
  ASSERT_TRUE(fs::exists(d + "/receiver/rover.ubx"));
  const std::string truth = d + "/truth/poses.csv";
  ASSERT_EQ(augrig(nav_args(d, d + "/with.csv"), &log), 0) << log;
  EXPECT_NE(log.find("receiver/rover.ubx: 151 UBX frames (151 NAV-RELPOSNED"), std::string::npos) << log;
  EXPECT_NE(log.find("moving-baseline RTK: 151 measurements"), std::string::npos) << log;
  EXPECT_NE(log.find("(optimistic)"), std::string::npos) << "single-point solutions' sigma: " << log;
  auto poses = nav::read_camera_pose_csv(d + "/with.csv");
  ASSERT_TRUE(poses);
  EXPECT_NE(log.find("Moving baseline: " + std::to_string(poses->rows.size()) + " of " +
                     std::to_string(poses->rows.size()) + " poses corrected"),
            std::string::npos)
      << log;
  std::ifstream f(d + "/with.csv");
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("# moving_baseline: " + d + "/receiver/rover.ubx:"), std::string::npos);
  ASSERT_EQ(augrig(nav_args(d, d + "/without.csv") + " --no-baseline", &log), 0) << log;
  EXPECT_EQ(log.find("Moving baseline"), std::string::npos) << log;
  const double with_mm = rms_error_mm(d + "/with.csv", truth), without_mm = rms_error_mm(d + "/without.csv", truth);
  std::printf("camera-frame position RMS: %.1f mm with the moving baseline, %.1f mm without\n", with_mm, without_mm);
  EXPECT_GT(without_mm, 500.0);
  EXPECT_LT(with_mm, 30.0);

  // Damage: bytes flipped in two frames, the end cut off.
  std::ifstream in(d + "/receiver/rover.ubx", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bytes[100] = static_cast<char>(bytes[100] ^ 0x5A);
  bytes[2000] = static_cast<char>(bytes[2000] ^ 0x01);
  bytes.resize(bytes.size() - 30);
  std::ofstream(d + "/damaged.ubx", std::ios::binary) << bytes;
  ASSERT_EQ(augrig(nav_args(d, d + "/damaged.csv") + " --baseline " + d + "/damaged.ubx", &log), 0) << log;
  EXPECT_NE(log.find("damaged.ubx: 148 UBX frames (148 NAV-RELPOSNED"), std::string::npos) << log;
  EXPECT_NE(log.find("2 bad checksums"), std::string::npos) << log;
  EXPECT_NE(log.find("bytes cut off at the end"), std::string::npos) << log;
  EXPECT_LT(rms_error_mm(d + "/damaged.csv", truth), 30.0);

  EXPECT_EQ(augrig(nav_args(d, d + "/x.csv") + " --baseline " + d + "/missing.ubx", &log), 1);
  EXPECT_NE(log.find(d + "/missing.ubx"), std::string::npos) << log;
  EXPECT_EQ(augrig(nav_args(d, d + "/x.csv") + " --baseline " + d + "/damaged.ubx --no-baseline", &log), 2);
}

// Every stream's clock at once (issue 20 §2): a 45 s racetrack at 45 deg bank, the left camera's
// clock 20 ms ahead of GPS time and the right's on it (480x360 cameras to keep the rendering
// short), the tanker's IMU 7 ms and the receiver's -4 ms off: nav finds all four within 1 ms (the
// cameras through the fused tanker's angular rate, itself on GPS time by its estimated IMU clock),
// says so and writes them in the metadata. (A straight and level flight is "not estimated": tests/nav/camera_clock_test.cpp.)
TEST(CmdNav, CameraClocksFromTheImages) {
  const std::string d = output_dir("cmd_nav_camera_clock");
  Rig rig = *load_rig_arg_for_test();
  for (RigCamera& c : rig.cameras) {
    c.model = CameraModel::pinhole_from_hfov(480, 360, deg_to_rad(56));
    c.model.distortion = DistortionModel::kRadTan;
    c.model.coeffs = {-0.05, 0.01, 0, 0, 0};
  }
  std::ofstream(d + "/rig.yaml") << rig_to_yaml(rig);
  const auto scenario = [&](const std::string& tanker) {
    return "augrig_scenario: 1\nduration_s: 45\nseed: 3\nrig: " + d +
           "/rig.yaml\n"
           "start: {utc: \"2024-06-01T12:00:00Z\", lat_deg: 51.0, lon_deg: -1.0, alt_m: 7000}\n"
           "tanker: " + tanker + "\n"
           "receiver:\n  phases: [{name: pre-contact, duration_s: 45, offset_m: [-15, 0, 4]}]\n"
           "  turbulence: {sigma_m: [0.15, 0.1, 0.15], sigma_deg: [0.4, 0.3, 0.3], length_scale_m: 500}\n"
           "sensors:\n  tanker: {imu: {preset: navigation, clock_offset_ns: 7000000},\n"
           "           gps: {lever_arm_m: [5.0, 0.0, -3.5], heading: true}}\n"
           "  receiver: {imu: {clock_offset_ns: -4000000}, gps: {lever_arm_m: [1.0, 0.0, -1.2]}}\n"
           "  cameras: {fps: 30, clock_offset_ns: [20000000, 0], jitter_ns: 20000, noise: 1.5}\n";
  };
  std::ofstream(d + "/turns.yaml")
      << scenario("{pattern: racetrack, speed_mps: 120, bank_deg: 45, leg_length_m: 600, roll_in_s: 4}");
  std::string log;
  ASSERT_EQ(augrig("sim --scenario " + d + "/turns.yaml --out " + d + "/turns", &log), 0) << log;
  const std::string s = d + "/turns";
  ASSERT_EQ(augrig(nav_args(s, d + "/estimated.csv") + " --camera-clock --camera-clock-every 2", &log), 0) << log;
  // "camera 0 (left) clock: offset 19.240 ms +- 0.670 ms (1-sigma) from ...": the offset and its 1-sigma.
  const auto offset_ms = [&](const std::string& camera) -> std::pair<double, double> {
    const std::size_t at = log.find(camera + " clock: offset ");
    EXPECT_NE(at, std::string::npos) << log;
    if (at == std::string::npos) return {NAN, NAN};
    const std::size_t pm = log.find(" +- ", at);
    EXPECT_NE(pm, std::string::npos) << log;
    return {std::stod(log.substr(at + camera.size() + 15)),
            pm == std::string::npos ? NAN : std::stod(log.substr(pm + 4))};
  };
  const auto [left_ms, left_sigma_ms] = offset_ms("camera 0 (left)");
  const auto [right_ms, right_sigma_ms] = offset_ms("camera 1 (right)");
  EXPECT_NEAR(left_ms, 20.0, 1.0) << log;
  EXPECT_NEAR(right_ms, 0.0, 1.0) << log;
  // The 1-sigma is honest: the truth within 2.5 of it (issue 20 §3). The 45 s hold one whole roll-in
  // and the start of a roll-out cut by the data's end, which the fit's own 1-sigma (0.15 ms, for
  // errors of 0.76 and 0.47 ms) did not cover.
  EXPECT_LE(std::abs(left_ms - 20.0), 2.5 * left_sigma_ms) << log;
  EXPECT_LE(std::abs(right_ms - 0.0), 2.5 * right_sigma_ms) << log;
  EXPECT_NE(log.find("(1-sigma) from the "), std::string::npos) << log;
  // The IMUs' clocks (7 ms on the tanker's, whose angular rate the cameras are matched to; -4 ms
  // on the receiver's), estimated by the filters as aircraft.yaml asks (augrig sim sets imu_clock).
  const auto imu_ms = [&](const std::string& who) {
    const std::string key = who + " IMU clock - GPS time: ";
    const std::size_t at = log.find(key);
    EXPECT_NE(at, std::string::npos) << log;
    return at == std::string::npos ? NAN : std::stod(log.substr(at + key.size()));
  };
  EXPECT_NEAR(imu_ms("tanker"), 7.0, 1.0) << log;
  EXPECT_NEAR(imu_ms("receiver"), -4.0, 1.0) << log;
  std::ifstream f(d + "/estimated.csv");
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("# camera_clock: camera 0 (left) clock: offset "), std::string::npos);
  EXPECT_EQ(augrig(nav_args(s, d + "/x.csv") + " --camera-clock --camera-offset-ns 1", &log), 2);
  EXPECT_EQ(augrig(nav_args(s, d + "/x.csv") + " --camera-clock-every 2", &log), 2);
}

TEST(CmdNav, BadInputsExitOneWithTheFile) {
  const std::string d = dataset();
  const std::string dir = output_dir("cmd_nav_errors");
  std::string log;
  EXPECT_EQ(augrig("nav --tanker /nonexistent --receiver " + d + "/receiver --rig default --frames " + d +
                       "/frames/index.csv --out " + dir + "/p.csv",
                   &log),
            1);
  EXPECT_NE(log.find("/nonexistent: not a folder"), std::string::npos) << log;
  {
    std::ofstream f(dir + "/index.csv");
    f << "sequence,camera,t_ns,file\n0,0,notanumber,a.png\n";
  }
  EXPECT_EQ(augrig(nav_args(d, dir + "/p.csv", "", dir + "/index.csv"), &log), 1);
  EXPECT_NE(log.find("index.csv:2: column 't_ns'"), std::string::npos) << log;
  EXPECT_EQ(augrig(nav_args(d, dir + "/p.csv") + " --camera-offset-ns 1,2,3", &log), 2);
}

}  // namespace
}  // namespace augrig
