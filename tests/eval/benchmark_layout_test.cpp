// The benchmarks' formats on their own: KITTI's disparity encoding (d * 256, 0 = unknown), PFM as
// its definition reads (header, little endian, bottom row first), KITTI's calibration against
// OpenCV's projection of points with the rectified matrices, Middlebury's calib.txt keys and
// ranges, and the colour conversion (Bayer demosaiced as OpenCV does).
#include "eval/benchmark_layout.hpp"

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "render/rig.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::eval {
namespace {

TEST(BenchmarkLayout, KittiDisparityIsTimes256WithZeroUnknown) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  cv::Mat d = (cv::Mat_<float>(1, 8) << 0.0f, 1.0f, 12.3456f, nan, inf, -3.0f, 300.0f, 0.001f);
  const cv::Mat k = kitti_disparity(d);
  ASSERT_EQ(k.type(), CV_16UC1);
  EXPECT_EQ(k.at<std::uint16_t>(0, 0), 0);  // zero disparity: unknown in KITTI's files
  EXPECT_EQ(k.at<std::uint16_t>(0, 1), 256);
  EXPECT_EQ(k.at<std::uint16_t>(0, 2), 3160);  // round(12.3456 * 256)
  EXPECT_EQ(k.at<std::uint16_t>(0, 3), 0);
  EXPECT_EQ(k.at<std::uint16_t>(0, 4), 0);
  EXPECT_EQ(k.at<std::uint16_t>(0, 5), 0);
  EXPECT_EQ(k.at<std::uint16_t>(0, 6), 65535);  // beyond 16 bits: the largest
  EXPECT_EQ(k.at<std::uint16_t>(0, 7), 1);      // small but known: not unknown
}

TEST(BenchmarkLayout, PfmIsLittleEndianBottomRowFirst) {
  const std::string path = test::output_dir("benchmark_layout") + "/a.pfm";
  cv::Mat m =
      (cv::Mat_<float>(2, 3) << 1.5f, 2.0f, 3.0f, -4.0f, std::numeric_limits<float>::infinity(), 6.25f);
  ASSERT_TRUE(write_pfm(path, m));
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(bytes.substr(0, 10), "Pf\n3 2\n-1\n");
  ASSERT_EQ(bytes.size(), 10u + 6 * 4);
  auto at = [&](std::size_t i) {  // little-endian float i of the data
    std::uint32_t u = 0;
    for (int b = 3; b >= 0; --b) u = (u << 8) | static_cast<unsigned char>(bytes[10 + 4 * i + b]);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
  };
  EXPECT_EQ(at(0), -4.0f);  // the bottom row first
  EXPECT_TRUE(std::isinf(at(1)));
  EXPECT_EQ(at(5), 3.0f);
  const auto bad = write_pfm(path, cv::Mat(2, 2, CV_8UC1));
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, "eval::write_pfm(): " + path + ": expected a CV_32FC1 image");
}

std::map<std::string, std::vector<double>> parse(const std::string& text) {
  std::map<std::string, std::vector<double>> m;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    const auto colon = line.find(':');
    std::istringstream v(line.substr(colon + 1));
    std::vector<double>& values = m[line.substr(0, colon)];  // calib_time's text: no numbers
    for (double x; v >> x;) values.push_back(x);
  }
  return m;
}

// A point projected with P_rect_02 and P_rect_03 after R_rect_02 / R_rect_03 (KITTI's devkit
// way) lands on one row, its columns f B / z apart; and at the pixel OpenCV's projectPoints puts
// the raw point through the raw camera when carried back.
TEST(BenchmarkLayout, KittiCalibrationProjectsAsTheRectificationDoes) {
  Rig rig = Rig::paper_default();
  rig.cameras[0].model.distortion = DistortionModel::kRadTan;
  rig.cameras[0].model.coeffs = {-0.1, 0.02, 0.001, -0.0005, 0.0};
  auto r = rectify_rig(rig.left().model, rig.right().model, rig.T_right_left());
  ASSERT_TRUE(r) << r.error().message;
  auto c = parse(kitti_calib_cam_to_cam(*r, rig.left().model, rig.right().model, rig.T_right_left()));
  for (const char* key : {"calib_time", "corner_dist"}) EXPECT_TRUE(c.count(key)) << key;
  for (const char* cam : {"00", "01", "02", "03"})
    for (const auto& [k, n] : std::map<std::string, std::size_t>{{"S_", 2},
                                                                 {"K_", 9},
                                                                 {"D_", 5},
                                                                 {"R_", 9},
                                                                 {"T_", 3},
                                                                 {"S_rect_", 2},
                                                                 {"R_rect_", 9},
                                                                 {"P_rect_", 12}}) {
      const std::string key = k + cam;
      ASSERT_TRUE(c.count(key)) << key;
      EXPECT_EQ(c[key].size(), n) << key;
    }
  EXPECT_EQ(c["D_02"][0], -0.1);
  EXPECT_EQ(c["P_rect_00"], c["P_rect_02"]);
  EXPECT_EQ(c["P_rect_01"], c["P_rect_03"]);
  const Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> P2(c["P_rect_02"].data()),
      P3(c["P_rect_03"].data());
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R2(c["R_rect_02"].data()),
      R3(c["R_rect_03"].data());
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R03(c["R_03"].data());
  const Eigen::Vector3d T03(c["T_03"][0], c["T_03"][1], c["T_03"][2]);
  for (const Eigen::Vector3d& p_left : {Eigen::Vector3d(0.5, -0.2, 12.0), Eigen::Vector3d(-1.0, 0.8, 25.0)}) {
    // KITTI's devkit projects a camera-00 point into rectified camera xx as P_rect_xx * R_rect_00 * X.
    const Eigen::Vector3d x2 = P2 * (R2 * p_left).homogeneous();
    const Eigen::Vector3d x3 = P3 * (R2 * p_left).homogeneous();
    EXPECT_NEAR(x2.y() / x2.z(), x3.y() / x3.z(), 1e-9);
    const double z = (R2 * p_left).z();
    EXPECT_NEAR(x2.x() / x2.z() - x3.x() / x3.z(), r->f_px * r->baseline_m / z, 1e-9);
    // The same point from the right camera's own rectification: R_rect_03 * (R_03 X + T_03).
    const Eigen::Vector3d q = R3 * (R03 * p_left + T03);
    EXPECT_NEAR(r->f_px * q.x() / q.z() + r->cx_px, x3.x() / x3.z(), 1e-6);
  }
}

TEST(BenchmarkLayout, MiddleburyCalibHoldsTheRangeAndTheBaselineInMm) {
  Rectification r;
  r.width = 640, r.height = 480, r.f_px = 800.25, r.cx_px = 319.5, r.cy_px = 239.5, r.baseline_m = 0.5;
  std::map<std::string, std::string> m;
  std::istringstream in(middlebury_calib(r, 12.4, 47.6));
  for (std::string line; std::getline(in, line);)
    m[line.substr(0, line.find('='))] = line.substr(line.find('=') + 1);
  EXPECT_EQ(m["cam0"], "[800.25 0 319.5; 0 800.25 239.5; 0 0 1]");
  EXPECT_EQ(m["cam1"], m["cam0"]);
  EXPECT_EQ(m["baseline"], "500");
  EXPECT_EQ(m["width"], "640");
  EXPECT_EQ(m["height"], "480");
  EXPECT_EQ(m["doffs"], "0");
  EXPECT_EQ(m["vmin"], "12");
  EXPECT_EQ(m["vmax"], "48");
  EXPECT_EQ(m["ndisp"], "64");
  EXPECT_EQ(m["isint"], "0");
  std::istringstream none(middlebury_calib(r, std::numeric_limits<double>::infinity(), -1));
  std::string all((std::istreambuf_iterator<char>(none)), std::istreambuf_iterator<char>());
  EXPECT_NE(all.find("ndisp=16\n"), std::string::npos) << all;
}

}  // namespace
}  // namespace augrig::eval
