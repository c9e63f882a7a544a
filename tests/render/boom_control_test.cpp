// Boom control: tracking puts the nozzle tip on reachable targets and clamps the rest; scripts
// interpolate and reject bad files with located errors.
#include "render/boom_control.hpp"

#include <filesystem>
#include <random>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

TEST(BoomControl, TrackPutsTheNozzleTipOnReachableTargets) {
  const Rig rig = Rig::paper_default();
  const BoomDimensions dims;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const BoomLimits& l = rig.boom.limits;
  for (int i = 0; i < 200; ++i) {
    // A target made from a random articulation inside the limits: tracking must recover it.
    BoomArticulation a;
    a.elevation_rad = l.elevation_min_rad + u(rng) * (l.elevation_max_rad - l.elevation_min_rad);
    a.azimuth_rad = l.azimuth_min_rad + u(rng) * (l.azimuth_max_rad - l.azimuth_min_rad);
    a.extension_m = l.extension_min_m + u(rng) * (l.extension_max_m - l.extension_min_m);
    const Eigen::Vector3d target = nozzle_tip_body(rig.boom.pivot_body_m, dims, a);
    const BoomCommand c = track_point(target, rig.boom.pivot_body_m, dims, l);
    EXPECT_FALSE(c.clamped);
    EXPECT_LT(c.miss_m, 1e-9);
    EXPECT_NEAR(c.articulation.elevation_rad, a.elevation_rad, 1e-12);
    EXPECT_NEAR(c.articulation.azimuth_rad, a.azimuth_rad, 1e-12);
    EXPECT_NEAR(c.articulation.extension_m, a.extension_m, 1e-9);
  }
}

TEST(BoomControl, HandWorkedGeometry) {
  // Pivot at the origin; a target straight aft and 30 deg down at 10 m: elevation 30 deg, azimuth 0.
  const BoomDimensions dims;
  BoomLimits l{deg_to_rad(0), deg_to_rad(60), deg_to_rad(-30), deg_to_rad(30), 0.0, 10.0};
  const double r = 10.0;
  const Eigen::Vector3d target(-r * std::cos(deg_to_rad(30)), 0.0, r * std::sin(deg_to_rad(30)));
  const BoomCommand c = track_point(target, Eigen::Vector3d::Zero(), dims, l);
  EXPECT_NEAR(rad_to_deg(c.articulation.elevation_rad), 30.0, 1e-12);
  EXPECT_NEAR(rad_to_deg(c.articulation.azimuth_rad), 0.0, 1e-12);
  EXPECT_NEAR(c.articulation.extension_m, r - dims.nozzle_tip_m(0.0), 1e-12);
  // Moving the target to starboard (+y) turns the boom to positive azimuth.
  const BoomCommand s = track_point(target + Eigen::Vector3d(0, 1.0, 0), Eigen::Vector3d::Zero(), dims, l);
  EXPECT_GT(s.articulation.azimuth_rad, 0.0);
}

TEST(BoomControl, UnreachableTargetsAreClampedAndReported) {
  const Rig rig = Rig::paper_default();
  const BoomDimensions dims;
  const BoomLimits& l = rig.boom.limits;
  // Far aft, level with the pivot: elevation below its minimum, extension beyond its maximum.
  const Eigen::Vector3d target = rig.boom.pivot_body_m + Eigen::Vector3d(-40.0, 0.0, 0.0);
  const BoomCommand c = track_point(target, rig.boom.pivot_body_m, dims, l);
  EXPECT_TRUE(c.clamped);
  EXPECT_DOUBLE_EQ(c.articulation.elevation_rad, l.elevation_min_rad);
  EXPECT_DOUBLE_EQ(c.articulation.extension_m, l.extension_max_m);
  EXPECT_GT(c.miss_m, 20.0);
  // The clamped articulation is the one the miss distance was measured for.
  EXPECT_NEAR(c.miss_m, (nozzle_tip_body(rig.boom.pivot_body_m, dims, c.articulation) - target).norm(),
              1e-12);
}

TEST(BoomControl, ScriptInterpolatesAndHoldsEnds) {
  auto s = parse_boom_script(
      "# a test timeline\n"
      "t_s,elevation_deg,azimuth_deg,extension_m\n"
      "0,20,0,0\n"
      "10,30,-10,4\n",
      "<test>");
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_NEAR(rad_to_deg(s->at(5).elevation_rad), 25.0, 1e-12);
  EXPECT_NEAR(rad_to_deg(s->at(5).azimuth_rad), -5.0, 1e-12);
  EXPECT_NEAR(s->at(5).extension_m, 2.0, 1e-12);
  EXPECT_NEAR(rad_to_deg(s->at(-3).elevation_rad), 20.0, 1e-12);
  EXPECT_NEAR(s->at(99).extension_m, 4.0, 1e-12);
}

TEST(BoomControl, BadScriptsNameLineAndColumn) {
  struct Case {
    const char* text;
    const char* expect;
  };
  const Case cases[] = {
      {"time,el,az,ext\n0,1,2,3\n", "<bad>:1: expected the header"},
      {"t_s,elevation_deg,azimuth_deg,extension_m\n0,20,0\n", "<bad>:2: expected 4 columns, got 3"},
      {"t_s,elevation_deg,azimuth_deg,extension_m\n0,20,x,1\n",
       "<bad>:2: column 'azimuth_deg': expected a number"},
      {"t_s,elevation_deg,azimuth_deg,extension_m\n1,20,0,1\n1,21,0,1\n",
       "<bad>:3: column 't_s': times must increase"},
      {"t_s,elevation_deg,azimuth_deg,extension_m\n", "no boom positions"},
      {"", "no boom positions"},
  };
  for (const Case& c : cases) {
    auto s = parse_boom_script(c.text, "<bad>");
    ASSERT_FALSE(s) << c.text;
    EXPECT_NE(s.error().message.find(c.expect), std::string::npos) << s.error().message;
  }
  auto missing = load_boom_script("/nonexistent/boom.csv");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("/nonexistent/boom.csv"), std::string::npos);
}

// A directory given as the boom script used to read as an empty script ("no boom positions").
TEST(BoomControl, DirectoryIsNotABoomScript) {
  const std::string dir = test::output_dir("boom_control_test_dir") + "/boom.csv";
  std::filesystem::create_directories(dir);
  const auto s = load_boom_script(dir);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "boom_script::load(): " + dir + ": is a directory, expected a file");
}

TEST(BoomControl, ModeNames) {
  EXPECT_EQ(*boom_mode_from_string("track"), BoomMode::kTrackReceptacle);
  EXPECT_EQ(*boom_mode_from_string("scripted"), BoomMode::kScripted);
  EXPECT_FALSE(boom_mode_from_string("wiggle"));
}

}  // namespace
}  // namespace augrig
