// Scene files: valid scenes give hand-worked T_body_receiver; every kind of bad scene gives one
// error naming the file, the line and the key.
#include "pipeline/scene_file.hpp"

#include <filesystem>
#include <string>
#include <tuple>

#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

using test::data_path;

// A receptacle stated here, not taken from the built-in model, so the numbers below are by hand.
const Eigen::Vector3d kReceptacle(4.0, 0.0, -0.9);

Expected<SceneState> load(const std::string& name, SceneExtras* extras = nullptr) {
  return load_scene(data_path("scenes/" + name), Rig::paper_default(), BoomDimensions{}, kReceptacle, extras);
}

void expect_vec(const Eigen::Vector3d& v, double x, double y, double z) {
  EXPECT_NEAR(v.x(), x, 1e-9);
  EXPECT_NEAR(v.y(), y, 1e-9);
  EXPECT_NEAR(v.z(), z, 1e-9);
}

TEST(SceneFile, AtContactPutsTheReceptacleAtTheNozzleTipPlusOffset) {
  SceneExtras extras;
  const auto s = load("contact.yaml", &extras);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_NEAR(s->boom.elevation_rad, deg_to_rad(30.0), 1e-12);
  EXPECT_NEAR(s->boom.azimuth_rad, 0.0, 1e-12);
  EXPECT_NEAR(s->boom.extension_m, 2.0, 1e-12);
  EXPECT_TRUE(s->receiver_present);
  ASSERT_TRUE(extras.t_ns.has_value());
  EXPECT_EQ(*extras.t_ns, 1000000000);
  // Nozzle tip: pivot (-4, 0, 2.3) + (7 + 1 + 2 + 0.5) m * (-cos 30, 0, sin 30) = (-13.0933, 0, 7.55).
  // T_body_receiver.t = tip + offset (0, 0, 0.5) - receptacle (4, 0, -0.9); attitude = tanker's.
  expect_vec(s->T_body_receiver.translation_m, -13.093266739736606 - 4.0, 0.0, 7.55 + 0.5 + 0.9);
  EXPECT_TRUE(s->T_body_receiver.R().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  // The receptacle, mapped to the body frame, sits 0.5 m below the tip.
  expect_vec(s->T_body_receiver * kReceptacle, -13.093266739736606, 0.0, 8.05);
}

TEST(SceneFile, AtContactWithAzimuthAndYaw) {
  const std::string text =
      "augrig_scene: 1\n"
      "boom: {elevation_deg: 20, azimuth_deg: 10, extension_m: 0}\n"
      "receiver: {at_contact: true, ypr_deg: [90, 0, 0]}\n";
  const auto s = parse_scene(text, "<string>", Rig::paper_default(), BoomDimensions{}, kReceptacle);
  ASSERT_TRUE(s) << s.error().message;
  // Tip: pivot + 8.5 m * (-cos20 cos10, cos20 sin10, sin20); Rz(90) * receptacle = (0, 4, -0.9).
  expect_vec(s->T_body_receiver.translation_m, -11.86604091638575, 1.386995244915546 - 4.0,
             5.207171218268184 + 0.9);
  const Eigen::Matrix3d R = s->T_body_receiver.R();
  expect_vec(R.col(0), 0, 1, 0);  // receiver nose points to the tanker's right
}

TEST(SceneFile, BodyRelativePose) {
  SceneExtras extras;
  const auto s = load("body.yaml", &extras);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_FALSE(extras.t_ns.has_value());
  EXPECT_NEAR(s->boom.azimuth_rad, deg_to_rad(-5.0), 1e-12);
  expect_vec(s->T_body_receiver.translation_m, -20, 1, 8);
  const Eigen::Matrix3d R = s->T_body_receiver.R();
  // Yaw 10 deg: nose (receiver x) at (cos 10, sin 10, 0) in the body frame.
  expect_vec(R.col(0), 0.984807753012208, 0.17364817766693033, 0.0);
  expect_vec(R.col(2), 0, 0, 1);
}

TEST(SceneFile, CameraRelativePoseComposesWithTheCameraExtrinsics) {
  const auto s = load("left_camera.yaml");
  ASSERT_TRUE(s) << s.error().message;
  // Left camera at (0, 0.25, 2) looking aft, 25 deg down: optical axis (-cos 25, 0, sin 25).
  // 20 m along it: (-18.1262, 0.25, 2 + 8.4524).
  expect_vec(s->T_body_receiver.translation_m, -18.126155740732997, 0.25, 10.452365234813989);
  // ypr 0: receiver axes = camera axes: x (image right) -> body -y, y (image down) -> (sin25, 0, cos25).
  const Eigen::Matrix3d R = s->T_body_receiver.R();
  expect_vec(R.col(0), 0, -1, 0);
  expect_vec(R.col(1), 0.42261826174069944, 0, 0.9063077870366499);
  expect_vec(R.col(2), -0.9063077870366499, 0, 0.42261826174069944);
}

TEST(SceneFile, RightCameraDiffersFromLeftByTheBaseline) {
  const std::string text =
      "augrig_scene: 1\nboom: {elevation_deg: 30, azimuth_deg: 0, extension_m: 0}\n"
      "receiver: {frame: right, translation_m: [0, 0, 20]}\n";
  const auto s = parse_scene(text, "<string>", Rig::paper_default(), BoomDimensions{}, kReceptacle);
  ASSERT_TRUE(s) << s.error().message;
  expect_vec(s->T_body_receiver.translation_m, -18.126155740732997, -0.25, 10.452365234813989);
}

TEST(SceneFile, AbsentReceiverNeedsNoPose) {
  const auto s = load("absent.yaml");
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_FALSE(s->receiver_present);
  EXPECT_NEAR(s->boom.extension_m, 4.0, 1e-12);
}

TEST(SceneFile, MissingFileNamesIt) {
  const auto s = load("no_such_scene.yaml");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("no_such_scene.yaml"), std::string::npos) << s.error().message;
}

// A directory given as the scene file used to read as an empty document ("got nothing (null)").
TEST(SceneFile, DirectoryIsNotASceneFile) {
  const std::string dir = test::output_dir("scene_file_test_dir") + "/scene.yaml";
  std::filesystem::create_directories(dir);
  const auto s = load_scene(dir, Rig::paper_default(), BoomDimensions{}, kReceptacle);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "scene::load(): " + dir + ": is a directory, expected a file");
}

struct BadScene {
  const char* file;
  int line;              // 1-based line the error must point at
  const char* key;       // key path that must be named ("" for syntax errors)
  const char* expected;  // a phrase of the explanation
};

class BadSceneTest : public ::testing::TestWithParam<BadScene> {};

TEST_P(BadSceneTest, ErrorNamesFileLineAndKey) {
  const BadScene& b = GetParam();
  const auto s = load(b.file);
  ASSERT_FALSE(s) << b.file << " loaded";
  const std::string& m = s.error().message;
  const std::string where = std::string(b.file) + ":" + std::to_string(b.line) + ":";
  EXPECT_NE(m.find(where), std::string::npos) << "expected '" << where << "' in: " << m;
  if (*b.key) {
    EXPECT_NE(m.find(std::string("key '") + b.key + "'"), std::string::npos) << m;
  }
  EXPECT_NE(m.find(b.expected), std::string::npos) << m;
  EXPECT_EQ(m.find('\n'), std::string::npos) << "one line: " << m;
}

INSTANTIATE_TEST_SUITE_P(
    AllKinds, BadSceneTest,
    ::testing::Values(
        BadScene{"bad_syntax.yaml", 3, "", "YAML syntax error"},
        BadScene{"bad_unknown_key.yaml", 5, "receiver.ofset_m", "allowed keys here: frame"},
        BadScene{"bad_wrong_type.yaml", 3, "boom.elevation_deg", "got 'thirty'"},
        BadScene{"bad_boom_limits.yaml", 5, "boom.extension_m", "limits [0, 5.8] metres, got 7.5"},
        BadScene{"bad_missing_receiver.yaml", 1, "receiver", "missing"},
        BadScene{"bad_frame.yaml", 4, "receiver.frame", "one of body, left, right"},
        BadScene{"bad_list_length.yaml", 5, "receiver.translation_m", "got a list of 2"},
        BadScene{"bad_missing_version.yaml", 2, "augrig_scene", "missing"},
        BadScene{"bad_version.yaml", 1, "augrig_scene", "version 1"},
        BadScene{"bad_contact_and_frame.yaml", 5, "receiver.frame", "not allowed with at_contact"},
        BadScene{"bad_t_ns.yaml", 2, "t_ns", "integer"}),
    [](const auto& info) {
      std::string n = info.param.file;
      return n.substr(0, n.find('.'));
    });

TEST(SceneFile, ElevationOutsideLimitsNamesTheLimitsInDegrees) {
  const std::string text =
      "augrig_scene: 1\nboom: {elevation_deg: 45, azimuth_deg: 0, extension_m: 0}\nreceiver: {at_contact: "
      "true}\n";
  const auto s = parse_scene(text, "inline.yaml", Rig::paper_default(), BoomDimensions{}, kReceptacle);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("inline.yaml:2:"), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("key 'boom.elevation_deg'"), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("[20, 40] degrees, got 45"), std::string::npos) << s.error().message;
}

// `sun:` sets the camera look's light in the body frame (azimuth from the nose, positive right;
// elevation above the wings' plane); without it the scene keeps the plain look's fixed light.
TEST(SceneFile, SunKeySetsTheLightInTheBodyFrame) {
  const std::string head =
      "augrig_scene: 1\nboom: {elevation_deg: 30, azimuth_deg: 0, extension_m: 2}\nreceiver: {at_contact: true}\n";
  auto s = parse_scene(head + "sun: {azimuth_deg: 90, elevation_deg: 30, direct: 0, sky: 0.6, ground: 0.3}\n",
                       "sun.yaml", Rig::paper_default(), BoomDimensions{}, kReceptacle);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->light.source, LightSource::kConfigured);
  expect_vec(s->light.towards_light_body, 0, std::cos(deg_to_rad(30)), -0.5);  // to the right, above
  EXPECT_EQ(s->light.direct, Eigen::Vector3d::Zero());
  EXPECT_EQ(s->light.sky, Eigen::Vector3d::Constant(0.6));
  EXPECT_EQ(s->light.ground, Eigen::Vector3d::Constant(0.3));
  s = parse_scene(head, "nosun.yaml", Rig::paper_default(), BoomDimensions{}, kReceptacle);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->light.source, LightSource::kFixed);
  for (const auto& [line, key, phrase] :
       {std::tuple{"sun: {azimuth_deg: 0, elevation_deg: 95}", "sun.elevation_deg", "-90..90 degrees, got 95"},
        std::tuple{"sun: {elevation_deg: 10}", "sun.azimuth_deg", "missing"},
        std::tuple{"sun: {azimuth_deg: 0, elevation_deg: 10, direct: -1}", "sun.direct", "0..2, got -1"},
        std::tuple{"sun: {azimuth_deg: 0, elevation_deg: 10, ambient: 1}", "sun.ambient", "unknown key"},
        std::tuple{"sun: 45", "sun", "a map {azimuth_deg"}}) {
    const auto bad = parse_scene(head + line + "\n", "bad.yaml", Rig::paper_default(), BoomDimensions{}, kReceptacle);
    ASSERT_FALSE(bad) << line;
    const std::string& m = bad.error().message;
    EXPECT_NE(m.find("bad.yaml:4:"), std::string::npos) << m;
    EXPECT_NE(m.find(std::string("key '") + key + "'"), std::string::npos) << m;
    EXPECT_NE(m.find(phrase), std::string::npos) << m;
  }
}

}  // namespace
}  // namespace augrig
