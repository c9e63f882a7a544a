// Rig files: the paper's default geometry, the YAML format (both pose forms, calibration imports,
// model paths), the canonical writer's round trip, and error messages that name file, line and key.
#include "render/rig.hpp"

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/calib_import.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;

void expect_pose_near(const Pose& a, const Pose& b, double tol) {
  EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), tol) << "\n"
                                                                  << a.matrix() << "\nvs\n"
                                                                  << b.matrix();
}

void expect_model_near(const CameraModel& a, const CameraModel& b, double tol) {
  EXPECT_EQ(a.width_px, b.width_px);
  EXPECT_EQ(a.height_px, b.height_px);
  EXPECT_NEAR(a.fx_px, b.fx_px, tol);
  EXPECT_NEAR(a.fy_px, b.fy_px, tol);
  EXPECT_NEAR(a.cx_px, b.cx_px, tol);
  EXPECT_NEAR(a.cy_px, b.cy_px, tol);
  EXPECT_EQ(a.distortion, b.distortion);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(a.coeffs[i], b.coeffs[i], tol) << i;
}

void expect_source_eq(const ModelSource& a, const ModelSource& b) {
  EXPECT_EQ(a.path, b.path);
  EXPECT_EQ(a.axes.forward, b.axes.forward);
  EXPECT_EQ(a.axes.right, b.axes.right);
  EXPECT_EQ(a.axes.down, b.axes.down);
  EXPECT_NEAR(a.scale, b.scale, 1e-12);
}

// Everything but Rig::source (where it came from) must agree within `tol`.
void expect_rig_near(const Rig& a, const Rig& b, double tol) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (std::size_t i = 0; i < a.cameras.size(); ++i) {
    SCOPED_TRACE("camera " + std::to_string(i));
    EXPECT_EQ(a.cameras[i].name, b.cameras[i].name);
    expect_model_near(a.cameras[i].model, b.cameras[i].model, tol);
    expect_pose_near(a.cameras[i].T_body_cam, b.cameras[i].T_body_cam, tol);
    EXPECT_NEAR(a.cameras[i].near_m, b.cameras[i].near_m, tol);
    EXPECT_NEAR(a.cameras[i].far_m, b.cameras[i].far_m, tol);
    EXPECT_EQ(a.cameras[i].source_uri, b.cameras[i].source_uri);
  }
  EXPECT_LT((a.boom.pivot_body_m - b.boom.pivot_body_m).norm(), tol);
  expect_source_eq(a.boom.model, b.boom.model);
  const BoomLimits &la = a.boom.limits, &lb = b.boom.limits;
  EXPECT_NEAR(la.elevation_min_rad, lb.elevation_min_rad, tol);
  EXPECT_NEAR(la.elevation_max_rad, lb.elevation_max_rad, tol);
  EXPECT_NEAR(la.azimuth_min_rad, lb.azimuth_min_rad, tol);
  EXPECT_NEAR(la.azimuth_max_rad, lb.azimuth_max_rad, tol);
  EXPECT_NEAR(la.extension_min_m, lb.extension_min_m, tol);
  EXPECT_NEAR(la.extension_max_m, lb.extension_max_m, tol);
  expect_source_eq(a.receiver.model, b.receiver.model);
  EXPECT_LT((a.receiver.receptacle_m - b.receiver.receptacle_m).norm(), tol);
  ASSERT_EQ(a.receiver.keypoints.size(), b.receiver.keypoints.size());
  for (std::size_t i = 0; i < a.receiver.keypoints.size(); ++i) {
    EXPECT_EQ(a.receiver.keypoints[i].name, b.receiver.keypoints[i].name);
    EXPECT_LT((a.receiver.keypoints[i].p_m - b.receiver.keypoints[i].p_m).norm(), tol);
  }
  EXPECT_NEAR(a.pairing.tolerance_us, b.pairing.tolerance_us, tol);
  EXPECT_EQ(a.pairing.mode, b.pairing.mode);
  EXPECT_EQ(a.pairing.clock, b.pairing.clock);
  EXPECT_EQ(a.pairing.queue, b.pairing.queue);
}

std::string write_file(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(Rig, PaperDefaultGeometry) {
  const Rig rig = Rig::paper_default();
  ASSERT_EQ(rig.cameras.size(), 2u);
  EXPECT_EQ(rig.source, "<built-in>");
  for (const RigCamera& cam : rig.cameras) {
    EXPECT_EQ(cam.model.width_px, 1280);
    EXPECT_EQ(cam.model.height_px, 960);
    EXPECT_EQ(cam.model.distortion, DistortionModel::kNone);
    EXPECT_NEAR(rad_to_deg(2.0 * std::atan(640.0 / cam.model.fx_px)), 56.0, 1e-9);
    EXPECT_DOUBLE_EQ(cam.near_m, 1.0);
    EXPECT_DOUBLE_EQ(cam.far_m, 100.0);
    // Optical axis aft and 25 deg below the horizontal (body z is down).
    const Eigen::Vector3d axis = cam.T_body_cam.R() * Eigen::Vector3d::UnitZ();
    const double c = std::cos(deg_to_rad(25.0)), s = std::sin(deg_to_rad(25.0));
    EXPECT_LT((axis - Eigen::Vector3d(-c, 0, s)).norm(), 1e-12);
    // Image "down" has a downward body component; looking aft, image-right is port (-y).
    EXPECT_GT((cam.T_body_cam.R() * Eigen::Vector3d::UnitY()).z(), 0.0);
    EXPECT_LT((cam.T_body_cam.R() * Eigen::Vector3d::UnitX() - Eigen::Vector3d(0, -1, 0)).norm(), 1e-12);
  }
  EXPECT_EQ(rig.left().name, "left");
  EXPECT_LT((rig.left().T_body_cam.translation_m - Eigen::Vector3d(0, 0.25, 2.0)).norm(), 1e-15);
  EXPECT_LT((rig.right().T_body_cam.translation_m - Eigen::Vector3d(0, -0.25, 2.0)).norm(), 1e-15);
  // The right camera's centre, in left-camera coordinates, lies at +x (to the image's right).
  const Eigen::Vector3d right_in_left =
      rig.left().T_body_cam.inverse() * rig.right().T_body_cam.translation_m;
  EXPECT_LT((right_in_left - Eigen::Vector3d(0.5, 0, 0)).norm(), 1e-12);
  const Pose T_rl = rig.T_right_left();
  EXPECT_LT((T_rl.translation_m - Eigen::Vector3d(-0.5, 0, 0)).norm(), 1e-12);
  EXPECT_LT((T_rl.R() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(T_rl.translation_m.norm(), 0.5, 1e-12);  // baseline
  // Boom and receiver.
  EXPECT_LT((rig.boom.pivot_body_m - Eigen::Vector3d(-4.0, 0, 2.3)).norm(), 1e-15);
  EXPECT_NEAR(rig.boom.limits.elevation_min_rad, deg_to_rad(20), 1e-15);
  EXPECT_NEAR(rig.boom.limits.elevation_max_rad, deg_to_rad(40), 1e-15);
  EXPECT_NEAR(rig.boom.limits.azimuth_min_rad, deg_to_rad(-15), 1e-15);
  EXPECT_NEAR(rig.boom.limits.azimuth_max_rad, deg_to_rad(15), 1e-15);
  EXPECT_DOUBLE_EQ(rig.boom.limits.extension_min_m, 0.0);
  EXPECT_DOUBLE_EQ(rig.boom.limits.extension_max_m, 5.8);
  EXPECT_TRUE(rig.boom.model.path.empty());
  EXPECT_TRUE(rig.receiver.model.path.empty());
  EXPECT_LT((rig.receiver.receptacle_m - Eigen::Vector3d(4.0, 0, -0.9)).norm(), 1e-15);
}

TEST(Rig, MountYprConvention) {
  // Identity mount: the optical axis is body forward, image right is body right, image down is body down.
  const Eigen::Matrix3d R0 = R_body_cam_from_mount_ypr(0, 0, 0);
  EXPECT_LT((R0 * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  EXPECT_LT((R0 * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-15);
  EXPECT_LT((R0 * Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  EXPECT_NEAR(R0.determinant(), 1.0, 1e-15);
  // Yaw 90 deg: looking starboard.
  const Eigen::Matrix3d R1 = R_body_cam_from_mount_ypr(kPi / 2, 0, 0);
  EXPECT_LT((R1 * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitY()).norm(), 1e-15);
}

TEST(Rig, PaperDefaultAssetMatches) {
  const auto path = std::string(AUGRIG_TEST_DATA_DIR) + "/../../assets/rigs/paper_default.yaml";
  const auto rig = load_rig(path);
  ASSERT_TRUE(rig) << rig.error().message;
  expect_rig_near(*rig, Rig::paper_default(), 1e-12);
  // The asset is exactly what rig_to_yaml writes (regenerate it if the format changes).
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), rig_to_yaml(Rig::paper_default()));
}

TEST(Rig, RoundTripPaperDefault) {
  const Rig a = Rig::paper_default();
  const auto b = parse_rig(rig_to_yaml(a), "<string>");
  ASSERT_TRUE(b) << b.error().message;
  expect_rig_near(*b, a, 1e-12);
  EXPECT_EQ(b->source, "<string>");
}

TEST(Rig, RoundTripEverything) {
  Rig a = Rig::paper_default();
  a.cameras[0].model.distortion = DistortionModel::kRadTan;
  a.cameras[0].model.coeffs = {-0.35, 0.15, 1e-3, -5e-4, -0.03};
  a.cameras[0].model.cx_px = 641.123456789;
  a.cameras[0].source_uri = "rtsp://cam0:554/stream # with: odd \"chars\"";
  a.cameras[1].model.distortion = DistortionModel::kEquidistant;
  a.cameras[1].model.coeffs = {0.01, -0.002, 0.0003, -0.00002, 0.0};
  a.cameras[1].name = "right cam";
  a.cameras[1].T_body_cam = Pose::from(rotation_from_ypr(0.1, -0.2, 0.3), {0.1, -0.3, 2.1});
  a.cameras[1].near_m = 0.7;
  a.cameras[1].far_m = 123.456;
  a.boom.model.path = "/abs/models/boom.glb";
  a.boom.model.axes = ModelAxes::frd();
  a.boom.model.scale = 0.001;
  a.receiver.model.path = "/abs/models/receiver dir/plane.obj";
  a.receiver.model.axes = {"-z", "+x", "-y"};
  a.receiver.receptacle_m = {3.3, 0.1, -1.2};
  // In the order written, which need not be sorted.
  a.receiver.keypoints = {{"nose", {6.5, 0, 0.1}}, {"wing_tip_left", {-1.0, -8.3, -0.2}}, {"a_fin", {-6, 0, -3.25}}};
  a.boom.limits.elevation_min_rad = deg_to_rad(12.345);
  a.pairing = {125.5, "trigger_id", "shared", 3};
  const std::string text = rig_to_yaml(a);
  const auto b = parse_rig(text, "<string>");
  ASSERT_TRUE(b) << b.error().message << "\n" << text;
  expect_rig_near(*b, a, 1e-12);
}

TEST(Rig, LoadsExampleWithBothPoseFormsAndModelPath) {
  const std::string path = test::data_path("rigs/example.yaml");
  const auto rig = load_rig(path);
  ASSERT_TRUE(rig) << rig.error().message;
  EXPECT_EQ(rig->source, path);
  EXPECT_EQ(rig->left().model.distortion, DistortionModel::kRadTan);
  EXPECT_DOUBLE_EQ(rig->left().model.coeffs[4], -0.01);
  EXPECT_EQ(rig->left().source_uri, "v4l2:///dev/video0");
  EXPECT_EQ(rig->right().model.distortion, DistortionModel::kEquidistant);
  EXPECT_NEAR(rig->right().model.fx_px, 640.0 / std::tan(deg_to_rad(28.0)), 1e-9);
  EXPECT_DOUBLE_EQ(rig->right().near_m, 1.5);
  EXPECT_DOUBLE_EQ(rig->right().far_m, 80.0);
  // The matrix form in the file is the same rotation as the mount_ypr form.
  EXPECT_LT((rig->right().T_body_cam.R() - rig->left().T_body_cam.R()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((rig->T_right_left().translation_m - Eigen::Vector3d(-0.5, 0, 0)).norm(), 1e-12);
  // Model paths become absolute, relative to the rig file's directory.
  const fs::path expected = fs::path(test::data_path("rigs/models/boom.glb")).lexically_normal();
  EXPECT_EQ(rig->boom.model.path, expected.string());
  EXPECT_TRUE(fs::path(rig->boom.model.path).is_absolute());
  EXPECT_EQ(rig->boom.model.axes.forward, "+z");
  EXPECT_TRUE(rig->receiver.model.path.empty());
}

TEST(Rig, MatrixAsSixteenNumbers) {
  const Rig paper = Rig::paper_default();
  std::string text = rig_to_yaml(paper);
  // Replace the left camera's 4 rows by one flat list of 16.
  const Eigen::Matrix4d T = paper.left().T_body_cam.matrix();
  std::ostringstream flat;
  flat.precision(17);
  flat << "      matrix: [";
  for (int i = 0; i < 16; ++i) flat << (i ? ", " : "") << T(i / 4, i % 4);
  flat << "]\n";
  const std::size_t a = text.find("      matrix:\n");
  const std::size_t b = text.find("    near_m:", a);
  text.replace(a, b - a, flat.str());
  const auto rig = parse_rig(text, "<string>");
  ASSERT_TRUE(rig) << rig.error().message;
  expect_pose_near(rig->left().T_body_cam, paper.left().T_body_cam, 1e-12);
}

void expect_calibrated(const Rig& rig, const StereoCalibration& calib) {
  expect_model_near(rig.left().model, calib.left, 1e-12);
  expect_model_near(rig.right().model, calib.right, 1e-12);
  expect_pose_near(rig.left().T_body_cam, Rig::paper_default().left().T_body_cam, 1e-12);
  // T_body_right = T_body_left * T_right_left^-1, so the rig's T_right_left is the calibration's.
  expect_pose_near(rig.T_right_left(), calib.T_right_left, 1e-12);
}

TEST(Rig, CalibrationOpenCV) {
  const auto rig = load_rig(test::data_path("rigs/opencv_calibrated.yaml"));
  ASSERT_TRUE(rig) << rig.error().message;
  const auto calib = import_opencv_stereo(test::data_path("calib/opencv_stereo.yml"));
  ASSERT_TRUE(calib) << calib.error().message;
  expect_calibrated(*rig, *calib);
  EXPECT_DOUBLE_EQ(rig->right().far_m, 60.0);
  EXPECT_EQ(rig->right().name, "right");
}

TEST(Rig, CalibrationKalibr) {
  const auto rig = load_rig(test::data_path("rigs/kalibr_calibrated.yaml"));
  ASSERT_TRUE(rig) << rig.error().message;
  const auto calib = import_kalibr_camchain(test::data_path("calib/kalibr_camchain.yaml"));
  ASSERT_TRUE(calib) << calib.error().message;
  expect_calibrated(*rig, *calib);
  EXPECT_EQ(rig->right().model.distortion, DistortionModel::kEquidistant);
}

TEST(Rig, CalibrationRos) {
  const auto rig = load_rig(test::data_path("rigs/ros_calibrated.yaml"));
  ASSERT_TRUE(rig) << rig.error().message;
  const auto calib =
      import_ros_camera_info(test::data_path("calib/ros_left.yaml"), test::data_path("calib/ros_right.yaml"));
  ASSERT_TRUE(calib) << calib.error().message;
  expect_calibrated(*rig, *calib);
  EXPECT_LT((rig->T_right_left().translation_m - Eigen::Vector3d(-0.5, 0, 0)).norm(), 1e-12);
  EXPECT_EQ(rig->left().name, "left");
}

TEST(Rig, MissingFile) {
  const auto rig = load_rig("/nonexistent/dir/rig.yaml");
  ASSERT_FALSE(rig);
  EXPECT_EQ(rig.error().message.rfind("rig::load(): /nonexistent/dir/rig.yaml: cannot open", 0), 0u)
      << rig.error().message;
}

TEST(Rig, DataFileErrors) {
  const std::string typo = test::data_path("rigs/bad_typo.yaml");
  auto rig = load_rig(typo);
  ASSERT_FALSE(rig);
  const std::string& m = rig.error().message;
  EXPECT_NE(m.find("rig::load(): " + typo + ":8:5: key 'cameras[0].nera_m': unknown key"), std::string::npos)
      << m;
  EXPECT_NE(m.find("near_m"), std::string::npos) << m;  // lists the allowed keys

  const std::string syntax = test::data_path("rigs/bad_syntax.yaml");
  rig = load_rig(syntax);
  ASSERT_FALSE(rig);
  EXPECT_EQ(rig.error().message.rfind("rig::load(): " + syntax + ":", 0), 0u) << rig.error().message;
  EXPECT_NE(rig.error().message.find("YAML syntax error"), std::string::npos) << rig.error().message;
}

// A valid rig in which each bad case replaces one line. Line numbers are 1-based.
const char* kBaseRig = R"(augrig_rig: 1
cameras:
  - name: left
    resolution: [1280, 960]
    hfov_deg: 56
    T_body_cam:
      translation_m: [0, 0.25, 2.0]
      mount_ypr_deg: [180, -25, 0]
  - name: right
    resolution: [1280, 960]
    intrinsics: [1203.7, 1203.7, 639.5, 479.5]
    distortion: {model: radtan, coeffs: [-0.1, 0.01, 0, 0, 0]}
    T_body_cam:
      translation_m: [0, -0.25, 2.0]
      mount_ypr_deg: [180, -25, 0]
    near_m: 1.0
    far_m: 100.0
boom:
  pivot_body_m: [-4.0, 0, 2.3]
  model: builtin
  limits:
    elevation_deg: [20, 40]
    azimuth_deg: [-15, 15]
    extension_m: [0, 5.8]
receiver:
  model: builtin
  receptacle_m: [4.0, 0, -0.9]
)";

// Replaces lines (1-based) of kBaseRig by new text (which may span several lines).
std::string edit(const std::map<int, std::string>& lines) {
  std::istringstream in(kBaseRig);
  std::string out, l;
  for (int n = 1; std::getline(in, l); ++n) out += (lines.count(n) ? lines.at(n) : l) + "\n";
  return out;
}
std::string base_with(int line, const std::string& text) {
  return edit({{line, text}});
}

TEST(Rig, BaseRigIsValid) {
  const auto rig = parse_rig(kBaseRig, "<string>");
  ASSERT_TRUE(rig) << rig.error().message;
  EXPECT_EQ(rig->right().model.distortion, DistortionModel::kRadTan);
}

// A rig without a boom section is a capture-only rig: it loads, says so, and stays one when written
// and read back; a boom section that is there must still be whole.
TEST(Rig, WithoutBoomSectionIsCaptureOnly) {
  const std::string yaml = edit({{18, "#"}, {19, "#"}, {20, "#"}, {21, "#"}, {22, "#"}, {23, "#"}, {24, "#"}});
  ASSERT_EQ(yaml.find("boom:"), std::string::npos);
  const auto rig = parse_rig(yaml, "capture.yaml");
  ASSERT_TRUE(rig) << rig.error().message;
  EXPECT_FALSE(rig->boom.configured);
  EXPECT_TRUE(parse_rig(kBaseRig, "<string>")->boom.configured);
  EXPECT_TRUE(Rig::paper_default().boom.configured);
  const std::string written = rig_to_yaml(*rig);
  EXPECT_EQ(written.find("boom:"), std::string::npos) << written;
  const auto again = parse_rig(written, "<string>");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_FALSE(again->boom.configured);
  expect_rig_near(*again, *rig, 1e-12);
  // An empty boom section is not a missing one.
  const auto empty = parse_rig(edit({{18, "boom: {}"}, {19, "#"}, {20, "#"}, {21, "#"}, {22, "#"}, {23, "#"}, {24, "#"}}),
                               "empty.yaml");
  ASSERT_FALSE(empty);
  EXPECT_NE(empty.error().message.find("boom"), std::string::npos) << empty.error().message;
}

struct BadRig {
  std::string what;
  std::string yaml;
  int line;             // expected line in the message
  std::string key;      // expected key path
  std::string message;  // expected fragment of the explanation
};

TEST(Rig, BadRigsNameFileLineAndKey) {
  const std::vector<BadRig> cases = {
      {"3 intrinsics", base_with(11, "    intrinsics: [1203.7, 1203.7, 639.5]"), 11, "cameras[1].intrinsics",
       "expected a list of 4 numbers [fx, fy, cx, cy], got a list of 3 element(s)"},
      {"non-number intrinsic", base_with(11, "    intrinsics: [1203.7, fx, 639.5, 479.5]"), 11,
       "cameras[1].intrinsics", "got 'fx' as element 1"},
      {"typo", base_with(16, "    nera_m: 1.0"), 16, "cameras[1].nera_m",
       "unknown key; allowed keys here: name"},
      {"top-level typo", base_with(25, "reciever:"), 25, "reciever", "unknown key"},
      {"negative focal", base_with(11, "    intrinsics: [-1203.7, 1203.7, 639.5, 479.5]"), 11,
       "cameras[1].intrinsics", "expected positive focal lengths"},
      {"principal point outside", base_with(11, "    intrinsics: [1203.7, 1203.7, 1500, 479.5]"), 11,
       "cameras[1].intrinsics", "principal point inside the image"},
      {"zero resolution", base_with(4, "    resolution: [1280, 0]"), 4, "cameras[0].resolution",
       "expected a list of 2 positive integers [width, height]"},
      {"hfov out of range", base_with(5, "    hfov_deg: 190"), 5, "cameras[0].hfov_deg", "(0, 180)"},
      // Inside (0, 180) but beyond the field augrig renders: refused at the camera.
      {"field beyond 80 degrees", base_with(5, "    hfov_deg: 170"), 3, "cameras[0]",
       "the lens sees 85.0 degrees off the optical axis"},
      {"fisheye beyond 80 degrees",
       edit({{11, "    intrinsics: [400, 400, 639.5, 479.5]"},
             {12, "    distortion: {model: equidistant, coeffs: [0, 0, 0, 0]}"}}),
       9, "cameras[1]", "within 80 degrees"},
      {"intrinsics and hfov",
       base_with(11, "    intrinsics: [1203.7, 1203.7, 639.5, 479.5]\n    hfov_deg: 56"), 12,
       "cameras[1].hfov_deg", "either 'intrinsics' or 'hfov_deg'"},
      {"unknown distortion model", base_with(12, "    distortion: {model: fisheye62, coeffs: [0, 0, 0, 0]}"),
       12, "cameras[1].distortion.model", "unknown distortion model"},
      {"radtan with 3 coeffs", base_with(12, "    distortion: {model: radtan, coeffs: [0, 0, 0]}"), 12,
       "cameras[1].distortion.coeffs", "4 or 5 numbers"},
      {"non-orthonormal matrix",
       edit({{14, "      matrix: [[1, 0, 0, 0], [0, 1.1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"}, {15, "#"}}),
       14, "cameras[1].T_body_cam.matrix", "orthonormal"},
      {"reflection matrix",
       edit({{7, "      matrix: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]"}, {8, "#"}}), 7,
       "cameras[0].T_body_cam.matrix", "reflection"},
      {"matrix last row",
       edit({{7, "      matrix: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1]"}, {8, "#"}}), 7,
       "cameras[0].T_body_cam.matrix", "last row"},
      {"matrix and translation", base_with(8, "      mount_ypr_deg: [180, -25, 0]\n      matrix: [1]"), 7,
       "cameras[0].T_body_cam", "either 'matrix' or"},
      {"bad ypr", base_with(8, "      mount_ypr_deg: [180, down, 0]"), 8,
       "cameras[0].T_body_cam.mount_ypr_deg", "got 'down' as element 1"},
      {"near zero", base_with(16, "    near_m: 0"), 16, "cameras[1].near_m", "expected near_m > 0"},
      {"far before near", base_with(17, "    far_m: 0.5"), 17, "cameras[1].far_m", "expected far_m > near_m"},
      {"elevation min > max", base_with(22, "    elevation_deg: [40, 20]"), 22, "boom.limits.elevation_deg",
       "expected min <= max, got [40, 20]"},
      {"duplicate key", base_with(24, "    extension_m: [0, 5.8]\n    azimuth_deg: [0, 1]"), 25,
       "boom.limits.azimuth_deg", "duplicate key"},
      {"missing limits", edit({{21, "#"}, {22, "#"}, {23, "#"}, {24, "#"}}), 19, "boom.limits", "missing"},
      {"version 2", base_with(1, "augrig_rig: 2"), 1, "augrig_rig", "expected format version 1, got '2'"},
      {"missing version", base_with(1, "# no version"), 2, "augrig_rig", "missing"},
      {"bad axes repeated",
       base_with(20, "  model: {path: boom.glb, axes: {forward: +x, right: +x, down: +z}}"), 20,
       "boom.model.axes", "right-handed"},
      {"bad axes mirrored",
       base_with(20, "  model: {path: boom.glb, axes: {forward: +x, right: -y, down: +z}}"), 20,
       "boom.model.axes", "mirrored"},
      {"bad axis string", base_with(20, "  model: {path: boom.glb, axes: {forward: +x, right: y, down: +z}}"),
       20, "boom.model.axes.right", "one of +x -x +y -y +z -z"},
      {"receptacle not 3", base_with(27, "  receptacle_m: [4.0, 0]"), 27, "receiver.receptacle_m",
       "a list of 3 numbers"},
      {"keypoints not a map", base_with(27, "  receptacle_m: [4.0, 0, -0.9]\n  keypoints: [1, 2]"), 28,
       "receiver.keypoints", "a map {name: [x, y, z] in metres (receiver FRD), ...}"},
      {"keypoints empty", base_with(27, "  receptacle_m: [4.0, 0, -0.9]\n  keypoints: {}"), 28, "receiver.keypoints",
       "at least one keypoint"},
      {"keypoint name", base_with(27, "  receptacle_m: [4.0, 0, -0.9]\n  keypoints: {nose: [1, 0, 0], 'wing-tip': [0, 1, 0]}"),
       28, "receiver.keypoints.wing-tip", "expected a name of letters, digits and '_', got 'wing-tip'"},
      {"keypoint short", base_with(27, "  receptacle_m: [4.0, 0, -0.9]\n  keypoints:\n    nose: [1, 0]"), 29,
       "receiver.keypoints.nose", "a list of 3 numbers"},
      {"keypoint twice", base_with(27, "  receptacle_m: [4.0, 0, -0.9]\n  keypoints:\n    nose: [1, 0, 0]\n    nose: [2, 0, 0]"),
       30, "receiver.keypoints.nose", "expected each name once, got 'nose' twice"},
      {"missing T_body_cam", edit({{6, "#"}, {7, "#"}, {8, "#"}}), 3, "cameras[0].T_body_cam", "missing"},
      {"calibration file missing",
       base_with(1, "augrig_rig: 1\ncalibration: {format: kalibr, file: nope.yaml}"), 2, "calibration.file",
       "nope.yaml: cannot open"},
      {"calibration format", base_with(1, "augrig_rig: 1\ncalibration: {format: matlab, file: x.mat}"), 2,
       "calibration.format", "expected one of opencv, ros, kalibr"},
      {"pairing tolerance zero", base_with(1, "augrig_rig: 1\npairing: {tolerance_us: 0}"), 2,
       "pairing.tolerance_us", "expected microseconds > 0 and at most 1e7 (10 s), got '0'"},
      {"pairing mode", base_with(1, "augrig_rig: 1\npairing: {mode: nearest}"), 2, "pairing.mode",
       "expected timestamp or trigger_id, got 'nearest'"},
      {"pairing clock", base_with(1, "augrig_rig: 1\npairing: {clock: gps}"), 2, "pairing.clock",
       "expected separate (each camera its own clock) or shared (PTP), got 'gps'"},
      {"pairing queue", base_with(1, "augrig_rig: 1\npairing: {queue: 2.5}"), 2, "pairing.queue",
       "expected an integer from 1 to 1024"},
      {"pairing typo", base_with(1, "augrig_rig: 1\npairing: {tolerance: 10}"), 2, "pairing.tolerance",
       "unknown key"},
      // Implausible values: finite, but every projection with them overflows.
      {"huge focal", base_with(11, "    intrinsics: [1e308, 1e308, 639.5, 479.5]"), 11,
       "cameras[1].intrinsics",
       "expected positive focal lengths fx, fy of at least 1 and at most 1e+07 pixels, got 1e+308, 1e+308"},
      // Below a pixel the augmenter's virtual pinhole image would need billions of pixels.
      {"tiny focal", base_with(11, "    intrinsics: [1e-300, 0.001, 639.5, 479.5]"), 11,
       "cameras[1].intrinsics",
       "expected positive focal lengths fx, fy of at least 1 and at most 1e+07 pixels, got 1e-300, 0.001"},
      {"huge resolution", base_with(10, "    resolution: [10000000000, 960]"), 10, "cameras[1].resolution",
       "at most 32768, got '10000000000' as element 0"},
      {"resolution above the limit", base_with(4, "    resolution: [40000, 960]"), 4, "cameras[0].resolution",
       "at most 32768"},
      {"huge equidistant coefficients",
       base_with(12, "    distortion: {model: equidistant, coeffs: [1e300, 1e300, 1e300, 1e300]}"), 12,
       "cameras[1].distortion.coeffs",
       "expected distortion coefficients in [-1000, 1000], got '1e300' as element 0"},
      {"huge radtan coefficient",
       base_with(12, "    distortion: {model: radtan, coeffs: [0, 0, 0, 0, -1e9]}"), 12,
       "cameras[1].distortion.coeffs", "as element 4"},
      {"tiny hfov", base_with(5, "    hfov_deg: 1e-300"), 3, "cameras[0]",
       "expected focal lengths fx, fy in [1, 1e7]"},
      // The camera look's keys (docs/LOOK.md).
      {"look PSF out of range", base_with(16, "    near_m: 1.0\n    look: {psf_sigma_px: 20}"), 17,
       "cameras[1].look.psf_sigma_px", "a PSF 1-sigma in pixels in 0..8, got 20"},
      {"look noise_a alone", base_with(16, "    near_m: 1.0\n    look: {noise_a: 0.2}"), 17,
       "cameras[1].look.noise_b", "noise_a and noise_b (sigma^2 = a I + b, DN) are given together"},
      {"look noise of 2 channels", base_with(16, "    near_m: 1.0\n    look: {noise_a: [1, 2], noise_b: 1}"),
       17, "cameras[1].look.noise_a", "or 3 (R, G, B)"},
      {"look negative noise", base_with(16, "    near_m: 1.0\n    look: {noise_a: 0.1, noise_b: -1}"), 17,
       "cameras[1].look.noise_b", "read-noise variance (DN^2) >= 0, got -1"},
      {"look gamma", base_with(16, "    near_m: 1.0\n    look: {gamma: 0}"), 17, "cameras[1].look.gamma",
       "in 0.2..5, got 0"},
      {"look typo", base_with(16, "    near_m: 1.0\n    look: {psf: 1}"), 17, "cameras[1].look.psf",
       "unknown key"},
      {"look exposure negative", base_with(16, "    near_m: 1.0\n    look: {exposure_ms: -2}"), 17,
       "cameras[1].look.exposure_ms", "expected an exposure time in milliseconds in 0..1000, got -2"},
      {"look exposure too long", base_with(16, "    near_m: 1.0\n    look: {exposure_ms: 2000}"), 17,
       "cameras[1].look.exposure_ms", "in 0..1000, got 2000"},
      {"look exposure not a number", base_with(16, "    near_m: 1.0\n    look: {exposure_ms: fast}"), 17,
       "cameras[1].look.exposure_ms", "an exposure time in milliseconds"},
      // The boom's finish.
      {"boom metallic", base_with(20, "  model: builtin\n  material: {metallic: 2}"), 21,
       "boom.material.metallic", "expected a metallic factor (0 paint, 1 bare metal) in 0..1, got 2"},
      {"boom roughness", base_with(20, "  model: builtin\n  material: {roughness: -0.5}"), 21,
       "boom.material.roughness", "expected a roughness (0 mirror, 1 matte) in 0..1, got -0.5"},
      {"boom material typo", base_with(20, "  model: builtin\n  material: {shininess: 3}"), 21,
       "boom.material.shininess", "unknown key"},
  };
  // Only one camera: the right camera's lines removed.
  std::vector<BadRig> all = cases;
  {
    std::string one = kBaseRig;
    const std::size_t a = one.find("  - name: right");
    const std::size_t b = one.find("boom:");
    one.erase(a, b - a);
    all.push_back({"one camera (erased)", one, 3, "cameras", "expected a list of exactly 2 cameras"});
  }
  const std::string dir = test::output_dir("rig_test_bad");
  int n = 0;
  for (const BadRig& c : all) {
    SCOPED_TRACE(c.what);
    const std::string path = write_file(dir, "bad_" + std::to_string(n++) + ".yaml", c.yaml);
    const auto rig = load_rig(path);
    ASSERT_FALSE(rig) << c.yaml;
    const std::string& m = rig.error().message;
    const std::string head = "rig::load(): " + path + ":" + std::to_string(c.line) + ":";
    EXPECT_EQ(m.rfind(head, 0), 0u) << m << "\nexpected to start with " << head;
    EXPECT_NE(m.find("key '" + c.key + "'"), std::string::npos) << m;
    EXPECT_NE(m.find(c.message), std::string::npos) << m;
  }
  EXPECT_GE(all.size(), 10u);
}

// The camera look's keys are read and written back; without noise keys the noise is estimated.
TEST(Rig, CameraLookKeysRoundTrip) {
  const auto rig = parse_rig(
      base_with(16, "    near_m: 1.0\n    look: {psf_sigma_px: 1.2, gamma: 2.2, noise_a: [0.1, 0.2, 0.3], "
                    "noise_b: 4, seed: 9}"),
      "<string>");
  ASSERT_TRUE(rig) << rig.error().message;
  const CameraLookParams& l = rig->right().look;
  EXPECT_EQ(l.psf_sigma_px, 1.2);
  EXPECT_EQ(l.gamma, 2.2);
  EXPECT_EQ(l.seed, 9u);
  EXPECT_EQ(l.noise.channels, 3);
  EXPECT_EQ(l.noise.a, (std::array<double, 3>{0.1, 0.2, 0.3}));
  EXPECT_EQ(l.noise.b, (std::array<double, 3>{4, 4, 4}));
  EXPECT_EQ(rig->left().look, CameraLookParams{});  // defaults; noise estimated
  const auto again = parse_rig(rig_to_yaml(*rig), "<round trip>");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->right().look, l);
  EXPECT_EQ(again->left().look, CameraLookParams{});
  const auto mono = parse_rig(base_with(16, "    near_m: 1.0\n    look: {noise_a: 0.5, noise_b: 2}"), "<string>");
  ASSERT_TRUE(mono) << mono.error().message;
  EXPECT_EQ(mono->right().look.noise.channels, 1);
  EXPECT_EQ(parse_rig(rig_to_yaml(*mono), "<round trip>")->right().look, mono->right().look);
}

// The exposure (motion blur): unknown unless given (the frames' own then), 0 an instant; written back.
TEST(Rig, CameraLookExposureRoundTrip) {
  const auto rig = parse_rig(base_with(16, "    near_m: 1.0\n    look: {exposure_ms: 4.5}"), "<string>");
  ASSERT_TRUE(rig) << rig.error().message;
  EXPECT_EQ(rig->right().look.exposure_ms, 4.5);
  EXPECT_LT(rig->left().look.exposure_ms, 0);  // not known here
  const auto again = parse_rig(rig_to_yaml(*rig), "<round trip>");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->right().look, rig->right().look);
  EXPECT_EQ(again->left().look, CameraLookParams{});
  const auto instant = parse_rig(base_with(16, "    near_m: 1.0\n    look: {exposure_ms: 0}"), "<string>");
  ASSERT_TRUE(instant) << instant.error().message;
  EXPECT_EQ(instant->right().look.exposure_ms, 0.0);
  EXPECT_EQ(parse_rig(rig_to_yaml(*instant), "<round trip>")->right().look.exposure_ms, 0.0);
}

// The boom's finish (`boom.material`) is read and written back; absent, none is set (the built-in
// paint, or the model file's own).
TEST(Rig, BoomMaterialRoundTrip) {
  const auto rig =
      parse_rig(base_with(20, "  model: builtin\n  material: {metallic: 1, roughness: 0.35}"), "<string>");
  ASSERT_TRUE(rig) << rig.error().message;
  ASSERT_TRUE(rig->boom.material);
  EXPECT_EQ(*rig->boom.material, (SurfaceFinish{1.0, 0.35}));
  const auto again = parse_rig(rig_to_yaml(*rig), "<round trip>");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->boom.material, rig->boom.material);
  const auto half = parse_rig(base_with(20, "  model: builtin\n  material: {roughness: 0.8}"), "<string>");
  ASSERT_TRUE(half) << half.error().message;
  EXPECT_EQ(*half->boom.material, (SurfaceFinish{kPaintedBoom.metallic, 0.8}));
  const auto none = parse_rig(kBaseRig, "<string>");
  ASSERT_TRUE(none);
  EXPECT_FALSE(none->boom.material);
  EXPECT_FALSE(parse_rig(rig_to_yaml(*none), "<round trip>")->boom.material);
}

// A directory given as the rig file used to read as an empty document ("got nothing (null)").
TEST(Rig, DirectoryIsNotARigFile) {
  const std::string dir = test::output_dir("rig_test_dir") + "/rig.yaml";
  fs::create_directories(dir);
  const auto rig = load_rig(dir);
  ASSERT_FALSE(rig);
  EXPECT_EQ(rig.error().message, "rig::load(): " + dir + ": is a directory, expected a file");
}

// The camera model's own bounds, shared by the rig and the calibration importers.
TEST(Rig, CameraModelProblemNamesTheValueAndRange) {
  CameraModel m = CameraModel::pinhole_from_hfov(1280, 960, deg_to_rad(56));
  EXPECT_EQ(camera_model_problem(m), "");
  m.fx_px = 1e308;
  EXPECT_NE(camera_model_problem(m).find("fx, fy in [1, 1e7] pixels, got 1e+308"), std::string::npos);
  m.fx_px = std::nan("");
  EXPECT_NE(camera_model_problem(m), "");
  m = CameraModel::pinhole_from_hfov(1280, 960, deg_to_rad(56));
  m.cx_px = 1e9;
  EXPECT_NE(camera_model_problem(m).find("principal point"), std::string::npos);
  m = CameraModel::pinhole_from_hfov(1280, 960, deg_to_rad(56));
  m.distortion = DistortionModel::kEquidistant;
  m.coeffs = {1e300, 1e300, 1e300, 1e300, 0};
  EXPECT_NE(camera_model_problem(m).find("equidistant distortion coefficients in [-1000, 1000], got 1e+300"),
            std::string::npos);
  m.coeffs[4] = 1e300;  // the 5th is unused by equidistant
  m.coeffs[0] = m.coeffs[1] = m.coeffs[2] = m.coeffs[3] = 0.1;
  EXPECT_EQ(camera_model_problem(m), "");
  m.width_px = 40000;
  EXPECT_NE(camera_model_problem(m).find("image size"), std::string::npos);
}

// The field augrig renders: within 80 degrees of the optical axis horizontally and vertically.
// Wider lenses are refused (their outer pixels would never be augmented), fisheyes looking 90
// degrees or more off axis included.
TEST(Rig, LensesSeeingBeyondTheRenderedFieldAreRefused) {
  CameraModel m;
  m.width_px = 1280, m.height_px = 960, m.cx_px = 639.5, m.cy_px = 479.5;
  m.distortion = DistortionModel::kEquidistant;
  m.coeffs = {0, 0, 0, 0, 0};
  // Pure equidistant, theta = r / f; the corners (800 px out) look farthest off axis. f = 560:
  // 81.9 degrees off axis there, 79.9 of it horizontally (tan 81.9 x 640 / 800): inside.
  m.fx_px = m.fy_px = 560;
  EXPECT_EQ(camera_model_problem(m), "");
  // f = 550: 83.3 degrees at the corner, 81.6 horizontally: refused, naming the corner.
  m.fx_px = m.fy_px = 550;
  std::string p = camera_model_problem(m);
  EXPECT_NE(p.find("81.6 degrees off the optical axis at pixel (0, 0)"), std::string::npos) << p;
  EXPECT_NE(p.find("within 80 degrees"), std::string::npos) << p;
  // f = 400: the corners look backwards (114.6 degrees): normalised coordinates do not exist
  // there, rays do.
  m.fx_px = m.fy_px = 400;
  p = camera_model_problem(m);
  EXPECT_NE(p.find("degrees off the optical axis"), std::string::npos) << p;
  // A pinhole of 170 degrees horizontal field: 85 degrees at the edges; 150: inside.
  p = camera_model_problem(CameraModel::pinhole_from_hfov(1280, 960, deg_to_rad(170)));
  EXPECT_NE(p.find("85.0 degrees"), std::string::npos) << p;
  EXPECT_EQ(camera_model_problem(CameraModel::pinhole_from_hfov(1280, 960, deg_to_rad(150))), "");
}

TEST(Rig, ParseRigErrorsUseParsePrefix) {
  const auto rig = parse_rig(base_with(11, "    intrinsics: [1, 2]"), "inline.yaml");
  ASSERT_FALSE(rig);
  EXPECT_EQ(
      rig.error().message.rfind("rig::parse(): inline.yaml:11:17: key 'cameras[1].intrinsics': expected a "
                                "list of 4 numbers [fx, fy, cx, cy], got a list of 2 element(s)",
                                0),
      0u)
      << rig.error().message;
  const auto empty = parse_rig("", "<string>");
  ASSERT_FALSE(empty);
  EXPECT_EQ(empty.error().message.rfind("rig::parse(): <string>", 0), 0u) << empty.error().message;
  const auto syntax = parse_rig("augrig_rig: 1\ncameras: [\n", "<string>");
  ASSERT_FALSE(syntax);
  EXPECT_NE(syntax.error().message.find("YAML syntax error"), std::string::npos) << syntax.error().message;
}

}  // namespace
}  // namespace augrig
