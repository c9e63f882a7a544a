// EurocSource (recorder/euroc_source.hpp) on datasets written by hand: a foreign dataset
// (OpenCV's %YAML:1.0 header, unpaired and missing images) plays; tolerance pairing and the gray
// format; a part of a dataset (start, end, the dataset's time origin) and its capabilities;
// sensor.yaml optional but not a directory; imu0 rows as trapezoid increments; CSV errors name the
// file and line. (An augrig export played back: tests/recorder/euroc_test.cpp.)
#include "recorder/euroc_source.hpp"

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// test::output_dir("euroc/" + name) holding a dataset of `pairs` stereo pairs, both cameras'
// images at t = 1000 + 100 k ns: 6 x 4 gray PNGs of value k. Returns that folder.
std::string write_dataset(const std::string& name, int pairs) {
  const std::string root = test::output_dir("euroc/" + name);
  const fs::path mav0 = fs::path(root) / "mav0";
  for (const char* cam : {"cam0", "cam1"}) {
    fs::create_directories(mav0 / cam / "data");
    std::ofstream csv(mav0 / cam / "data.csv");
    csv << "#timestamp [ns],filename\n";
    for (int i = 0; i < pairs; ++i) {
      const TimestampNs t = 1000 + 100 * i;
      cv::imwrite((mav0 / cam / "data" / (std::to_string(t) + ".png")).string(),
                  cv::Mat(4, 6, CV_8UC1, cv::Scalar(i)));
      csv << t << "," << t << ".png\n";
    }
  }
  return root;
}

// A dataset as others write it: OpenCV's "%YAML:1.0" header, a frame only one camera has, a
// listed image that is missing, 8-bit gray PNGs.
TEST(EurocSource, ForeignDatasetWithUnpairedAndMissingImages) {
  const std::string root = test::output_dir("euroc/foreign");
  const fs::path mav0 = fs::path(root) / "mav0";
  for (const char* cam : {"cam0", "cam1"}) {
    fs::create_directories(mav0 / cam / "data");
    std::ofstream(mav0 / cam / "sensor.yaml") << "%YAML:1.0\nsensor_type: camera\nrate_hz: 20\n";
  }
  std::ofstream c0(mav0 / "cam0/data.csv"), c1(mav0 / "cam1/data.csv");
  c0 << "#timestamp [ns],filename\r\n";
  c1 << "#timestamp [ns],filename\n";
  std::vector<cv::Mat> written;
  for (int i = 0; i < 5; ++i) {
    const TimestampNs t = 1000 + 100 * i;
    cv::Mat m(12, 16, CV_8UC1, cv::Scalar(10 * i));
    m.at<std::uint8_t>(3, 4) = 255;
    cv::imwrite((mav0 / "cam0/data" / (std::to_string(t) + ".png")).string(), m);
    c0 << t << ", " << t << ".png\r\n";
    if (i == 2) continue;  // cam1 lacks frame 2
    if (i != 3)
      cv::imwrite((mav0 / "cam1/data" / (std::to_string(t) + ".png")).string(), m);  // frame 3 missing
    c1 << t << "," << t << ".png\n";
  }
  c1 << 5000 << "," << 5000 << ".png\n";  // an image cam0 does not have
  c0.close();
  c1.close();

  auto src = EurocSource::open(root);
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_EQ((*src)->pair_count(), 4u);
  EXPECT_EQ((*src)->unpaired(), 2u);
  EXPECT_TRUE((*src)->imu().empty());
  std::vector<TimestampNs> times;
  std::vector<std::string> errors;
  Frame f;
  for (;;) {
    auto st = (*src)->read(f, 0ns);
    if (!st) {
      errors.push_back(st.error().message);
      continue;
    }
    if (*st == ReadStatus::kEndOfStream) break;
    EXPECT_EQ(f.image.format(), PixelFormat::kMono8);
    EXPECT_EQ(f.clock, ClockDomain::kUnknown);
    EXPECT_EQ(f.image.row(3)[4], 255);
    times.push_back(f.t_ns);
  }
  EXPECT_EQ(times, (std::vector<TimestampNs>{1000, 1000, 1100, 1100, 1400, 1400}));
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("cam1/data/1300.png: no such file"), std::string::npos) << errors[0];
  EXPECT_EQ((*src)->frames_dropped(), 4u);

  // A tolerance pairs skewed timestamps; errors name the file and line.
  std::ofstream(mav0 / "cam1/data.csv") << "#timestamp [ns],filename\n1003,1000.png\n1097,1100.png\n";
  EurocOptions o;
  o.pair_tolerance_ns = 5;
  o.gray_format = PixelFormat::kBayerGR8;
  src = EurocSource::open("euroc://" + root, o);
  ASSERT_TRUE(src);
  EXPECT_EQ((*src)->pair_count(), 2u);
  ASSERT_TRUE((*src)->read(f, 0ns));
  EXPECT_EQ(f.image.format(), PixelFormat::kBayerGR8);
  std::ofstream(mav0 / "cam1/data.csv") << "#timestamp [ns],filename\n1003,1000.png\nabc,x.png\n";
  auto bad = EurocSource::open(root);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("cam1/data.csv:3: timestamp: expected whole nanoseconds, got 'abc'"),
            std::string::npos)
      << bad.error().message;
  bad = EurocSource::open(test::output_dir("euroc/not_a_dataset"));
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("not a EuRoC/ASL dataset"), std::string::npos) << bad.error().message;
}

// A part of a dataset, as a campaign plays it: where it starts in the dataset, the dataset's time
// origin whatever the start, and an end.
TEST(EurocSource, StartEndAndTheDatasetsFirstTime) {
  const std::string root = write_dataset("range", 6);
  EurocOptions o;
  o.start_pair = 2;
  auto src = EurocSource::open(root, o);
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_EQ((*src)->start_pair(), 2u);
  EXPECT_EQ((*src)->first_t_ns(), std::optional<TimestampNs>(1000));  // pair 0's, not the start's
  EXPECT_EQ((*src)->pair_count(), 4u);
  auto bad = (*src)->set_end_pair(2);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("recorder::EurocSource::set_end_pair(): "), std::string::npos);
  EXPECT_NE(bad.error().message.find("the end (pair 2) is not after the start (pair 2)"), std::string::npos)
      << bad.error().message;
  ASSERT_TRUE((*src)->set_end_pair(4));
  EXPECT_EQ((*src)->pair_count(), 2u);
  ASSERT_TRUE((*src)->set_end_pair(100));  // past the end: nothing changes
  EXPECT_EQ((*src)->pair_count(), 2u);
  std::vector<std::pair<TimestampNs, std::uint64_t>> read;  // (t_ns, sequence) of the left Frames
  Frame f;
  for (;;) {
    auto st = (*src)->read(f, 0ns);
    ASSERT_TRUE(st) << st.error().message;
    if (*st == ReadStatus::kEndOfStream) break;
    if (f.camera == CameraId::kLeft) read.emplace_back(f.t_ns, f.sequence);
  }
  // Pair k of the part is the dataset's pair start_pair() + k.
  EXPECT_EQ(read, (std::vector<std::pair<TimestampNs, std::uint64_t>>{{1200, 0}, {1300, 1}}));
  o = {};
  o.start_offset_ns = 250;  // the first pair 250 ns or more after pair 0: pair 3
  src = EurocSource::open(root, o);
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_EQ((*src)->start_pair(), 3u);
  EXPECT_EQ((*src)->first_t_ns(), std::optional<TimestampNs>(1000));
}

// A EuRoC folder's range as capabilities: where it starts, its time origin, an end.
TEST(EurocSource, CapabilitiesAreARange) {
  const std::string root = write_dataset("capabilities", 12);
  EurocOptions o;
  o.start_pair = 3;
  auto s = EurocSource::open("euroc://" + root, o);
  ASSERT_TRUE(s) << s.error().message;
  FrameSource& src = **s;
  EXPECT_TRUE(src.capabilities().finite && src.capabilities().ranged);
  EXPECT_FALSE(src.capabilities().seekable);
  EXPECT_EQ(src.range_start(), 3u);
  EXPECT_EQ(src.origin_t_ns(), std::optional<TimestampNs>(1000))
      << "the folder's first pair, whatever the start";
  EXPECT_EQ(src.pair_count(), 9u);
  ASSERT_TRUE(src.set_range_end(7));
  EXPECT_EQ(src.pair_count(), 4u);
}

// sensor.yaml is optional, but a directory in its place is named, not read as an empty file.
TEST(EurocSource, SensorYamlThatIsADirectory) {
  const std::string root = test::output_dir("euroc/sensor_yaml_dir");
  const fs::path mav0 = fs::path(root) / "mav0";
  for (const char* cam : {"cam0", "cam1"}) {
    fs::create_directories(mav0 / cam);
    std::ofstream(mav0 / cam / "data.csv") << "#timestamp [ns],filename\n";
  }
  ASSERT_TRUE(EurocSource::open(root));  // no sensor.yaml: fine
  fs::create_directories(mav0 / "cam1/sensor.yaml");
  const auto bad = EurocSource::open(root);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, "recorder::EurocSource::open(): " + (mav0 / "cam1/sensor.yaml").string() +
                                     ": is a directory, expected a file");
}

TEST(EurocSource, ImuIncrementsAreTrapezoids) {
  std::vector<EurocImuRow> rows(3);
  for (int k = 0; k < 3; ++k) {
    rows[static_cast<std::size_t>(k)].t_ns = 1'000'000'000 + k * 10'000'000;
    rows[static_cast<std::size_t>(k)].w_rad_s = Eigen::Vector3d(k, 0, 0);
    rows[static_cast<std::size_t>(k)].a_mps2 = Eigen::Vector3d(0, 0, -9.81 + k);
  }
  const auto s = imu_increments(rows);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[1].t_ns, rows[2].t_ns);
  EXPECT_NEAR(s[1].dt_s, 0.01, 1e-15);
  EXPECT_NEAR(s[1].dtheta_rad.x(), 1.5 * 0.01, 1e-15);
  EXPECT_NEAR(s[1].dv_mps.z(), (-9.81 + 1.5) * 0.01, 1e-15);
}

// Timestamps whose intervals would overflow int64 are rejected by line (imu_increments() takes
// their differences); a directory where data.csv should be is named as such.
TEST(EurocSource, ImuCsvTimesOutOfRangeAndDirectories) {
  const std::string dir = test::output_dir("euroc/imu_range");
  const std::string path = dir + "/data.csv";
  std::ofstream(path) << "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n"
                      << "-9000000000000000000,0,0,0,0,0,0\n9000000000000000000,0,0,0,0,0,0\n";
  auto rows = read_euroc_imu_csv(path);
  ASSERT_FALSE(rows);
  EXPECT_NE(rows.error().message.find(path + ":2: timestamp: expected a time in -4e18..4e18 ns"),
            std::string::npos)
      << rows.error().message;
  std::filesystem::create_directories(dir + "/imu.csv");
  rows = read_euroc_imu_csv(dir + "/imu.csv");
  ASSERT_FALSE(rows);
  EXPECT_EQ(rows.error().message,
            "recorder::read_euroc_imu_csv(): " + dir + "/imu.csv: is a directory, expected a file");
  auto cams = read_euroc_camera_csv(dir + "/imu.csv");
  ASSERT_FALSE(cams);
  EXPECT_NE(cams.error().message.find("is a directory, expected a file"), std::string::npos);
}

}  // namespace
}  // namespace augrig::recorder
