// pipeline/boom_stage.hpp: each frame's boom from the pose source or the mode in force. Oracles:
// the nozzle tip computed here from the boom's geometry (pivot + length along the direction
// (-cos az cos el, sin az cos el, sin el), length = tube + stick-out + extension + nozzle) and
// cross-checked with render's nozzle_tip_body() (as app/cmd_demo.cpp does), the receptacle placed
// by a receiver pose built here; scripted and fixed booms against values interpolated and clamped
// by hand; the rig's limits.
#include "pipeline/boom_stage.hpp"

#include <cmath>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "render/boom_control.hpp"

namespace augrig::pipeline {
namespace {

constexpr double kDeg = M_PI / 180.0;

// The nozzle tip in the tanker body frame, by hand.
Eigen::Vector3d tip_by_hand(const Eigen::Vector3d& pivot, const BoomDimensions& d,
                            const BoomArticulation& a) {
  const double length = d.fixed_tube_length_m + d.telescope_stick_out_m + a.extension_m + d.nozzle_length_m;
  const double el = a.elevation_rad, az = a.azimuth_rad;
  return pivot +
         length * Eigen::Vector3d(-std::cos(az) * std::cos(el), std::sin(az) * std::cos(el), std::sin(el));
}

BoomArticulation art(double el_deg, double az_deg, double ext_m) {
  return {el_deg * kDeg, az_deg * kDeg, ext_m};
}

void expect_art(const BoomArticulation& got, const BoomArticulation& want, double tol,
                const std::string& what) {
  EXPECT_NEAR(got.elevation_rad, want.elevation_rad, tol) << what;
  EXPECT_NEAR(got.azimuth_rad, want.azimuth_rad, tol) << what;
  EXPECT_NEAR(got.extension_m, want.extension_m, tol) << what;
}

void expect_within_limits(const BoomArticulation& a, const BoomLimits& l, const std::string& what) {
  EXPECT_GE(a.elevation_rad, l.elevation_min_rad - 1e-12) << what;
  EXPECT_LE(a.elevation_rad, l.elevation_max_rad + 1e-12) << what;
  EXPECT_GE(a.azimuth_rad, l.azimuth_min_rad - 1e-12) << what;
  EXPECT_LE(a.azimuth_rad, l.azimuth_max_rad + 1e-12) << what;
  EXPECT_GE(a.extension_m, l.extension_min_m - 1e-12) << what;
  EXPECT_LE(a.extension_m, l.extension_max_m + 1e-12) << what;
}

// A receiver pose (some attitude) that puts `receptacle_m` (receiver body frame) on `target_body`.
Pose receiver_with_receptacle_at(const Eigen::Vector3d& target_body, const Eigen::Vector3d& receptacle_m) {
  const Eigen::Matrix3d R = rotation_from_ypr(3 * kDeg, -4 * kDeg, 2 * kDeg);
  return Pose::from(R, target_body - R * receptacle_m);
}

const Eigen::Vector3d kReceptacle(4.1, 0.05, -0.95);

// The user's boom, as --boom gives it.
BoomArg fixed_arg(const BoomArticulation& a) {
  BoomArg b;
  b.mode = BoomMode::kFixed;
  b.fixed = a;
  return b;
}
BoomArg track_arg() {
  return BoomArg{};  // track is the default
}
BoomArg script_arg() {
  BoomArg b;
  b.mode = BoomMode::kScripted;
  b.script.points = {{0.0, art(20, 0, 1)},  //
                     {2.0, art(30, 10, 3)},
                     {4.0, art(50, 20, 7)}};  // beyond every limit of the paper's rig
  return b;
}

TEST(BoomStage, WithoutAnArgThePoseSourcesBoomAsItComes) {
  const Rig rig = Rig::paper_default();
  BoomStage stage(rig, kReceptacle, std::nullopt);
  EXPECT_EQ(stage.mode(), DisplayBoomMode::kFixed);
  EXPECT_EQ(stage.describe(), "as the poses give it");
  SceneState s;
  s.boom = art(55, -30, 9);  // outside the limits: a pose source's boom is used as given
  s.T_body_receiver = receiver_with_receptacle_at({-14, 0, 8}, kReceptacle);
  stage.apply(s, 0.0);
  expect_art(s.boom, art(55, -30, 9), 0, "as given");
  s.boom = art(25, 1, 2);
  stage.apply(s, 1.0);
  expect_art(s.boom, art(25, 1, 2), 0, "as given, the next frame");
}

TEST(BoomStage, FixedIsTheUsersArticulationClampedToTheLimits) {
  const Rig rig = Rig::paper_default();
  const BoomLimits& L = rig.boom.limits;
  {
    BoomStage stage(rig, kReceptacle, fixed_arg(art(33, -5, 4)));
    EXPECT_EQ(stage.mode(), DisplayBoomMode::kFixed);
    EXPECT_EQ(stage.describe(), "fixed");
    for (double t : {0.0, 5.0, 100.0}) {
      SceneState s;
      s.boom = art(21, 0, 0);  // the pose source's: overridden
      stage.apply(s, t);
      expect_art(s.boom, art(33, -5, 4), 1e-15, "fixed at t " + std::to_string(t));
    }
  }
  BoomStage out(rig, kReceptacle, fixed_arg(art(60, -40, -1)));
  SceneState s;
  out.apply(s, 0.0);
  expect_art(s.boom, {L.elevation_max_rad, L.azimuth_min_rad, L.extension_min_m}, 0, "clamped");
  EXPECT_NEAR(s.boom.elevation_rad, 40 * kDeg, 1e-12);
  EXPECT_NEAR(s.boom.azimuth_rad, -15 * kDeg, 1e-12);
}

TEST(BoomStage, ScriptedInterpolatesHoldsAfterTheEndAndIsClamped) {
  const Rig rig = Rig::paper_default();
  BoomStage stage(rig, kReceptacle, script_arg());
  EXPECT_EQ(stage.mode(), DisplayBoomMode::kScripted);
  EXPECT_EQ(stage.describe(), "scripted");
  auto at = [&](double t) {
    SceneState s;
    s.boom = art(22, 2, 2);  // the pose source's: overridden
    stage.apply(s, t);
    return s.boom;
  };
  expect_art(at(0.0), art(20, 0, 1), 1e-12, "t 0");
  expect_art(at(-1.0), art(20, 0, 1), 1e-12, "held before the first point");
  expect_art(at(1.0), art(25, 5, 2), 1e-12, "half way to the second point");
  expect_art(at(0.5), art(22.5, 2.5, 1.5), 1e-12, "a quarter of the way");
  expect_art(at(2.0), art(30, 10, 3), 1e-12, "t 2");
  // 2.5 s: (35, 12.5, 4) inside the limits; 3.5 s: (45, 17.5, 6) clamped to (40, 15, 5.8).
  expect_art(at(2.5), art(35, 12.5, 4), 1e-12, "t 2.5");
  expect_art(at(3.5), art(40, 15, 5.8), 1e-12, "t 3.5, clamped");
  // After the end: the last point, clamped.
  expect_art(at(4.0), art(40, 15, 5.8), 1e-12, "t 4");
  expect_art(at(60.0), art(40, 15, 5.8), 1e-12, "held after the end");
}

TEST(BoomStage, TrackingPutsTheNozzleTipOnTheReceptacle) {
  const Rig rig = Rig::paper_default();
  const BoomLimits& L = rig.boom.limits;
  const BoomDimensions dims;
  BoomStage stage(rig, kReceptacle, track_arg(), dims);
  EXPECT_EQ(stage.mode(), DisplayBoomMode::kTrackReceptacle);
  EXPECT_EQ(stage.describe(), "tracking the receptacle");
  // Receptacles the boom reaches: each put where an articulation inside the limits puts the tip.
  for (const BoomArticulation& a :
       {art(30, 0, 2.9), art(22, -12, 0.4), art(38.5, 14, 5.5), art(25, 7, 1.0)}) {
    const Eigen::Vector3d target = tip_by_hand(rig.boom.pivot_body_m, dims, a);
    ASSERT_LT((nozzle_tip_body(rig.boom.pivot_body_m, dims, a) - target).norm(), 1e-9)
        << "the two tip computations agree";
    SceneState s;
    s.boom = art(20, 0, 0);
    s.T_body_receiver = receiver_with_receptacle_at(target, kReceptacle);
    stage.apply(s, 0.0);
    const std::string what = "aim " + std::to_string(a.elevation_rad / kDeg) + " deg";
    expect_within_limits(s.boom, L, what);
    EXPECT_LT((tip_by_hand(rig.boom.pivot_body_m, dims, s.boom) - target).norm(), 1e-6) << what;
    expect_art(s.boom, a, 1e-9, what);
    EXPECT_TRUE(s.receiver_present);
  }
}

TEST(BoomStage, TrackingUsesTheBoomItIsGivenAndItsPivot) {
  Rig rig = Rig::paper_default();
  rig.boom.pivot_body_m = Eigen::Vector3d(-6.0, 0.3, 2.6);
  BoomDimensions dims;
  dims.fixed_tube_length_m = 6.0;
  dims.telescope_stick_out_m = 0.5;
  dims.nozzle_length_m = 0.8;
  BoomStage stage(rig, kReceptacle, track_arg(), dims);
  const BoomArticulation a = art(33, -6, 3.3);
  const Eigen::Vector3d target = tip_by_hand(rig.boom.pivot_body_m, dims, a);
  SceneState s;
  s.T_body_receiver = receiver_with_receptacle_at(target, kReceptacle);
  stage.apply(s, 0.0);
  EXPECT_LT((tip_by_hand(rig.boom.pivot_body_m, dims, s.boom) - target).norm(), 1e-6);
  EXPECT_LT((nozzle_tip_body(rig.boom.pivot_body_m, dims, s.boom) - target).norm(), 1e-6);
  expect_art(s.boom, a, 1e-9, "own boom");
}

TEST(BoomStage, TrackingOutOfReachStaysWithinTheLimits) {
  const Rig rig = Rig::paper_default();
  const BoomLimits& L = rig.boom.limits;
  const BoomDimensions dims;
  BoomStage stage(rig, kReceptacle, track_arg(), dims);
  // Straight along the boom at 30 deg but 5 m beyond full extension: full extension, same aim,
  // the tip 5 m short (the nearest point the boom reaches).
  const BoomArticulation along = art(30, 0, L.extension_max_m + 5.0);
  const Eigen::Vector3d far = tip_by_hand(rig.boom.pivot_body_m, dims, along);
  SceneState s;
  s.T_body_receiver = receiver_with_receptacle_at(far, kReceptacle);
  stage.apply(s, 0.0);
  expect_art(s.boom, art(30, 0, L.extension_max_m), 1e-9, "full extension");
  EXPECT_NEAR((tip_by_hand(rig.boom.pivot_body_m, dims, s.boom) - far).norm(), 5.0, 1e-6);
  // Far off to the side and above the limits: every axis within the limits.
  for (const BoomArticulation& a : {art(70, 40, 3), art(5, -50, -3), art(-20, 0, 12)}) {
    SceneState o;
    o.T_body_receiver = receiver_with_receptacle_at(tip_by_hand(rig.boom.pivot_body_m, dims, a), kReceptacle);
    stage.apply(o, 0.0);
    expect_within_limits(o.boom, L, "unreachable");
  }
}

TEST(BoomStage, WithoutAReceiverTrackingHoldsTheLastBoom) {
  const Rig rig = Rig::paper_default();
  const BoomDimensions dims;
  BoomStage stage(rig, kReceptacle, track_arg(), dims);
  // No receiver and nothing tracked yet: the boom the frame came with.
  SceneState none;
  none.receiver_present = false;
  none.boom = art(24, 3, 1.5);
  stage.apply(none, 0.0);
  expect_art(none.boom, art(24, 3, 1.5), 0, "nothing to track yet");

  const BoomArticulation a = art(31, 4, 2.2);
  SceneState s;
  s.T_body_receiver = receiver_with_receptacle_at(tip_by_hand(rig.boom.pivot_body_m, dims, a), kReceptacle);
  stage.apply(s, 0.1);
  expect_art(s.boom, a, 1e-9, "tracked");
  // The receiver lost: the boom holds where it was, whatever the frame says.
  SceneState lost;
  lost.receiver_present = false;
  lost.boom = art(20, 0, 0);
  lost.T_body_receiver = receiver_with_receptacle_at({-20, 0, 12}, kReceptacle);
  stage.apply(lost, 0.2);
  expect_art(lost.boom, s.boom, 0, "held");
  stage.apply(lost, 0.3);
  expect_art(lost.boom, s.boom, 0, "still held");
}

TEST(BoomStage, NudgesMakeItInteractiveFromTheLastBoomClampedToTheLimits) {
  const Rig rig = Rig::paper_default();
  const BoomLimits& L = rig.boom.limits;
  const BoomDimensions dims;
  BoomStage stage(rig, kReceptacle, track_arg(), dims);
  const BoomArticulation a = art(30, 2, 3);
  const Pose T = receiver_with_receptacle_at(tip_by_hand(rig.boom.pivot_body_m, dims, a), kReceptacle);
  SceneState s;
  s.T_body_receiver = T;
  stage.apply(s, 0.0);
  expect_art(s.boom, a, 1e-9, "tracked");

  // A zero nudge changes nothing.
  stage.nudge(BoomNudge{});
  EXPECT_EQ(stage.mode(), DisplayBoomMode::kTrackReceptacle);

  stage.nudge({2 * kDeg, -1 * kDeg, 0.5});
  EXPECT_EQ(stage.mode(), DisplayBoomMode::kInteractive);
  EXPECT_EQ(stage.describe(), "interactive");
  SceneState f;
  f.T_body_receiver = T;  // the receiver is still there: not tracked any more
  f.boom = art(20, 0, 0);
  stage.apply(f, 0.1);
  expect_art(f.boom, art(32, 1, 3.5), 1e-12, "the tracked boom nudged");
  // Nudges add up; the operator holds the boom where it was between them.
  stage.nudge({1 * kDeg, 0, -0.25});
  stage.apply(f, 0.2);
  expect_art(f.boom, art(33, 1, 3.25), 1e-12, "nudged twice");
  stage.apply(f, 0.3);
  expect_art(f.boom, art(33, 1, 3.25), 1e-12, "held");
  // Beyond the limits: clamped; a nudge back moves it from the limit.
  stage.nudge({20 * kDeg, -40 * kDeg, 10});
  stage.apply(f, 0.4);
  expect_art(f.boom, {L.elevation_max_rad, L.azimuth_min_rad, L.extension_max_m}, 1e-12, "clamped");
  stage.nudge({-1 * kDeg, 1 * kDeg, -1});
  stage.apply(f, 0.5);
  expect_art(f.boom, art(39, -14, 4.8), 1e-12, "back from the limits");

  // Back to tracking: the receptacle again.
  stage.set_mode(DisplayBoomMode::kTrackReceptacle);
  stage.apply(f, 0.6);
  expect_art(f.boom, a, 1e-9, "tracking again");
}

// Taking the boom over by hand again after another mode flew it: the nudge moves the boom from
// where it is (docs/DISPLAY.md: "moving the boom by hand takes it over"; Up/Down move it by 0.5
// deg), and pressing 4 (interactive) holds it where it is; it does not jump back to where the
// operator left it before.
TEST(BoomStage, TakingTheBoomOverAgainStartsWhereItIs) {
  const Rig rig = Rig::paper_default();
  const BoomDimensions dims;
  BoomStage stage(rig, kReceptacle, track_arg(), dims);
  SceneState s;
  s.T_body_receiver =
      receiver_with_receptacle_at(tip_by_hand(rig.boom.pivot_body_m, dims, art(30, 0, 3)), kReceptacle);
  stage.apply(s, 0.0);
  stage.nudge({2 * kDeg, 0, 0});  // the operator takes over: (32, 0, 3)
  stage.apply(s, 0.1);
  expect_art(s.boom, art(32, 0, 3), 1e-9, "first take-over");
  // Back to tracking; the receptacle moves: the boom follows it.
  stage.set_mode(DisplayBoomMode::kTrackReceptacle);
  const BoomArticulation y = art(25, -6, 1.5);
  s.T_body_receiver = receiver_with_receptacle_at(tip_by_hand(rig.boom.pivot_body_m, dims, y), kReceptacle);
  stage.apply(s, 0.2);
  expect_art(s.boom, y, 1e-9, "tracked");
  // A nudge takes it over again: from where it is now.
  stage.nudge({0.5 * kDeg, 0, 0});
  stage.apply(s, 0.3);
  expect_art(s.boom, art(25.5, -6, 1.5), 1e-9, "nudged from where the boom is");
  // The same with the mode key: the boom stays where tracking left it.
  stage.set_mode(DisplayBoomMode::kTrackReceptacle);
  stage.apply(s, 0.4);
  expect_art(s.boom, y, 1e-9, "tracked again");
  stage.set_mode(DisplayBoomMode::kInteractive);
  stage.apply(s, 0.5);
  expect_art(s.boom, y, 1e-9, "interactive: held where it is");
}

TEST(BoomStage, ModeChangesFromTheWindow) {
  const Rig rig = Rig::paper_default();
  const BoomDimensions dims;
  // The user asked for a script; the window switches to fixed: the pose source's boom.
  BoomStage stage(rig, kReceptacle, script_arg(), dims);
  SceneState s;
  s.boom = art(26, -3, 1.2);
  stage.set_mode(DisplayBoomMode::kFixed);
  EXPECT_EQ(stage.describe(), "as the poses give it");
  stage.apply(s, 1.0);
  expect_art(s.boom, art(26, -3, 1.2), 0, "the pose source's");
  // Back to scripted: the script's.
  stage.set_mode(DisplayBoomMode::kScripted);
  stage.apply(s, 1.0);
  expect_art(s.boom, art(25, 5, 2), 1e-12, "the script's");
  // To tracking: the receptacle.
  const BoomArticulation a = art(28, -8, 1.7);
  s.T_body_receiver = receiver_with_receptacle_at(tip_by_hand(rig.boom.pivot_body_m, dims, a), kReceptacle);
  stage.set_mode(DisplayBoomMode::kTrackReceptacle);
  stage.apply(s, 1.5);
  expect_art(s.boom, a, 1e-9, "tracking");
  // Interactive without a nudge: starts where the boom was and stays there.
  stage.set_mode(DisplayBoomMode::kInteractive);
  SceneState i;
  i.boom = art(21, 0, 0);
  stage.apply(i, 2.0);
  expect_art(i.boom, a, 1e-9, "interactive from the last boom");

  // The user's fixed boom; the window asks for scripted, which the user gave no script for: the pose
  // source's boom.
  BoomStage fixed(rig, kReceptacle, fixed_arg(art(35, 0, 3)), dims);
  fixed.set_mode(DisplayBoomMode::kScripted);
  SceneState p;
  p.boom = art(23, 1, 0.5);
  fixed.apply(p, 0.0);
  expect_art(p.boom, art(23, 1, 0.5), 0, "no script: the pose source's");
  fixed.set_mode(DisplayBoomMode::kFixed);
  fixed.apply(p, 0.0);
  expect_art(p.boom, art(35, 0, 3), 1e-12, "the user's fixed boom");
}

// How fast the boom moves (the camera look's motion blur): a script's slope, clamped with it; a
// fixed or hand-flown boom none; a tracking boom's and the pose source's change since the last
// frame, none on a mode's first frame, across a gap or back in time.
TEST(BoomStage, RateIsTheScriptsSlopeOrTheChangeSinceTheLastFrame) {
  const Rig rig = Rig::paper_default();
  BoomStage scripted(rig, kReceptacle, script_arg());
  SceneState s;
  scripted.apply(s, 1.0);  // (20, 0, 1) -> (30, 10, 3) over 2 s
  expect_art(s.boom_rate_per_s, art(5, 5, 1), 1e-9, "the script's slope");
  scripted.apply(s, 3.5);  // clamped in every axis: held at the limits
  expect_art(s.boom_rate_per_s, art(0, 0, 0), 1e-9, "clamped");

  BoomStage fixed(rig, kReceptacle, fixed_arg(art(33, -5, 4)));
  for (double t : {0.0, 0.033}) {
    fixed.apply(s, t);
    expect_art(s.boom_rate_per_s, {}, 0, "fixed");
  }

  BoomStage given(rig, kReceptacle, std::nullopt);
  s.boom = art(25, 1, 2);
  given.apply(s, 10.0);
  expect_art(s.boom_rate_per_s, {}, 0, "the first frame");
  s.boom = art(25.1, 0.9, 2.05);
  given.apply(s, 10.05);
  expect_art(s.boom_rate_per_s, art(2, -2, 1), 1e-9, "the pose source's change over 50 ms");
  s.boom = art(26, 0, 2);
  given.apply(s, 10.05 + BoomStage::kMaxRateGap_s + 0.01);
  expect_art(s.boom_rate_per_s, {}, 0, "across a gap");
  s.boom = art(25, 0, 2);
  given.apply(s, 9.0);
  expect_art(s.boom_rate_per_s, {}, 0, "back in time");

  BoomStage track(rig, kReceptacle, track_arg());
  s.T_body_receiver = receiver_with_receptacle_at({-14, 0, 8}, kReceptacle);
  track.apply(s, 0.0);
  const BoomArticulation first = s.boom;
  s.T_body_receiver = receiver_with_receptacle_at({-14, 0.1, 8}, kReceptacle);
  track.apply(s, 0.04);
  EXPECT_NEAR(s.boom_rate_per_s.azimuth_rad, (s.boom.azimuth_rad - first.azimuth_rad) / 0.04, 1e-9);
  EXPECT_NE(s.boom_rate_per_s.azimuth_rad, 0.0);
  track.set_mode(DisplayBoomMode::kInteractive);
  track.apply(s, 0.08);
  expect_art(s.boom_rate_per_s, {}, 0, "hand-flown");
  track.set_mode(DisplayBoomMode::kTrackReceptacle);
  track.apply(s, 0.12);
  expect_art(s.boom_rate_per_s, {}, 0, "a mode's first frame");
}

TEST(BoomArg, CommandPerMode) {
  const BoomLimits L = Rig::paper_default().boom.limits;
  const BoomCommand tracked{art(27, 3, 2), true, 0.4};
  const BoomCommand t = track_arg().command(1.0, tracked, L);
  expect_art(t.articulation, tracked.articulation, 0, "track passes tracking through");
  EXPECT_TRUE(t.clamped);
  EXPECT_EQ(t.miss_m, 0.4);
  const BoomCommand f = fixed_arg(art(45, 0, 1)).command(1.0, tracked, L);
  expect_art(f.articulation, art(40, 0, 1), 1e-12, "fixed, clamped");
  EXPECT_TRUE(f.clamped);
  const BoomCommand s = script_arg().command(1.0, tracked, L);
  expect_art(s.articulation, art(25, 5, 2), 1e-12, "scripted");
  EXPECT_FALSE(s.clamped);
}

}  // namespace
}  // namespace augrig::pipeline
