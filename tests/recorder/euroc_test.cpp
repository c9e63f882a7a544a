// EuRoC/ASL export: export a recording, play the export back through EurocSource and get the
// recorded images and timestamps back exactly (raw, augmented, masks); sensor.yaml read with
// yaml-cpp holds the rig; imu0 holds the recorded increments as rates; poses.csv and stats.csv;
// the statistics plot is a real picture; gnuplot missing is a clear error. (EurocSource on its own, on
// datasets written by hand: tests/recorder/euroc_source_test.cpp.)
#include "recorder/euroc.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include "nav/imu_stream.hpp"
#include "nav/ins.hpp"
#include "nav/logs.hpp"
#include "nav/nmea.hpp"
#include "pipeline/flight_nav.hpp"
#include "recorder/euroc_source.hpp"
#include "recorder/plot.hpp"
#include "recorder/recorder.hpp"
#include "recorder/store.hpp"
#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr int kW = 80, kH = 60;
constexpr TimestampNs kT0 = 1'400'000'000'000'000'000;  // GPS-time-like magnitudes
constexpr TimestampNs kPeriod = 50'000'000;             // 20 Hz
constexpr int kFrames = 12;

Rig small_rig() {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.model = CameraModel::pinhole_from_hfov(kW, kH, deg_to_rad(56.0));
  CameraModel& r = rig.cameras[1].model;
  r.fx_px += 0.25;
  r.cx_px -= 0.5;
  r.distortion = DistortionModel::kRadTan;
  r.coeffs = {-0.12, 0.015, 0.0007, -0.0004, 0.0};
  return *parse_rig(rig_to_yaml(rig), "<string>");
}

Image random_image(int w, int h, PixelFormat f, std::uint64_t seed) {
  Image img(w, h, f);
  std::mt19937_64 rng(seed);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w * bytes_per_pixel(f); ++x) img.row(y)[x] = static_cast<std::uint8_t>(rng());
  return img;
}

FrameRecord frame(int i) {
  FrameRecord r;
  r.raw.pair_sequence = static_cast<std::uint64_t>(i);
  r.raw.t_key_ns = r.raw.left.t_ns = r.raw.right.t_ns = kT0 + i * kPeriod;
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    Frame& f = r.raw[id];
    const int c = index_of(id);
    f.camera = id;
    f.clock = ClockDomain::kGps;
    f.sequence = static_cast<std::uint64_t>(i);
    f.image = random_image(kW, kH, PixelFormat::kBayerRG8, static_cast<std::uint64_t>(10 * i + c));
    // The augmented image: the raw one with a painted box; the mask: bits in that box.
    r.augmented[c] = Image::copy_of(f.image.cview());
    r.mask[c] = Image(kW, kH, PixelFormat::kMono8);
    for (int y = 10; y < 20 + i; ++y)
      for (int x = 5 + c; x < 30; ++x) {
        r.augmented[c].row(y)[x] = 200;
        r.mask[c].row(y)[x] = (x < 15 ? kMaskBoom : kMaskBoom | kMaskReceiver);
      }
    r.T_cam_receiver[c] = Pose::from(rotation_from_ypr(0.1 * i, 0.02, -0.03 * c),
                                     Eigen::Vector3d(0.1 * c, -2.0, 15.0 + 0.1 * i));
  }
  // The receiver relative to the tanker, closing at 4 m/s; frame 5 without it (no nav pose yet).
  if (i != 5)
    r.T_body_receiver = Pose::from(rotation_from_ypr(0.01 * i, 0.02, 0.0), Eigen::Vector3d(-15.0 + 0.2 * i, 0.1, 8.0));
  r.sigma_pos_m = 0.05;
  r.sigma_att_deg = 0.2;
  r.boom = BoomArticulation{deg_to_rad(30), deg_to_rad(-2), 3.5};
  OcclusionStats s;
  s.t_ns = r.raw.t_key_ns;
  s.width = kW;
  s.height = kH;
  s.occluded_pct_left = 10 + 3 * i;
  s.occluded_pct_right = 40 - 2 * i;
  s.boom_overlap_pct_union = 50 + (i % 3) * 10;
  s.receiver_pct_left = 20 + i;
  s.receiver_pct_right = 22 + i;
  s.boom_pct_left = 5 + 0.5 * i;
  s.boom_pct_right = 6 + 0.5 * i;
  s.boom_px_left = 100 + i;
  r.stats = s;
  return r;
}

nav::ImuSample imu_sample(int k) {
  nav::ImuSample s;
  s.dt_s = 0.005;
  s.t_ns = kT0 + k * 5'000'000;
  s.dtheta_rad = Eigen::Vector3d(0.01, -0.02 + 1e-4 * k, 0.003) * s.dt_s;
  s.dv_mps = Eigen::Vector3d(0.5, 0.1 * k, -9.81) * s.dt_s;
  return s;
}

std::string make_recording(const std::string& name, bool with_rig = true) {
  const std::string dir = test::output_dir("euroc/" + name);
  RecordingInfo info;
  if (with_rig) info.rig_yaml = rig_to_yaml(small_rig());
  auto rec = Recorder::create(dir, info);
  EXPECT_TRUE(rec) << rec.error().message;
  for (int k = 0; k < 100; ++k) (*rec)->push(imu_input(imu_sample(k), "tanker.imu"));
  (*rec)->push(NavInputRecord{"tanker.gps", 5, ClockDomain::kGps, 6, "$GPHDT,274.07,T*03", false});
  for (int i = 0; i < kFrames; ++i) EXPECT_TRUE((*rec)->push(frame(i)));
  // The flight's phases beside the statistics (one began before the first frame), and an event
  // that is not a phase.
  (*rec)->push(EventRecord{kT0 + 3 * kPeriod, ClockDomain::kGps, "phase: contact"});
  (*rec)->push(EventRecord{kT0 - 1'000'000'000, ClockDomain::kGps, "phase: pre-contact"});
  (*rec)->push(EventRecord{kT0 + kPeriod, ClockDomain::kHostMonotonic, "nav stale from pair 1"});
  EXPECT_TRUE((*rec)->close());
  return dir;
}

struct Exported {
  std::string recording, out;
  EurocExportReport report;
};

// One recording exported once per test process, in folders of that test's own (CTest runs the
// tests of this file in parallel processes).
const Exported& exported() {
  static const Exported e = [] {
    const std::string name = testing::UnitTest::GetInstance()->current_test_info()->name();
    Exported x;
    x.recording = make_recording("recording_" + name);
    x.out = test::output_dir("euroc/export_" + name);
    auto rd = RecordingReader::open(x.recording);
    EXPECT_TRUE(rd) << rd.error().message;
    auto st = export_euroc(**rd, x.out, {}, x.report);
    EXPECT_TRUE(st) << st.error().message;
    return x;
  }();
  return e;
}

std::vector<Frame> read_all(const std::string& dir, const EurocOptions& o = {}) {
  auto src = EurocSource::open(dir, o);
  EXPECT_TRUE(src) << src.error().message;
  std::vector<Frame> frames;
  if (!src) return frames;
  Frame f;
  for (;;) {
    auto st = (*src)->read(f, 0ns);
    EXPECT_TRUE(st) << st.error().message;
    if (!st || *st == ReadStatus::kEndOfStream) break;
    frames.push_back(f);
  }
  return frames;
}

TEST(EurocExport, ReplayGivesTheRecordedImagesAndTimestampsBack) {
  const Exported& e = exported();
  EXPECT_EQ(e.report.frames, static_cast<std::size_t>(kFrames));
  EXPECT_EQ(e.report.frames_written, static_cast<std::size_t>(kFrames));
  EXPECT_TRUE(e.report.problems.empty()) << e.report.problems.front();
  EXPECT_DOUBLE_EQ(e.report.rate_hz, 20.0);
  for (const char* s : {"cam0", "cam1", "cam0_augmented", "cam1_augmented", "cam0_mask", "cam1_mask"}) {
    const fs::path d = fs::path(e.out) / "mav0" / s;
    EXPECT_TRUE(fs::exists(d / "data.csv")) << d;
    EXPECT_TRUE(fs::exists(d / "sensor.yaml")) << d;
    EXPECT_TRUE(fs::exists(d / "data" / (std::to_string(kT0) + ".png"))) << d;
  }
  std::ifstream csv(fs::path(e.out) / "mav0/cam0/data.csv");
  std::string header, row;
  std::getline(csv, header);
  std::getline(csv, row);
  EXPECT_EQ(header, "#timestamp [ns],filename");
  EXPECT_EQ(row, std::to_string(kT0) + "," + std::to_string(kT0) + ".png");

  // Raw: Bayer mosaics come back as Bayer (sensor.yaml's augrig: pixel_format), bit for bit.
  const auto raw = read_all("euroc://" + e.out);
  ASSERT_EQ(raw.size(), 2u * kFrames);
  for (int i = 0; i < kFrames; ++i) {
    const FrameRecord want = frame(i);
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      const Frame& got = raw[static_cast<std::size_t>(2 * i + index_of(id))];
      EXPECT_EQ(got.camera, id);
      EXPECT_EQ(got.t_ns, want.raw[id].t_ns);
      EXPECT_EQ(got.clock, ClockDomain::kGps);
      EXPECT_EQ(got.sequence, static_cast<std::uint64_t>(i));
      EXPECT_EQ(got.image.format(), PixelFormat::kBayerRG8);
      EXPECT_TRUE(pixels_equal(got.image, want.raw[id].image)) << "frame " << i;
    }
  }
  // Augmented and masks, through the same source on their folders.
  EurocOptions o;
  o.left_stream = "cam0_augmented";
  o.right_stream = "cam1_augmented";
  const auto aug = read_all(e.out + "/mav0", o);
  o.left_stream = "cam0_mask";
  o.right_stream = "cam1_mask";
  const auto mask = read_all(e.out, o);
  ASSERT_EQ(aug.size(), 2u * kFrames);
  ASSERT_EQ(mask.size(), 2u * kFrames);
  for (int i = 0; i < kFrames; ++i) {
    const FrameRecord want = frame(i);
    for (int c = 0; c < 2; ++c) {
      const std::size_t k = static_cast<std::size_t>(2 * i + c);
      EXPECT_TRUE(pixels_equal(aug[k].image, want.augmented[c])) << "frame " << i;
      EXPECT_EQ(mask[k].image.format(), PixelFormat::kMono8);
      EXPECT_TRUE(pixels_equal(mask[k].image, want.mask[c])) << "frame " << i;
      EXPECT_EQ(aug[k].t_ns, want.raw.t_key_ns);
    }
  }
}

// The receiver's pose per stereo frame in EuRoC's ground-truth folder and columns: the recorded
// T_body_receiver, the velocity by central differences, none for the frame without a pose.
TEST(EurocExport, ReceiverStateInStateGroundtruthEstimate0) {
  const Exported& e = exported();
  const fs::path dir = fs::path(e.out) / "mav0" / "state_groundtruth_estimate0";
  ASSERT_TRUE(fs::exists(dir / "sensor.yaml"));
  std::ifstream f(dir / "data.csv");
  std::string line;
  ASSERT_TRUE(std::getline(f, line));
  EXPECT_EQ(line.rfind("#timestamp, p_RS_R_x [m]", 0), 0u) << line;
  std::vector<std::vector<double>> rows;
  std::vector<TimestampNs> t;
  while (std::getline(f, line)) {
    std::stringstream ss(line);
    std::string cell;
    std::getline(ss, cell, ',');
    t.push_back(std::stoll(cell));
    std::vector<double> v;
    while (std::getline(ss, cell, ',')) v.push_back(std::stod(cell));
    ASSERT_EQ(v.size(), 16u) << line;
    rows.push_back(v);
  }
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(kFrames - 1));
  std::size_t k = 0;
  for (int i = 0; i < kFrames; ++i) {
    if (i == 5) continue;
    const FrameRecord want = frame(i);
    SCOPED_TRACE("frame " + std::to_string(i));
    EXPECT_EQ(t[k], want.raw.left.t_ns);
    for (int a = 0; a < 3; ++a) EXPECT_DOUBLE_EQ(rows[k][a], want.T_body_receiver->translation_m[a]);
    const Eigen::Quaterniond q = want.T_body_receiver->rotation.normalized();
    EXPECT_DOUBLE_EQ(rows[k][3], q.w());
    EXPECT_DOUBLE_EQ(rows[k][4], q.x());
    EXPECT_DOUBLE_EQ(rows[k][6], q.z());
    // 0.2 m a frame of 50 ms: 4 m/s along x, whichever neighbours the difference spans.
    EXPECT_NEAR(rows[k][7], 4.0, 1e-6);
    EXPECT_NEAR(rows[k][8], 0.0, 1e-9);
    for (int b = 10; b < 16; ++b) EXPECT_EQ(rows[k][b], 0.0) << "biases: not estimated";
    ++k;
  }
}

// A camera looking straight aft: T_BS entries of exactly 0 and -1, not a few ulps off.
TEST(EurocExport, TbsOfRightAnglesIsExact) {
  const RigCamera cam = Rig::paper_default().cameras[0];
  const YAML::Node y = YAML::Load(euroc_camera_yaml(cam, "left", "raw", 30, PixelFormat::kMono8, ClockDomain::kDevice));
  const auto t = y["T_BS"]["data"].as<std::vector<double>>();
  ASSERT_EQ(t.size(), 16u);
  EXPECT_EQ(t[0], 0.0);
  EXPECT_EQ(t[4], -1.0);
  EXPECT_EQ(t[6], 0.0);
  EXPECT_EQ(t[8], 0.0);
  EXPECT_EQ(t[5], 0.0);
  const Eigen::Matrix4d T = cam.T_body_cam.matrix();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) EXPECT_NEAR(t[static_cast<std::size_t>(4 * r + c)], T(r, c), 1e-14);
}

TEST(EurocExport, SensorYamlParsesWithYamlCppAndHoldsTheRig) {
  const Exported& e = exported();
  const Rig rig = small_rig();
  for (int c = 0; c < 2; ++c) {
    for (const char* stream : {"", "_augmented", "_mask"}) {
      const fs::path p = fs::path(e.out) / "mav0" / ("cam" + std::to_string(c) + stream) / "sensor.yaml";
      YAML::Node y;
      ASSERT_NO_THROW(y = YAML::LoadFile(p.string())) << p;
      const CameraModel& m = rig.cameras[static_cast<std::size_t>(c)].model;
      EXPECT_EQ(y["sensor_type"].as<std::string>(), "camera");
      EXPECT_EQ(y["camera_model"].as<std::string>(), "pinhole");
      EXPECT_DOUBLE_EQ(y["rate_hz"].as<double>(), 20.0);
      const auto res = y["resolution"].as<std::vector<int>>();
      EXPECT_EQ(res, (std::vector<int>{kW, kH}));
      const auto in = y["intrinsics"].as<std::vector<double>>();
      ASSERT_EQ(in.size(), 4u);
      EXPECT_EQ(in[0], m.fx_px);  // shortest round-trip text: exact
      EXPECT_EQ(in[1], m.fy_px);
      EXPECT_EQ(in[2], m.cx_px);
      EXPECT_EQ(in[3], m.cy_px);
      EXPECT_EQ(y["distortion_model"].as<std::string>(), "radial-tangential");
      const auto d = y["distortion_coefficients"].as<std::vector<double>>();
      ASSERT_EQ(d.size(), 4u);
      for (int k = 0; k < 4; ++k)
        EXPECT_EQ(d[static_cast<std::size_t>(k)], m.coeffs[static_cast<std::size_t>(k)]);
      EXPECT_EQ(y["T_BS"]["rows"].as<int>(), 4);
      EXPECT_EQ(y["T_BS"]["cols"].as<int>(), 4);
      const auto t = y["T_BS"]["data"].as<std::vector<double>>();
      ASSERT_EQ(t.size(), 16u);
      const Eigen::Matrix4d T = rig.cameras[static_cast<std::size_t>(c)].T_body_cam.matrix();
      for (int r = 0; r < 4; ++r)
        for (int k = 0; k < 4; ++k)
          EXPECT_NEAR(t[static_cast<std::size_t>(4 * r + k)], T(r, k), 1e-14) << r << "," << k;
      EXPECT_EQ(y["augrig"]["pixel_format"].as<std::string>(),
                *stream == '\0' || std::string(stream) == "_augmented" ? "BayerRG8" : "Mono8");
    }
  }
  // An equidistant lens is written as such.
  RigCamera fisheye = rig.cameras[0];
  fisheye.model.distortion = DistortionModel::kEquidistant;
  fisheye.model.coeffs = {0.1, -0.01, 0.002, -0.0003, 0};
  const YAML::Node y =
      YAML::Load(euroc_camera_yaml(fisheye, "left", "raw", 30, PixelFormat::kMono8, ClockDomain::kDevice));
  EXPECT_EQ(y["distortion_model"].as<std::string>(), "equidistant");
  EXPECT_EQ(y["distortion_coefficients"].as<std::vector<double>>(),
            (std::vector<double>{0.1, -0.01, 0.002, -0.0003}));
}

TEST(EurocExport, ImuIncrementsBecomeRatesAtTheMiddleOfTheirInterval) {
  const Exported& e = exported();
  EXPECT_EQ(e.report.imu_stream, "tanker.imu");
  EXPECT_EQ(e.report.imu_samples, 100u);
  auto rows = read_euroc_imu_csv(e.out + "/mav0/imu0/data.csv");
  ASSERT_TRUE(rows) << rows.error().message;
  ASSERT_EQ(rows->size(), 100u);
  for (int k = 0; k < 100; ++k) {
    const nav::ImuSample s = imu_sample(k);
    const EurocImuRow& r = (*rows)[static_cast<std::size_t>(k)];
    EXPECT_EQ(r.t_ns, s.t_ns - 2'500'000);
    EXPECT_NEAR((r.w_rad_s - s.dtheta_rad / s.dt_s).norm(), 0, 1e-12);
    EXPECT_NEAR((r.a_mps2 - s.dv_mps / s.dt_s).norm(), 0, 1e-12);
  }
  std::ifstream csv(e.out + "/mav0/imu0/data.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("#timestamp [ns],w_RS_S_x [rad s^-1],", 0), 0u) << header;
  EXPECT_NE(header.find("a_RS_S_z [m s^-2]"), std::string::npos) << header;
  const YAML::Node y = YAML::LoadFile(e.out + "/mav0/imu0/sensor.yaml");
  EXPECT_EQ(y["sensor_type"].as<std::string>(), "imu");
  EXPECT_DOUBLE_EQ(y["rate_hz"].as<double>(), 200.0);

  // EurocSource reads imu0 back, and turns the rates into increments again.
  auto src = EurocSource::open(e.out);
  ASSERT_TRUE(src);
  EXPECT_EQ((*src)->imu().size(), 100u);
  const auto inc = (*src)->imu_samples();
  ASSERT_EQ(inc.size(), 99u);
  EXPECT_EQ(inc[0].t_ns, (*rows)[1].t_ns);
  EXPECT_NEAR(inc[0].dt_s, 0.005, 1e-12);
  EXPECT_NEAR(inc[0].dtheta_rad.x(), 0.01 * 0.005, 1e-15);
}

TEST(EurocExport, PosesAndStatisticsCsv) {
  const Exported& e = exported();
  EXPECT_EQ(e.report.pose_rows, 2u * kFrames);
  auto poses = nav::read_camera_pose_csv(e.out + "/poses.csv");
  ASSERT_TRUE(poses) << poses.error().message;
  ASSERT_EQ(poses->rows.size(), 2u * kFrames);
  for (const nav::CameraPoseRow& p : poses->rows) {
    const FrameRecord want = frame(static_cast<int>(p.sequence));
    const Pose& T = *want.T_cam_receiver[static_cast<std::size_t>(p.camera)];
    EXPECT_EQ(p.t_ns, want.raw.t_key_ns);
    EXPECT_NEAR(p.z_m, T.translation_m.z(), 1e-12);
    EXPECT_NEAR(std::abs(p.qw * T.rotation.w() + p.qx * T.rotation.x() + p.qy * T.rotation.y() +
                         p.qz * T.rotation.z()),
                1.0, 1e-12);
    EXPECT_NEAR(p.boom_elevation_deg, 30.0, 1e-9);
    EXPECT_NEAR(p.sigma_pos_m, 0.05, 1e-15);
  }
  std::ifstream csv(e.out + "/stats.csv");
  std::string line;
  std::size_t lines = 0;
  while (std::getline(csv, line)) ++lines;
  EXPECT_EQ(lines, static_cast<std::size_t>(kFrames) + 1);
}

TEST(EurocExport, StatisticsPlotIsARealPicture) {
  const Exported& e = exported();
  if (find_gnuplot().empty())
    GTEST_SKIP() << "gnuplot is not installed (Debian: gnuplot-nox); the plot needs it";
  ASSERT_TRUE(e.report.plotted);
  const cv::Mat png = cv::imread(e.out + "/stats.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  EXPECT_EQ(png.cols, 1200);
  EXPECT_EQ(png.rows, 1100);  // three panels
  cv::Scalar mean, stddev;
  cv::meanStdDev(png, mean, stddev);
  EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 20.0) << "a uniform picture";
  // The curves' colours are there: blue (occluded % left) and red (right), in BGR.
  cv::Mat blue, red;
  cv::inRange(png, cv::Scalar(150, 90, 0), cv::Scalar(210, 140, 60), blue);
  cv::inRange(png, cv::Scalar(10, 10, 190), cv::Scalar(70, 70, 240), red);
  EXPECT_GT(cv::countNonZero(blue), 200);
  EXPECT_GT(cv::countNonZero(red), 100);
}

// The recorded phases: OUT/phases.csv on the export's clock, in time order, seconds from the
// first frame (negative: began before it); other events are not phases.
TEST(EurocExport, PhasesAreWrittenBesideTheStatistics) {
  const Exported& e = exported();
  EXPECT_EQ(e.report.phases, 2u);
  std::ifstream csv(fs::path(e.out) / "phases.csv");
  std::string header, a, b, extra;
  std::getline(csv, header);
  std::getline(csv, a);
  std::getline(csv, b);
  EXPECT_FALSE(std::getline(csv, extra));
  EXPECT_EQ(header, "#t_ns,t_s,phase");
  EXPECT_EQ(a, std::to_string(kT0 - 1'000'000'000) + ",-1.000000,pre-contact");
  char t_s[32];
  std::snprintf(t_s, sizeof t_s, "%.6f", 3 * kPeriod / 1e9);
  EXPECT_EQ(b, std::to_string(kT0 + 3 * kPeriod) + "," + t_s + ",contact");
}

TEST(EurocExport, PlotOfOneFrameAndOfGaps) {
  if (find_gnuplot().empty())
    GTEST_SKIP() << "gnuplot is not installed (Debian: gnuplot-nox); the plot needs it";
  const std::string dir = test::output_dir("euroc/plots");
  auto s = plot_occlusion_stats({frame(0).stats.value()}, dir + "/one.png");
  ASSERT_TRUE(s) << s.error().message;
  // No receiver at all in some frames (NaN percentages), and a whole column NaN.
  std::vector<OcclusionStats> stats;
  for (int i = 0; i < 6; ++i) {
    OcclusionStats o = frame(i).stats.value();
    if (i % 2) o.occluded_pct_left = std::numeric_limits<double>::quiet_NaN();
    o.occluded_pct_right = std::numeric_limits<double>::quiet_NaN();
    stats.push_back(o);
  }
  s = plot_occlusion_stats(stats, dir + "/gaps.png");
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_FALSE(cv::imread(dir + "/gaps.png").empty());
}

TEST(EurocExport, MissingGnuplotIsAClearError) {
  std::vector<OcclusionStats> stats = {frame(0).stats.value(), frame(1).stats.value()};
  const std::string out = test::output_dir("euroc/no_gnuplot") + "/stats.png";
  ::setenv("AUGRIG_GNUPLOT", "/nonexistent/gnuplot", 1);
  auto s = plot_occlusion_stats(stats, out);
  ::unsetenv("AUGRIG_GNUPLOT");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("$AUGRIG_GNUPLOT=/nonexistent/gnuplot) is not an executable file"),
            std::string::npos)
      << s.error().message;
  EXPECT_NE(s.error().message.find("apt-get install gnuplot-nox"), std::string::npos) << s.error().message;
  const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
  ::setenv("PATH", test::output_dir("euroc/empty_path").c_str(), 1);
  s = plot_occlusion_stats(stats, out);
  ::setenv("PATH", path.c_str(), 1);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("gnuplot is not installed"), std::string::npos) << s.error().message;
  s = plot_occlusion_stats({}, out);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("no statistics"), std::string::npos);
}

// A directory where the PNG should go is named as such, and left alone (an empty one used to be
// removed and replaced by the plot).
TEST(EurocExport, PlotPathThatIsADirectory) {
  const std::vector<OcclusionStats> stats = {frame(0).stats.value(), frame(1).stats.value()};
  const std::string out = test::output_dir("euroc/plot_dir") + "/stats.png";
  fs::create_directories(out);
  const auto s = plot_occlusion_stats(stats, out);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message,
            "recorder::plot_occlusion_stats(): " + out + ": is a directory, expected a file");
  EXPECT_TRUE(fs::is_directory(out));
}

TEST(EurocExport, ErrorsAndNotes) {
  const Exported& e = exported();
  auto rd = RecordingReader::open(e.recording);
  ASSERT_TRUE(rd);
  EurocExportReport r;
  auto st = export_euroc(**rd, e.out, {}, r);  // again into the same folder
  ASSERT_FALSE(st);
  EXPECT_NE(st.error().message.find("mav0: exists already"), std::string::npos) << st.error().message;

  const std::string norig = make_recording("no_rig", false);
  rd = RecordingReader::open(norig);
  ASSERT_TRUE(rd);
  st = export_euroc(**rd, test::output_dir("euroc/no_rig_out"), {}, r);
  ASSERT_FALSE(st);
  EXPECT_NE(st.error().message.find("the recording stores no rig"), std::string::npos) << st.error().message;
  // With a rig given, and without the optional streams.
  EurocExportOptions o;
  o.rig = small_rig();
  o.augmented = o.masks = o.plot = false;
  o.imu_stream = "tanker.gps";  // not IMU rows: a problem, the rest is exported
  const std::string out = test::output_dir("euroc/no_rig_out2");
  st = export_euroc(**rd, out, o, r);
  ASSERT_TRUE(st) << st.error().message;
  EXPECT_EQ(r.frames_written, static_cast<std::size_t>(kFrames));
  EXPECT_FALSE(fs::exists(out + "/mav0/cam0_augmented"));
  EXPECT_FALSE(fs::exists(out + "/mav0/imu0"));
  EXPECT_FALSE(fs::exists(out + "/stats.png"));
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_NE(r.problems[0].find("imu0 not exported"), std::string::npos) << r.problems[0];
}

// ---- Live-nav recordings, speed settings, progress, INCOMPLETE ------------------------------------

// A recording as `augrig run --nav` makes it: both aircraft's IMU as augrig IMU datagrams (BLOB, 4
// samples each) and GPS as NMEA lines, every row with t_ns 0, clock unknown and its host arrival;
// frames on each camera's device clock with their host times. The nav data are the demo scenario's
// first 12 s (sim/sensors.hpp); the host clock runs kHostMinusGps behind GPS time, the cameras'
// clocks kDeviceMinusGps[c] ahead of it.
constexpr TimestampNs kHostMinusGps = -1'400'000'000'000'000'000 + 5'000'000'000;
constexpr TimestampNs kDeviceMinusGps[2] = {1'200'000, 1'250'000};

struct LiveRecording {
  std::string dir;
  sim::SensorLogs logs;
  TimestampNs t0_gps_ns = 0;
};

const LiveRecording& live_recording() {
  static const LiveRecording rec = [] {
    LiveRecording out;
    out.dir = test::output_dir("euroc/live_" +
                               std::string(testing::UnitTest::GetInstance()->current_test_info()->name()));
    sim::Scenario sc = *sim::builtin_scenario("demo");
    sc.duration_s = 12;
    const sim::Flight flight = *sim::Flight::create(sc);
    out.logs = sim::simulate_sensors(sc, flight);
    RecordingInfo info;
    info.rig_yaml = rig_to_yaml(small_rig());
    info.extra["aircraft_yaml.tanker"] = pipeline::aircraft_config_to_yaml(pipeline::ins_config_for(sc.sensors.tanker));
    info.extra["aircraft_yaml.receiver"] = pipeline::aircraft_config_to_yaml(pipeline::ins_config_for(sc.sensors.receiver));
    auto r = Recorder::create(out.dir, info);
    EXPECT_TRUE(r) << r.error().message;
    auto push_imu = [&](const std::vector<nav::ImuSample>& imu, const std::string& stream) {
      for (std::size_t k = 0; k + 4 <= imu.size(); k += 4) {
        auto d = nav::encode_imu_datagram(std::span(imu).subspan(k, 4), k);
        ASSERT_TRUE(d) << d.error().message;
        NavInputRecord n;
        n.stream = stream;
        n.clock = ClockDomain::kUnknown;
        n.arrival_ns = imu[k + 3].t_ns + kHostMinusGps + 200'000;  // 0.2 ms on the way
        n.data.assign(reinterpret_cast<const char*>(d->data()), d->size());
        n.binary = true;
        (*r)->push(std::move(n));
      }
    };
    auto push_gps = [&](const std::vector<nav::GpsFix>& gps, const std::string& stream) {
      for (const nav::GpsFix& f : gps)
        for (const std::string& line : nav::nmea_sentences(f))
          (*r)->push(NavInputRecord{stream, 0, ClockDomain::kUnknown, f.t_ns + kHostMinusGps + 30'000'000, line, false});
    };
    push_imu(out.logs.tanker_imu, "tanker.imu");
    push_imu(out.logs.receiver_imu, "receiver.imu");
    push_gps(out.logs.tanker_gps, "tanker.gps");
    push_gps(out.logs.receiver_gps, "receiver.gps");
    out.t0_gps_ns = out.logs.tanker_imu.front().t_ns;
    for (int i = 0; i < kFrames; ++i) {
      FrameRecord f = frame(i);
      const TimestampNs t_gps = out.t0_gps_ns + 3'000'000'000 + i * 100'000'000;
      f.raw.t_key_ns = t_gps + kDeviceMinusGps[0];
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        Frame& fr = f.raw[id];
        fr.clock = ClockDomain::kDevice;
        fr.t_ns = t_gps + kDeviceMinusGps[index_of(id)];
        fr.t_host_ns = t_gps + kHostMinusGps + 1'000'000 * (i % 3);  // released 0..2 ms late
      }
      f.stats->t_ns = f.raw.t_key_ns;
      EXPECT_TRUE((*r)->push(std::move(f)));
    }
    EXPECT_TRUE((*r)->close());
    return out;
  }();
  return rec;
}

TEST(EurocExport, LiveNavRecordingImuDatagramsBitExactNavLogsFuse) {
  const LiveRecording& live = live_recording();
  auto rd = RecordingReader::open(live.dir);
  ASSERT_TRUE(rd) << rd.error().message;
  const std::string out = test::output_dir("euroc/live_out");
  EurocExportOptions o;
  o.plot = false;
  EurocExportReport r;
  ASSERT_TRUE(export_euroc(**rd, out, o, r));
  EXPECT_TRUE(r.problems.empty()) << r.problems.front();
  EXPECT_FALSE(fs::exists(out + "/INCOMPLETE"));
  EXPECT_EQ(r.clock, ClockDomain::kGps);
  EXPECT_EQ(r.imu_stream, "tanker.imu");
  const std::size_t whole = live.logs.tanker_imu.size() / 4 * 4;  // whole datagrams
  ASSERT_EQ(r.imu_samples, whole);

  // imu0: each datagram sample's mean rates, bit-exact, at the middle of its interval.
  auto imu0 = read_euroc_imu_csv(out + "/mav0/imu0/data.csv");
  ASSERT_TRUE(imu0) << imu0.error().message;
  ASSERT_EQ(imu0->size(), whole);
  for (std::size_t k = 0; k < whole; ++k) {
    const nav::ImuSample& s = live.logs.tanker_imu[k];
    const EurocImuRow& row = (*imu0)[k];
    EXPECT_EQ(row.t_ns, s.t_ns - s_to_ns(0.5 * s.dt_s));
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(row.w_rad_s[a], s.dtheta_rad[a] / s.dt_s) << k;
      EXPECT_EQ(row.a_mps2[a], s.dv_mps[a] / s.dt_s) << k;
    }
  }

  // The frames on GPS time: device time minus the camera's offset, to within the host release
  // jitter the lower envelope removes (the envelope's minimum is an exact release here).
  auto index = nav::read_frame_index_csv(out + "/frames.csv");
  ASSERT_TRUE(index) << index.error().message;
  EXPECT_EQ(index->clock, ClockDomain::kGps);
  ASSERT_EQ(index->rows.size(), 2u * kFrames);
  for (const nav::FrameIndexRow& row : index->rows) {
    const TimestampNs want = live.t0_gps_ns + 3'000'000'000 + static_cast<TimestampNs>(row.sequence) * 100'000'000;
    EXPECT_NEAR(static_cast<double>(row.t_ns - want), 0.0, 250'000.0) << row.sequence;  // the 0.2 ms IMU delay
    EXPECT_TRUE(fs::exists(out + "/" + row.file)) << row.file;
  }

  // Each aircraft's logs read back through the nav readers and fuse.
  for (const char* who : {"tanker", "receiver"}) {
    auto logs = pipeline::load_aircraft_logs(out + "/nav/" + who);
    ASSERT_TRUE(logs) << logs.error().message;
    const auto& want_imu = std::string(who) == "tanker" ? live.logs.tanker_imu : live.logs.receiver_imu;
    const auto& want_gps = std::string(who) == "tanker" ? live.logs.tanker_gps : live.logs.receiver_gps;
    ASSERT_EQ(logs->imu.size(), want_imu.size() / 4 * 4) << who;
    for (std::size_t k = 0; k < logs->imu.size(); ++k) {
      EXPECT_EQ(logs->imu[k].t_ns, want_imu[k].t_ns);
      EXPECT_EQ(logs->imu[k].dt_s, want_imu[k].dt_s);
      EXPECT_EQ(logs->imu[k].dtheta_rad, want_imu[k].dtheta_rad);
      EXPECT_EQ(logs->imu[k].dv_mps, want_imu[k].dv_mps);
    }
    ASSERT_EQ(logs->gps.size(), want_gps.size()) << who;
    for (std::size_t k = 0; k < logs->gps.size(); ++k) {
      EXPECT_EQ(logs->gps[k].t_ns, want_gps[k].t_ns);
      EXPECT_EQ(logs->gps[k].arrival_ns, want_gps[k].t_ns + kHostMinusGps + 30'000'000);
    }
    // aircraft.yaml is the recording's (meta aircraft_yaml.<aircraft>): the surveyed lever arm.
    EXPECT_GT(logs->config.lever_arm_body_m.norm(), 0.5) << who;
    auto fused = nav::fuse(logs->imu, logs->gps, logs->config, true);
    ASSERT_TRUE(fused) << fused.error().message;
    EXPECT_GT(fused->report().fixes_used, want_gps.size() / 2) << who;
  }
}

// Every PNG setting and thread count gives the recorded pixels back; the progress callback's
// counts add up and its last call is the whole recording.
TEST(EurocExport, EverySpeedSettingIsLosslessAndProgressAddsUp) {
  const Exported& e = exported();
  auto rd = RecordingReader::open(e.recording);
  ASSERT_TRUE(rd);
  for (int level : {0, 1, 6}) {
    for (int threads : {1, 3}) {
      const std::string out =
          test::output_dir("euroc/speed_" + std::to_string(level) + "_" + std::to_string(threads));
      EurocExportOptions o;
      o.plot = false;
      o.png_compression = level;
      o.threads = threads;
      o.progress_interval_s = 0;  // every frame
      std::vector<EurocExportProgress> calls;
      o.progress = [&](const EurocExportProgress& p) { calls.push_back(p); };
      EurocExportReport r;
      ASSERT_TRUE(export_euroc(**rd, out, o, r));
      ASSERT_FALSE(calls.empty());
      std::size_t last = 0;
      for (const EurocExportProgress& p : calls) {
        EXPECT_EQ(p.frames_done, p.frames_written + p.frames_skipped);
        EXPECT_EQ(p.frames_total, static_cast<std::size_t>(kFrames));
        EXPECT_GE(p.frames_done, last);
        last = p.frames_done;
      }
      EXPECT_TRUE(calls.back().final);
      EXPECT_EQ(calls.back().frames_done, static_cast<std::size_t>(kFrames));
      for (const char* s : {"cam0", "cam0_augmented", "cam1_mask"}) {
        EurocOptions eo;
        eo.left_stream = s;
        eo.right_stream = s;
        const auto frames = read_all(out, eo);
        ASSERT_EQ(frames.size(), 2u * kFrames) << s;
        for (int i = 0; i < kFrames; ++i) {
          const FrameRecord want = frame(i);
          const Image& w = std::string(s) == "cam0"             ? want.raw.left.image
                           : std::string(s) == "cam0_augmented" ? want.augmented[0]
                                                                : want.mask[1];
          EXPECT_TRUE(pixels_equal(frames[static_cast<std::size_t>(2 * i)].image, w))
              << s << " frame " << i << " level " << level << " threads " << threads;
        }
      }
    }
  }
}

// OUT/INCOMPLETE: gone after a clean export; kept, listing the problem, after a damaged frame.
TEST(EurocExport, IncompleteMarker) {
  const Exported& e = exported();
  EXPECT_FALSE(fs::exists(e.out + "/INCOMPLETE"));
  const std::string dir = test::output_dir("euroc/damaged");
  fs::copy_file(e.recording + "/recording.sqlite", dir + "/recording.sqlite", fs::copy_options::overwrite_existing);
  {
    auto db = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(db);
    ASSERT_TRUE(db->exec("UPDATE frames SET left_raw = CAST(substr(left_raw, 1, 100) || x'00' || "
                         "substr(left_raw, 102) AS BLOB) WHERE pair_sequence = 3"));
  }
  auto rd = RecordingReader::open(dir);
  ASSERT_TRUE(rd);
  const std::string out = test::output_dir("euroc/damaged_out");
  EurocExportOptions o;
  o.plot = false;
  EurocExportReport r;
  ASSERT_TRUE(export_euroc(**rd, out, o, r));
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_EQ(r.frames_written, static_cast<std::size_t>(kFrames - 1));
  std::ifstream m(out + "/INCOMPLETE");
  ASSERT_TRUE(m);
  const std::string text((std::istreambuf_iterator<char>(m)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("frame 3"), std::string::npos) << text;
}

}  // namespace
}  // namespace augrig::recorder
