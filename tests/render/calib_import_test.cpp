// Calibration importers: OpenCV FileStorage (files written by cv::FileStorage here and one
// hand-written sample), ROS camera_info pairs (synthesised with cv::stereoRectify from a known
// extrinsic) and Kalibr camchains; bad files give errors naming file, line/key and expectation.
#include "render/calib_import.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

// Ground truth of the sample files in tests/data/calib.
Pose sample_T_right_left() {
  cv::Mat R;
  cv::Rodrigues(cv::Vec3d(0.01, -0.02, 0.005), R);
  Eigen::Matrix3d Re;
  for (int i = 0; i < 9; ++i) Re(i / 3, i % 3) = R.at<double>(i / 3, i % 3);
  return Pose::from(Re, {-0.5, 0.003, -0.002});
}

void expect_pose_near(const Pose& a, const Pose& b, double tol) {
  EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), tol) << "\n"
                                                                  << a.matrix() << "\nvs\n"
                                                                  << b.matrix();
}

std::string write_text(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

// 1-based number of the nth line starting with `prefix` in a file (to check error positions).
int line_of(const std::string& path, const std::string& prefix, int nth = 1) {
  std::ifstream in(path);
  std::string l;
  for (int n = 1; std::getline(in, l); ++n) {
    if (l.rfind(prefix, 0) == 0 && --nth == 0) return n;
  }
  return -1;
}

void expect_error(const Expected<StereoCalibration>& r, const std::vector<std::string>& fragments) {
  ASSERT_FALSE(r) << "expected an error";
  for (const auto& f : fragments)
    EXPECT_NE(r.error().message.find(f), std::string::npos) << r.error().message << "\nmissing: " << f;
}

cv::Mat K_of(double fx, double fy, double cx, double cy) {
  return (cv::Mat_<double>(3, 3) << fx, 0, cx, 0, fy, cy, 0, 0, 1);
}

TEST(CalibImport, OpenCVHandWrittenSample) {
  const auto c = import_opencv_stereo(test::data_path("calib/opencv_stereo.yml"));
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->format, "opencv");
  EXPECT_EQ(c->left.width_px, 1280);
  EXPECT_EQ(c->left.height_px, 960);
  EXPECT_EQ(c->right.width_px, 1280);
  EXPECT_DOUBLE_EQ(c->left.fx_px, 1210.5);
  EXPECT_DOUBLE_EQ(c->left.fy_px, 1208.9);
  EXPECT_DOUBLE_EQ(c->left.cx_px, 642.3);
  EXPECT_DOUBLE_EQ(c->left.cy_px, 481.7);
  EXPECT_EQ(c->left.distortion, DistortionModel::kRadTan);
  EXPECT_DOUBLE_EQ(c->left.coeffs[2], 8e-4);
  EXPECT_DOUBLE_EQ(c->left.coeffs[4], -0.01);
  EXPECT_DOUBLE_EQ(c->right.fx_px, 1205.1);
  EXPECT_DOUBLE_EQ(c->right.coeffs[4], -0.008);  // first 5 of the 8-element D2
  expect_pose_near(c->T_right_left, sample_T_right_left(), 1e-12);
}

struct OpenCVFile {
  std::string k1 = "M1", k2 = "M2";
  cv::Mat D1 = (cv::Mat_<double>(1, 5) << -0.2, 0.07, 1e-3, -2e-4, -0.01);
  cv::Mat D2 = (cv::Mat_<double>(5, 1) << -0.19, 0.06, -3e-4, 5e-4, -0.02);
  cv::Mat R;
  cv::Mat T = (cv::Mat_<double>(3, 1) << -0.48, 0.01, 0.004);
  int size_style = 0;  // 0: image_width/height, 1: imageSize (cv::Size), 2: none
  bool write_R = true, write_T = true;
};

std::string write_opencv(const std::string& path, const OpenCVFile& f) {
  cv::FileStorage fs(path, cv::FileStorage::WRITE);
  if (f.size_style == 0) {
    fs << "image_width" << 1280 << "image_height" << 960;
  } else if (f.size_style == 1) {
    fs << "imageSize" << cv::Size(1280, 960);
  }
  fs << f.k1 << K_of(1100.5, 1099.25, 650.75, 470.125) << "D1" << f.D1;
  fs << f.k2 << K_of(1101.0, 1100.0, 630.0, 480.0) << "D2" << f.D2;
  cv::Mat R = f.R;
  if (R.empty()) cv::Rodrigues(cv::Vec3d(-0.004, 0.03, 0.002), R);
  if (f.write_R) fs << "R" << R;
  if (f.write_T) fs << "T" << f.T;
  fs.release();
  return path;
}

TEST(CalibImport, OpenCVWrittenByFileStorage) {
  const std::string dir = test::output_dir("calib_opencv");
  for (const std::string ext : {".yml", ".yaml", ".xml"}) {
    for (int style : {0, 1}) {
      SCOPED_TRACE(ext + " size style " + std::to_string(style));
      OpenCVFile f;
      f.size_style = style;
      if (style == 1) {
        f.k1 = "K1";
        f.k2 = "K2";
        f.D2 = (cv::Mat_<double>(1, 14) << -0.19, 0.06, -3e-4, 5e-4, -0.02, 0, 0, 0, 0, 0, 0, 0, 0, 0);
      }
      const std::string path = write_opencv(dir + "/stereo" + std::to_string(style) + ext, f);
      const auto c = import_opencv_stereo(path);
      ASSERT_TRUE(c) << c.error().message;
      EXPECT_EQ(c->left.width_px, 1280);
      EXPECT_EQ(c->left.height_px, 960);
      EXPECT_DOUBLE_EQ(c->left.fx_px, 1100.5);
      EXPECT_DOUBLE_EQ(c->left.fy_px, 1099.25);
      EXPECT_DOUBLE_EQ(c->left.cx_px, 650.75);
      EXPECT_DOUBLE_EQ(c->left.cy_px, 470.125);
      EXPECT_DOUBLE_EQ(c->right.cx_px, 630.0);
      for (int i = 0; i < 5; ++i) {
        EXPECT_DOUBLE_EQ(c->left.coeffs[i], f.D1.at<double>(i));
        EXPECT_DOUBLE_EQ(c->right.coeffs[i], f.D2.at<double>(i));
      }
      cv::Mat R;
      cv::Rodrigues(cv::Vec3d(-0.004, 0.03, 0.002), R);
      Eigen::Matrix3d Re;
      for (int i = 0; i < 9; ++i) Re(i / 3, i % 3) = R.at<double>(i / 3, i % 3);
      expect_pose_near(c->T_right_left, Pose::from(Re, {-0.48, 0.01, 0.004}), 1e-12);
      // Auto-detection picks the OpenCV importer.
      const auto a = import_calibration("auto", path);
      ASSERT_TRUE(a) << a.error().message;
      EXPECT_EQ(a->format, "opencv");
    }
  }
}

TEST(CalibImport, OpenCVImageSizeFromArguments) {
  const std::string dir = test::output_dir("calib_opencv_size");
  OpenCVFile f;
  f.size_style = 2;
  const std::string path = write_opencv(dir + "/nosize.yml", f);
  expect_error(import_opencv_stereo(path), {"calib::import_opencv_stereo(): " + path, "image size"});
  const auto c = import_opencv_stereo(path, 640, 480);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->right.width_px, 640);
  EXPECT_EQ(c->right.height_px, 480);
}

// Image sizes are range-checked as numbers before they become ints (1e10 was undefined behaviour).
TEST(CalibImport, OpenCVHugeImageSizes) {
  const std::string dir = test::output_dir("calib_opencv_huge");
  std::ifstream in(test::data_path("calib/opencv_stereo.yml"));
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string good = ss.str();
  const auto with = [&](const std::string& to, const std::string& name) {
    std::string t = good;
    const std::string from = "imageSize: [ 1280, 960 ]";
    t.replace(t.find(from), from.size(), to);
    return write_text(dir + "/" + name, t);
  };
  const std::string a = with("imageSize: [ 1e10, 960 ]", "image_size.yml");
  expect_error(import_opencv_stereo(a), {a + ":5: key 'imageSize'", "in 1..32768", "got [1e+10, 960]"});
  const std::string b = with("image_width: 1e10\nimage_height: 960", "width_real.yml");
  expect_error(import_opencv_stereo(b), {b + ":5: key 'image_width'", "an integer in 1..32768"});
  const std::string c = with("image_width: 1280\nimage_height: 99999", "height_big.yml");
  expect_error(import_opencv_stereo(c),
               {c + ":6: key 'image_height'", "an integer in 1..32768", "got 99999"});
  // A matrix whose header asks for 2e9 columns: OpenCV allocated 48 GB for it (fuzz/fuzz_calib).
  for (const char* dims : {"rows: 3\n   cols: 2000000000", "rows: 3\n   cols: 4", "rows: -3\n   cols: 3"}) {
    std::string t = good;
    const std::string from = "rows: 3\n   cols: 3";
    t.replace(t.find(from), from.size(), dims);
    const std::string p = write_text(dir + "/matrix_dims.yml", t);
    expect_error(import_opencv_stereo(p),
                 {p + ":6: key 'M1'", "1..64 rows and cols with rows x cols numbers"});
  }
}

TEST(CalibImport, OpenCVErrors) {
  const std::string dir = test::output_dir("calib_opencv_errors");
  {
    OpenCVFile f;
    f.D2 = (cv::Mat_<double>(1, 14) << -0.19, 0.06, -3e-4, 5e-4, -0.02, 0, 0, 0.001, 0, 0, 0, 0, 0, 0);
    const std::string path = write_opencv(dir + "/thinprism.yml", f);
    expect_error(import_opencv_stereo(path),
                 {path + ":" + std::to_string(line_of(path, "D2:")) + ": key 'D2'",
                  "rational/thin-prism model not supported", "element 7"});
  }
  {
    OpenCVFile f;
    f.D1 = (cv::Mat_<double>(1, 6) << 0, 0, 0, 0, 0, 0);
    const std::string path = write_opencv(dir + "/d6.yml", f);
    expect_error(import_opencv_stereo(path), {path, "key 'D1'", "4, 5, 8, 12 or 14", "got 6"});
  }
  {
    OpenCVFile f;
    f.write_T = false;
    const std::string path = write_opencv(dir + "/noT.xml", f);
    expect_error(import_opencv_stereo(path), {path, "key 'T'", "missing", "translation"});
  }
  {
    OpenCVFile f;
    f.R = (cv::Mat_<double>(3, 3) << 1, 0, 0, 0, 1.2, 0, 0, 0, 1);
    const std::string path = write_opencv(dir + "/badR.yml", f);
    expect_error(import_opencv_stereo(path),
                 {path + ":" + std::to_string(line_of(path, "R:")) + ": key 'R'", "orthonormal"});
  }
  {
    const std::string path = write_text(dir + "/garbage.yml", "%YAML:1.0\nM1: [ 1, 2\n  : : ]]]\n");
    expect_error(import_opencv_stereo(path),
                 {"calib::import_opencv_stereo(): " + path + ":3: not a valid OpenCV FileStorage"});
  }
  {
    const std::string path = write_text(dir + "/noM.yml", "%YAML:1.0\nfoo: 1\n");
    expect_error(import_opencv_stereo(path), {path, "key 'M1'", "M1 D1 M2 D2 R T"});
  }
  expect_error(import_opencv_stereo(dir + "/missing.yml"), {dir + "/missing.yml", "cannot open"});
}

// --- ROS ----------------------------------------------------------------------------------------

std::string ros_list(const cv::Mat& m) {
  std::ostringstream o;
  o.precision(17);
  o << "[";
  for (int i = 0; i < static_cast<int>(m.total()); ++i) o << (i ? ", " : "") << m.at<double>(i);
  return o.str() + "]";
}

std::string ros_yaml(const cv::Mat& K, const cv::Mat& D, const std::string& model, const cv::Mat& R,
                     const cv::Mat& P, bool message_form = false) {
  std::ostringstream o;
  if (message_form) {  // a dumped sensor_msgs/CameraInfo
    o << "height: 960\nwidth: 1280\ndistortion_model: " << model << "\nD: " << ros_list(D)
      << "\nK: " << ros_list(K) << "\nR: " << ros_list(R) << "\nP: " << ros_list(P) << "\n";
    return o.str();
  }
  o << "image_width: 1280\nimage_height: 960\ncamera_name: cam\n"
    << "camera_matrix:\n  rows: 3\n  cols: 3\n  data: " << ros_list(K) << "\n"
    << "distortion_model: " << model << "\n"
    << "distortion_coefficients:\n  rows: 1\n  cols: " << D.total() << "\n  data: " << ros_list(D) << "\n"
    << "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: " << ros_list(R) << "\n"
    << "projection_matrix:\n  rows: 3\n  cols: 4\n  data: " << ros_list(P) << "\n";
  return o.str();
}

// Builds a ROS pair from a known extrinsic with cv::stereoRectify (what ROS's calibrator does).
TEST(CalibImport, RosPairFromStereoRectify) {
  const std::string dir = test::output_dir("calib_ros");
  const cv::Mat K1 = K_of(1100.0, 1098.0, 645.0, 470.0), K2 = K_of(1105.0, 1104.0, 630.0, 485.0);
  const cv::Mat D1 = (cv::Mat_<double>(1, 5) << -0.2, 0.07, 1e-3, -2e-4, -0.01);
  const cv::Mat D2 = (cv::Mat_<double>(1, 5) << -0.18, 0.05, -4e-4, 3e-4, -0.005);
  struct Case {
    const char* name;
    cv::Vec3d rvec, t;
  };
  for (const Case& cs : {Case{"horizontal", {0.01, -0.03, 0.004}, {-0.5, 0.012, -0.006}},
                         Case{"vertical", {0.02, 0.01, -0.01}, {0.01, -0.4, 0.02}},
                         Case{"long baseline", {-0.002, 0.05, 0.0}, {-1.7, -0.02, 0.1}}}) {
    SCOPED_TRACE(cs.name);
    cv::Mat R;
    cv::Rodrigues(cs.rvec, R);
    const cv::Mat T(cs.t);
    cv::Mat R1, R2, P1, P2, Q;
    cv::stereoRectify(K1, D1, K2, D2, cv::Size(1280, 960), R, T, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY,
                      0);
    for (bool msg : {false, true}) {
      const std::string l = write_text(dir + "/" + cs.name + (msg ? "_msg" : "") + "_left.yaml",
                                       ros_yaml(K1, D1, "plumb_bob", R1, P1, msg));
      const std::string r = write_text(dir + "/" + cs.name + (msg ? "_msg" : "") + "_right.yaml",
                                       ros_yaml(K2, D2, "plumb_bob", R2, P2, msg));
      const auto c = import_ros_camera_info(l, r);
      ASSERT_TRUE(c) << c.error().message;
      EXPECT_EQ(c->format, "ros");
      Eigen::Matrix3d Re;
      for (int i = 0; i < 9; ++i) Re(i / 3, i % 3) = R.at<double>(i / 3, i % 3);
      expect_pose_near(c->T_right_left, Pose::from(Re, {cs.t[0], cs.t[1], cs.t[2]}), 1e-9);
      EXPECT_DOUBLE_EQ(c->left.fx_px, 1100.0);
      EXPECT_DOUBLE_EQ(c->right.cy_px, 485.0);
      EXPECT_DOUBLE_EQ(c->right.coeffs[4], -0.005);
      EXPECT_EQ(c->left.width_px, 1280);
      const auto a = import_calibration("auto", l, r);
      ASSERT_TRUE(a) << a.error().message;
      EXPECT_EQ(a->format, "ros");
    }
  }
}

TEST(CalibImport, RosSampleFiles) {
  const auto c =
      import_ros_camera_info(test::data_path("calib/ros_left.yaml"), test::data_path("calib/ros_right.yaml"));
  ASSERT_TRUE(c) << c.error().message;
  expect_pose_near(c->T_right_left, Pose::from(Eigen::Matrix3d::Identity(), {-0.5, 0, 0}), 1e-12);
  EXPECT_DOUBLE_EQ(c->left.fx_px, 1210.5);
  EXPECT_DOUBLE_EQ(c->right.coeffs[0], -0.11);
}

TEST(CalibImport, RosModelsAndErrors) {
  const std::string dir = test::output_dir("calib_ros_errors");
  const cv::Mat K = K_of(1000, 1000, 640, 480);
  const cv::Mat I = cv::Mat::eye(3, 3, CV_64F);
  const cv::Mat P1 = (cv::Mat_<double>(3, 4) << 1000, 0, 640, 0, 0, 1000, 480, 0, 0, 0, 1, 0);
  const cv::Mat P2 = (cv::Mat_<double>(3, 4) << 1000, 0, 640, -300, 0, 1000, 480, 0, 0, 0, 1, 0);
  const cv::Mat D4 = (cv::Mat_<double>(1, 4) << 0.01, -0.002, 0.0003, -0.00002);
  const std::string right = write_text(dir + "/right.yaml", ros_yaml(K, D4, "equidistant", I, P2));
  for (const char* fisheye : {"equidistant", "fisheye"}) {
    const std::string l = write_text(dir + "/left_fisheye.yaml", ros_yaml(K, D4, fisheye, I, P1));
    const auto c = import_ros_camera_info(l, right);
    ASSERT_TRUE(c) << c.error().message;
    EXPECT_EQ(c->left.distortion, DistortionModel::kEquidistant);
    EXPECT_DOUBLE_EQ(c->left.coeffs[3], -0.00002);
    expect_pose_near(c->T_right_left, Pose::from(Eigen::Matrix3d::Identity(), {-0.3, 0, 0}), 1e-12);
  }
  {  // rational_polynomial: first 5 used, the rest must be zero
    const cv::Mat D8 = (cv::Mat_<double>(1, 8) << -0.1, 0.01, 0, 0, 0.001, 0, 0, 0);
    const std::string l =
        write_text(dir + "/rational_ok.yaml", ros_yaml(K, D8, "rational_polynomial", I, P1));
    const auto c = import_ros_camera_info(l, right);
    ASSERT_TRUE(c) << c.error().message;
    EXPECT_DOUBLE_EQ(c->left.coeffs[4], 0.001);
    const cv::Mat D8b = (cv::Mat_<double>(1, 8) << -0.1, 0.01, 0, 0, 0.001, 0.2, 0, 0);
    const std::string bad =
        write_text(dir + "/rational_bad.yaml", ros_yaml(K, D8b, "rational_polynomial", I, P1));
    expect_error(import_ros_camera_info(bad, right),
                 {bad + ":" + std::to_string(line_of(bad, "  data:", 2)),
                  "key 'distortion_coefficients.data'", "rational/thin-prism model not supported"});
  }
  {
    const std::string bad =
        write_text(dir + "/unknown_model.yaml", ros_yaml(K, D4, "kannala_brandt9", I, P1));
    expect_error(
        import_ros_camera_info(bad, right),
        {"calib::import_ros_camera_info(): " + bad + ":" + std::to_string(line_of(bad, "distortion_model")),
         "key 'distortion_model'", "unsupported distortion model", "got 'kannala_brandt9'"});
  }
  {
    std::string text = ros_yaml(K, D4, "equidistant", I, P1);
    const std::string from = "data: [1000, 0, 640, 0, 1000, 480, 0, 0, 1]";
    text.replace(text.find(from), from.size(), "data: [1000, 0, 640, 0, 1000, 480, 0, 0]");
    const std::string bad = write_text(dir + "/short_K.yaml", text);
    expect_error(import_ros_camera_info(bad, right),
                 {bad + ":" + std::to_string(line_of(bad, "  data:")), "key 'camera_matrix.data'",
                  "9 numbers", "got a list of 8 element(s)"});
  }
  {
    std::string text = ros_yaml(K, D4, "equidistant", I, P1);
    text.erase(text.find("projection_matrix"));
    const std::string bad = write_text(dir + "/no_P.yaml", text);
    expect_error(import_ros_camera_info(bad, right), {bad, "key 'projection_matrix'", "missing"});
  }
  expect_error(import_ros_camera_info(dir + "/nope.yaml", right), {dir + "/nope.yaml", "cannot open"});
  expect_error(import_calibration("ros", right), {"second path"});
}

// --- Kalibr -------------------------------------------------------------------------------------

TEST(CalibImport, KalibrSample) {
  const std::string path = test::data_path("calib/kalibr_camchain.yaml");
  const auto c = import_kalibr_camchain(path);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->format, "kalibr");
  EXPECT_EQ(c->left.distortion, DistortionModel::kRadTan);
  EXPECT_DOUBLE_EQ(c->left.coeffs[2], 0.0008);
  EXPECT_DOUBLE_EQ(c->left.coeffs[4], 0.0);
  EXPECT_DOUBLE_EQ(c->left.cy_px, 481.7);
  EXPECT_EQ(c->right.distortion, DistortionModel::kEquidistant);
  EXPECT_DOUBLE_EQ(c->right.coeffs[3], -0.00002);
  EXPECT_EQ(c->right.width_px, 1280);
  EXPECT_EQ(c->right.height_px, 960);
  expect_pose_near(c->T_right_left, sample_T_right_left(), 1e-12);
  const auto a = import_calibration("auto", path);
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(a->format, "kalibr");
}

TEST(CalibImport, KalibrErrors) {
  const std::string dir = test::output_dir("calib_kalibr_errors");
  std::ifstream in(test::data_path("calib/kalibr_camchain.yaml"));
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string good = ss.str();
  auto with = [&](const std::string& from, const std::string& to, const std::string& name) {
    std::string t = good;
    t.replace(t.find(from), from.size(), to);
    return write_text(dir + "/" + name, t);
  };
  {
    const std::string p = with("  T_cn_cnm1:", "  T_cn_cnm0:", "no_T.yaml");
    expect_error(import_kalibr_camchain(p),
                 {"calib::import_kalibr_camchain(): " + p, "key 'cam1.T_cn_cnm1'", "missing"});
  }
  {
    const std::string p = with("  camera_model: pinhole\n  distortion_coeffs: [-0.12",
                               "  camera_model: omni\n  distortion_coeffs: [-0.12", "omni.yaml");
    expect_error(import_kalibr_camchain(p),
                 {p + ":" + std::to_string(line_of(p, "  camera_model: omni")) + ":17",
                  "key 'cam0.camera_model'", "expected pinhole", "got 'omni'"});
  }
  {
    const std::string p =
        with("[-0.12, 0.05, 0.0008, -0.0004]", "[-0.12, 0.05, 0.0008, -0.0004, 0.1]", "radtan5.yaml");
    expect_error(import_kalibr_camchain(p),
                 {p + ":" + std::to_string(line_of(p, "  distortion_coeffs: [-0.12")),
                  "key 'cam0.distortion_coeffs'", "4 numbers", "got a list of 5"});
  }
  {
    const std::string p = with("  - [0.0, 0.0, 0.0, 1.0]", "  - [0.0, 0.0, 0.0, 2.0]", "lastrow.yaml");
    expect_error(import_kalibr_camchain(p), {p, "key 'cam1.T_cn_cnm1'", "last row"});
  }
  {
    const std::string p = with("intrinsics: [1205.1,", "intrinsics: [-1205.1,", "negf.yaml");
    expect_error(import_kalibr_camchain(p), {p, "key 'cam1.intrinsics'", "positive focal"});
  }
  {
    // 1e10 used to be cast to int before any check (undefined behaviour).
    const std::string p = with("  resolution: [1280, 960]", "  resolution: [1e10, 960]", "huge_res.yaml");
    expect_error(import_kalibr_camchain(p),
                 {p + ":" + std::to_string(line_of(p, "  resolution: [1e10")) + ":16",
                  "key 'cam0.resolution'", "in 1..32768", "got '1e10' as element 0"});
  }
  {
    const std::string p = with("intrinsics: [1205.1, 1204.2,", "intrinsics: [1e308, 1e308,", "huge_f.yaml");
    expect_error(import_kalibr_camchain(p), {p, "key 'cam1.intrinsics'", "fx, fy in [1, 1e7]"});
  }
  {
    const std::string p =
        with("[-0.12, 0.05, 0.0008, -0.0004]", "[-0.12, 1e300, 0.0008, -0.0004]", "huge_k.yaml");
    expect_error(import_kalibr_camchain(p), {p, "key 'cam0.distortion_coeffs'",
                                             "coefficients in [-1000, 1000]", "got 1e+300 as element 1"});
  }
  {
    // A directory where the file should be.
    const std::string d = dir + "/camchain.yaml";
    std::filesystem::create_directories(d);
    expect_error(import_kalibr_camchain(d),
                 {"calib::import_kalibr_camchain(): " + d, "is a directory, expected a file"});
    expect_error(import_opencv_stereo(d), {d, "is a directory, expected a file"});
    expect_error(import_calibration("auto", d), {d, "is a directory, expected a file"});
  }
  {
    const std::string p = write_text(dir + "/syntax.yaml", "cam0:\n  intrinsics: [1, 2\n");
    expect_error(import_kalibr_camchain(p), {p + ":", "YAML syntax error"});
  }
  expect_error(import_calibration("matlab", "x.yaml"), {"unknown format 'matlab'"});
}

}  // namespace
}  // namespace augrig
