// pipeline/poses.hpp: the fixed scene, the poses recorded with replayed frames, `augrig nav`'s
// poses.csv and the simulation's truth, each asked for frames made here. Oracles: the scenes and
// records given (copied through unchanged), the rig's left camera pose composed with the camera-
// relative pose as 4x4 matrices, a poses.csv written here by hand, and sim::frame_truths of a
// short scenario for the frames its source actually delivers. choose_poses(): the one order of the
// sources every command offers, each source's own provider (by what it answers), the alternatives
// that exclude each other, a folder of scene files with their timestamps, errors naming the file.
#include "pipeline/poses.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/conventions.hpp"
#include "pipeline/scene_file.hpp"
#include "recorder/replay_source.hpp"
#include "sim/flight_source.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

Pose pose(double yaw_deg, double pitch_deg, double roll_deg, const Eigen::Vector3d& t) {
  return pose_from_ypr(t, deg_to_rad(yaw_deg), deg_to_rad(pitch_deg), deg_to_rad(roll_deg));
}

void expect_pose_near(const Pose& got, const Eigen::Matrix4d& want, double tol, const std::string& what) {
  EXPECT_TRUE(got.matrix().isApprox(want, tol)) << what << "\ngot\n" << got.matrix() << "\nwant\n" << want;
  EXPECT_LT((got.matrix() - want).cwiseAbs().maxCoeff(), tol) << what;
}
void expect_pose_eq(const Pose& got, const Pose& want, const std::string& what) {
  expect_pose_near(got, want.matrix(), 1e-12, what);
}
void expect_boom_eq(const BoomArticulation& got, const BoomArticulation& want, const std::string& what) {
  EXPECT_DOUBLE_EQ(got.elevation_rad, want.elevation_rad) << what;
  EXPECT_DOUBLE_EQ(got.azimuth_rad, want.azimuth_rad) << what;
  EXPECT_DOUBLE_EQ(got.extension_m, want.extension_m) << what;
}

StereoFrame frame_at(TimestampNs t_ns, std::uint64_t sequence = 0) {
  StereoFrame f;
  f.left.camera = CameraId::kLeft;
  f.left.t_ns = t_ns;
  f.left.sequence = sequence;
  f.right.camera = CameraId::kRight;
  f.right.t_ns = t_ns + 1000;
  f.right.sequence = sequence;
  f.t_key_ns = t_ns + 500;
  f.skew_ns = 1000;
  return f;
}

// A frame of a replayed recording: both cameras carry the recorded frame.
StereoFrame recorded_frame(const recorder::FrameRecord& record, std::size_t index) {
  auto rf = std::make_shared<recorder::RecordedFrame>();
  rf->index = index;
  rf->record = record;
  StereoFrame f = frame_at(1'000'000'000 + static_cast<TimestampNs>(index));
  f.left.attachment = rf;
  f.right.attachment = rf;
  return f;
}

TEST(FixedScenePoses, TheSameSceneForEveryFrame) {
  SceneState scene;
  scene.boom = {0.4, -0.1, 2.5};
  scene.T_body_receiver = pose(3, -2, 1, {-18, 0.5, 9});
  auto p = fixed_scene_poses(scene, "contact.yaml");
  EXPECT_EQ(p->describe(), "the scene contact.yaml");
  EXPECT_FALSE(p->live());
  for (TimestampNs t : {TimestampNs{0}, TimestampNs{123'456'789}, TimestampNs{9'000'000'000}}) {
    const FramePoses fp = p->at(frame_at(t), t + 7);
    ASSERT_TRUE(fp.scene) << t;
    EXPECT_TRUE(fp.boom_given);
    EXPECT_FALSE(fp.stale);
    EXPECT_TRUE(fp.problems.empty());
    expect_boom_eq(fp.scene->boom, scene.boom, "boom");
    expect_pose_eq(fp.scene->T_body_receiver, scene.T_body_receiver, "receiver");
    EXPECT_TRUE(fp.scene->receiver_present);
  }
}

TEST(RecordedPoses, BoomAndBodyPoseAsRecorded) {
  recorder::FrameRecord r;
  r.boom = BoomArticulation{0.5, 0.05, 3.0};
  r.T_body_receiver = pose(1, 2, 3, {-17, 0.2, 8.5});
  // A camera-relative pose that disagrees: the body pose recorded wins.
  r.T_cam_receiver[0] = pose(0, 0, 0, {1, 2, 30});
  r.sigma_pos_m = 0.012;
  r.sigma_att_deg = 0.2;
  auto p = recorded_poses(Rig::paper_default());
  const FramePoses fp = p->at(recorded_frame(r, 5), 0);
  ASSERT_TRUE(fp.scene);
  EXPECT_TRUE(fp.boom_given);
  EXPECT_TRUE(fp.problems.empty());
  expect_boom_eq(fp.scene->boom, *r.boom, "boom");
  expect_pose_eq(fp.scene->T_body_receiver, *r.T_body_receiver, "receiver");
  EXPECT_TRUE(fp.scene->receiver_present);
  EXPECT_EQ(fp.sigma_pos_m, 0.012);
  EXPECT_EQ(fp.sigma_att_deg, 0.2);
  EXPECT_EQ(fp.hud.sigma_pos_m, 0.012);
}

TEST(RecordedPoses, OnlyTheLeftCameraPoseGoesThroughTheRecordedRig) {
  Rig rig = Rig::paper_default();
  // A left camera mounted off any axis, so that the composition order matters.
  rig.cameras[0].T_body_cam = pose(170, -30, 4, {0.3, 0.25, 2.1});
  recorder::FrameRecord r;
  r.boom = BoomArticulation{0.45, 0.0, 1.0};
  r.T_cam_receiver[0] = pose(-80, 10, 60, {-1.5, -2.8, 50.0});
  r.T_cam_receiver[1] = pose(0, 0, 0, {0, 0, 1});  // the right one is not used
  auto p = recorded_poses(rig);
  const FramePoses fp = p->at(recorded_frame(r, 0), 0);
  ASSERT_TRUE(fp.scene);
  EXPECT_TRUE(fp.boom_given);
  const Eigen::Matrix4d want = rig.left().T_body_cam.matrix() * r.T_cam_receiver[0]->matrix();
  expect_pose_near(fp.scene->T_body_receiver, want, 1e-9, "T_body_cam * T_cam_receiver");
  EXPECT_TRUE(fp.scene->receiver_present);
}

TEST(RecordedPoses, APoseWithoutABoomLeavesTheBoomToAugrig) {
  recorder::FrameRecord r;
  r.T_body_receiver = pose(0, 1, 0, {-20, 0, 10});
  auto p = recorded_poses(std::nullopt);
  const FramePoses fp = p->at(recorded_frame(r, 3), 0);
  ASSERT_TRUE(fp.scene);
  EXPECT_FALSE(fp.boom_given);
  expect_pose_eq(fp.scene->T_body_receiver, *r.T_body_receiver, "receiver");
  EXPECT_TRUE(fp.scene->receiver_present);

  // Only a camera-relative pose and a rig: the same.
  recorder::FrameRecord c;
  c.T_cam_receiver[0] = pose(0, 0, 0, {0, 0, 40});
  const Rig rig = Rig::paper_default();
  const FramePoses fc = recorded_poses(rig)->at(recorded_frame(c, 4), 0);
  ASSERT_TRUE(fc.scene);
  EXPECT_FALSE(fc.boom_given);
  expect_pose_near(fc.scene->T_body_receiver, rig.left().T_body_cam.matrix() * c.T_cam_receiver[0]->matrix(),
                   1e-9, "through the rig");
}

TEST(RecordedPoses, ABoomWithoutAReceiverOrAReceiverRecordedAbsent) {
  recorder::FrameRecord r;
  r.boom = BoomArticulation{0.6, 0.1, 2.0};
  const FramePoses fp = recorded_poses(std::nullopt)->at(recorded_frame(r, 1), 0);
  ASSERT_TRUE(fp.scene);
  EXPECT_TRUE(fp.boom_given);
  expect_boom_eq(fp.scene->boom, *r.boom, "boom");
  EXPECT_FALSE(fp.scene->receiver_present);

  recorder::FrameRecord a;
  a.boom = BoomArticulation{0.6, 0.1, 2.0};
  a.T_body_receiver = pose(0, 0, 0, {-20, 0, 10});
  a.receiver_present = false;
  const FramePoses fa = recorded_poses(std::nullopt)->at(recorded_frame(a, 2), 0);
  ASSERT_TRUE(fa.scene);
  EXPECT_FALSE(fa.scene->receiver_present);
}

TEST(RecordedPoses, NeitherBoomNorPoseIsNoSceneNamingTheFrame) {
  recorder::FrameRecord r;
  r.sigma_pos_m = 1;
  const FramePoses fp = recorded_poses(Rig::paper_default())->at(recorded_frame(r, 17), 0);
  EXPECT_FALSE(fp.scene);
  ASSERT_FALSE(fp.problems.empty());
  EXPECT_NE(fp.problems[0].find("frame 17"), std::string::npos) << fp.problems[0];
  EXPECT_NE(fp.hud.status.find("no pose"), std::string::npos) << fp.hud.status;

  // A camera-relative pose without a rig to carry it into the body frame: nothing either.
  recorder::FrameRecord c;
  c.T_cam_receiver[0] = pose(0, 0, 0, {0, 0, 40});
  const FramePoses fc = recorded_poses(std::nullopt)->at(recorded_frame(c, 18), 0);
  EXPECT_FALSE(fc.scene);
  ASSERT_FALSE(fc.problems.empty());
  EXPECT_NE(fc.problems[0].find("frame 18"), std::string::npos) << fc.problems[0];
}

TEST(RecordedPoses, AFrameFromNoRecordingHasNoScene) {
  const FramePoses fp = recorded_poses(Rig::paper_default())->at(frame_at(1000), 0);
  EXPECT_FALSE(fp.scene);
  EXPECT_FALSE(fp.problems.empty());
  // Another kind of attachment is not a recording either.
  struct Other : FrameAttachment {};
  StereoFrame f = frame_at(1000);
  f.left.attachment = std::make_shared<Other>();
  EXPECT_FALSE(recorded_poses(Rig::paper_default())->at(f, 0).scene);
}

// poses.csv: written here as `augrig nav` writes it (docs/NAV_FORMATS.md).
const char* kHeader =
    "sequence,camera,t_ns,t_nav_ns,x_m,y_m,z_m,qw,qx,qy,qz,sigma_pos_m,sigma_att_deg,boom_elevation_deg,"
    "boom_azimuth_deg,boom_extension_m\n";

// A unit quaternion's text, w x y z, of a rotation given as yaw/pitch/roll (degrees).
std::string quat_text(double y, double p, double r, Eigen::Quaterniond* q) {
  *q = Eigen::Quaterniond(rotation_from_ypr(deg_to_rad(y), deg_to_rad(p), deg_to_rad(r))).normalized();
  char b[160];
  std::snprintf(b, sizeof b, "%.17g,%.17g,%.17g,%.17g", q->w(), q->x(), q->y(), q->z());
  return b;
}

struct PosesFile {
  std::string path;
  Eigen::Quaterniond q0, q1, q2;
};

PosesFile write_poses(const std::string& dir) {
  PosesFile f;
  f.path = dir + "/poses.csv";
  std::ofstream o(f.path);
  o << "# augrig camera poses (docs/NAV_FORMATS.md)\n# clock: device\n# t_nav_ns: gps\n" << kHeader;
  // t = 1000: camera 0 with the boom; camera 1 at the same time with another pose.
  o << "0,0,1000,900,-1.5,-2.5,50," << quat_text(80, -20, 10, &f.q0) << ",0.01,0.3,30,2,3.5\n";
  Eigen::Quaterniond unused;
  o << "0,1,1000,900,-2,-2.5,50," << quat_text(0, 0, 0, &unused) << ",0.02,0.4,10,1,1\n";
  // t = 2000: camera 0 without a boom (empty boom cells); a camera-1-only time at 2500.
  o << "1,0,2000,1900,-1,-2,40," << quat_text(85, -22, 5, &f.q1) << ",,,,,\n";
  o << "1,1,2500,1900,-1,-2,40," << quat_text(0, 0, 0, &unused) << ",,,,,\n";
  // t = 3000: a boom with one column empty: not a boom.
  o << "2,0,3000,2900,0,0,30," << quat_text(90, -25, 0, &f.q2) << ",0.1,1,25,,2\n";
  return f;
}

TEST(PosesCsv, TheLeftCamerasRowAtTheFramesTimeThroughTheRig) {
  const std::string dir = test::output_dir("poses_csv_exact");
  const PosesFile file = write_poses(dir);
  Rig rig = Rig::paper_default();
  rig.cameras[0].T_body_cam = pose(175, -28, 2, {0.1, 0.3, 2.0});
  auto p = poses_csv(file.path, rig, 0);
  ASSERT_TRUE(p) << p.error().message;
  EXPECT_NE((*p)->describe().find(file.path), std::string::npos);

  const FramePoses a = (*p)->at(frame_at(1000), 0);
  ASSERT_TRUE(a.scene) << (a.problems.empty() ? "" : a.problems[0]);
  Eigen::Matrix4d T_cam_rec = Eigen::Matrix4d::Identity();
  T_cam_rec.topLeftCorner<3, 3>() = file.q0.toRotationMatrix();
  T_cam_rec.topRightCorner<3, 1>() = Eigen::Vector3d(-1.5, -2.5, 50);
  expect_pose_near(a.scene->T_body_receiver, rig.left().T_body_cam.matrix() * T_cam_rec, 1e-9,
                   "camera 0's row, not camera 1's");
  EXPECT_TRUE(a.boom_given);
  EXPECT_NEAR(a.scene->boom.elevation_rad, 30 * M_PI / 180, 1e-12);
  EXPECT_NEAR(a.scene->boom.azimuth_rad, 2 * M_PI / 180, 1e-12);
  EXPECT_DOUBLE_EQ(a.scene->boom.extension_m, 3.5);
  EXPECT_DOUBLE_EQ(a.sigma_pos_m, 0.01);
  EXPECT_DOUBLE_EQ(a.sigma_att_deg, 0.3);
  EXPECT_TRUE(a.scene->receiver_present);

  // No boom columns: a pose, the boom not given.
  const FramePoses b = (*p)->at(frame_at(2000), 0);
  ASSERT_TRUE(b.scene);
  EXPECT_FALSE(b.boom_given);
  EXPECT_TRUE(std::isnan(b.sigma_pos_m));
  T_cam_rec.topLeftCorner<3, 3>() = file.q1.toRotationMatrix();
  T_cam_rec.topRightCorner<3, 1>() = Eigen::Vector3d(-1, -2, 40);
  expect_pose_near(b.scene->T_body_receiver, rig.left().T_body_cam.matrix() * T_cam_rec, 1e-9, "t 2000");

  // One boom column empty: the boom is not given.
  const FramePoses c = (*p)->at(frame_at(3000), 0);
  ASSERT_TRUE(c.scene);
  EXPECT_FALSE(c.boom_given);

  // Exactly: 1 ns off is no pose; camera 1's time is no pose; the problem names the file and time.
  for (TimestampNs t : {TimestampNs{1001}, TimestampNs{999}, TimestampNs{2500}, TimestampNs{0}}) {
    const FramePoses n = (*p)->at(frame_at(t), 0);
    EXPECT_FALSE(n.scene) << t;
    ASSERT_EQ(n.problems.size(), 1u) << t;
    EXPECT_NE(n.problems[0].find(file.path), std::string::npos) << n.problems[0];
    EXPECT_NE(n.problems[0].find(std::to_string(t)), std::string::npos) << n.problems[0];
  }
}

TEST(PosesCsv, WithinTheToleranceTheNearestLeftRow) {
  const std::string dir = test::output_dir("poses_csv_tolerance");
  const PosesFile file = write_poses(dir);
  const Rig rig = Rig::paper_default();
  auto p = poses_csv(file.path, rig, 400);
  ASSERT_TRUE(p) << p.error().message;
  auto z_of = [&](TimestampNs t) {
    const FramePoses fp = (*p)->at(frame_at(t), 0);
    if (!fp.scene) return -1.0;
    // The row's camera z, back from the body frame through the rig.
    return (rig.left().T_body_cam.inverse() * fp.scene->T_body_receiver).translation_m.z();
  };
  EXPECT_NEAR(z_of(1000), 50, 1e-9);
  EXPECT_NEAR(z_of(1399), 50, 1e-9);
  EXPECT_NEAR(z_of(600), 50, 1e-9);
  EXPECT_EQ(z_of(599), -1.0) << "beyond the tolerance";
  EXPECT_NEAR(z_of(1601), 40, 1e-9) << "only the row at 2000 within 400 ns";
  EXPECT_NEAR(z_of(2300), 40, 1e-9);
  // 2500 is camera 1's row: the left rows at 2000 and 3000 are 500 away, out of tolerance.
  EXPECT_EQ(z_of(2500), -1.0);
  EXPECT_NEAR(z_of(2700), 30, 1e-9);
  EXPECT_EQ(z_of(3401), -1.0);
  const FramePoses n = (*p)->at(frame_at(2500), 0);
  ASSERT_FALSE(n.problems.empty());
  EXPECT_NE(n.problems[0].find("400"), std::string::npos) << n.problems[0];

  // With a wide tolerance the nearest of several rows in reach.
  auto wide = poses_csv(file.path, rig, 5000);
  ASSERT_TRUE(wide);
  auto z_wide = [&](TimestampNs t) {
    const FramePoses fp = (*wide)->at(frame_at(t), 0);
    return fp.scene ? (rig.left().T_body_cam.inverse() * fp.scene->T_body_receiver).translation_m.z() : -1.0;
  };
  EXPECT_NEAR(z_wide(1400), 50, 1e-9);
  EXPECT_NEAR(z_wide(1600), 40, 1e-9);
  EXPECT_NEAR(z_wide(2600), 30, 1e-9);
  EXPECT_NEAR(z_wide(7000), 30, 1e-9);
}

TEST(PosesCsv, AFileWithoutLeftRowsOrNoFileFailsNamingIt) {
  const std::string dir = test::output_dir("poses_csv_bad");
  const std::string right_only = dir + "/right_only.csv";
  {
    std::ofstream o(right_only);
    o << kHeader << "0,1,1000,900,0,0,30,1,0,0,0,,,,,\n";
  }
  auto p = poses_csv(right_only, Rig::paper_default(), 0);
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find(right_only), std::string::npos) << p.error().message;
  EXPECT_NE(p.error().message.find("camera 0"), std::string::npos) << p.error().message;

  const std::string missing = dir + "/missing.csv";
  auto m = poses_csv(missing, Rig::paper_default(), 0);
  ASSERT_FALSE(m);
  EXPECT_NE(m.error().message.find(missing), std::string::npos) << m.error().message;
}

TEST(SimTruthPoses, TheTruthOfEachFrameTheSourceDelivers) {
  const std::string uri = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?rate=0";
  auto opened = open_sources(uri);
  ASSERT_TRUE(opened) << opened.error().message;
  ASSERT_TRUE(opened->sim);
  const SimulatedFlight& sim = *opened->sim;
  auto provider = sim_truth_poses(sim);
  EXPECT_FALSE(provider->live());

  // The oracle: the scenario's truth per (camera, camera timestamp).
  std::map<std::pair<int, TimestampNs>, sim::FrameTruth> truth;
  for (const sim::FrameTruth& t : sim::frame_truths(sim.scenario, *sim.flight, sim.logs.cameras))
    truth[{t.camera, t.t_camera_ns}] = t;
  ASSERT_GT(truth.size(), 20u);

  // The first frames the source delivers, each camera's in order.
  ASSERT_FALSE(opened->sources.empty());
  std::map<std::uint64_t, StereoFrame> by_sequence;
  int got = 0;
  for (int i = 0; i < 6; ++i) {
    Frame f;
    auto st = opened->sources[0]->read(f, std::chrono::seconds(30));
    ASSERT_TRUE(st) << st.error().message;
    ASSERT_EQ(*st, ReadStatus::kFrame);
    f.image = Image();  // the pixels are not needed
    by_sequence[f.sequence][f.camera] = f;
    ++got;
  }
  int checked = 0;
  std::vector<Eigen::Vector3d> positions;
  const Rig& rig = sim.scenario.rig;
  for (auto& [seq, sf] : by_sequence) {
    if (sf.left.t_ns == 0 || sf.right.t_ns == 0) continue;  // only one camera's frame read yet
    sf.left.camera = CameraId::kLeft;
    const FramePoses fp = provider->at(sf, 0);
    const auto it = truth.find({0, sf.left.t_ns});
    ASSERT_NE(it, truth.end()) << "the source's left frame " << seq << " has a truth";
    ASSERT_TRUE(fp.scene) << (fp.problems.empty() ? "" : fp.problems[0]);
    // The receiver is the truth; the boom is augrig's to fly (it tracks, as in the demo): the
    // scenario's boom is only where it starts, not a boom the source gives.
    EXPECT_FALSE(fp.boom_given);
    EXPECT_TRUE(fp.problems.empty());
    EXPECT_EQ(fp.sigma_pos_m, 0);
    expect_pose_eq(fp.scene->T_body_receiver, it->second.T_body_receiver, "frame " + std::to_string(seq));
    expect_boom_eq(fp.scene->boom, it->second.boom, "frame " + std::to_string(seq));
    EXPECT_TRUE(fp.scene->receiver_present);
    // The same truth seen from the left camera through the rig: the truth's own camera pose.
    expect_pose_near(rig.left().T_body_cam.inverse() * fp.scene->T_body_receiver,
                     it->second.T_cam_receiver.matrix(), 1e-6,
                     "T_cam_receiver, frame " + std::to_string(seq));
    positions.push_back(fp.scene->T_body_receiver.translation_m);
    ++checked;
  }
  EXPECT_GE(checked, 2) << got << " frames read";
  // Late in the approach (to contact) the receiver has moved: that frame has its own truth.
  const sim::FrameTruth* late = nullptr;
  for (const auto& [key, t] : truth)
    if (key.first == 0 && (!late || t.t_true_s > late->t_true_s)) late = &t;
  ASSERT_TRUE(late);
  const FramePoses fl = provider->at(frame_at(late->t_camera_ns), 0);
  ASSERT_TRUE(fl.scene);
  expect_pose_eq(fl.scene->T_body_receiver, late->T_body_receiver, "the last frame");
  ASSERT_FALSE(positions.empty());
  EXPECT_GT((fl.scene->T_body_receiver.translation_m - positions.front()).norm(), 0.1);
  // A time that is no frame's has no truth.
  const StereoFrame none = frame_at(by_sequence.begin()->second.left.t_ns + 1);
  const FramePoses fn = provider->at(none, 0);
  EXPECT_FALSE(fn.scene);
  ASSERT_FALSE(fn.problems.empty());
  EXPECT_NE(fn.hud.status.find("no pose"), std::string::npos);
  // The right camera's stamp used as a left frame's is not the left camera's truth.
  const auto first_right =
      std::find_if(truth.begin(), truth.end(), [](const auto& kv) { return kv.first.first == 1; });
  ASSERT_NE(first_right, truth.end());
  if (!truth.count({0, first_right->first.second})) {
    EXPECT_FALSE(provider->at(frame_at(first_right->first.second), 0).scene);
  }
}

// ---- choose_poses(): the one order every command takes its pose sources in ----

const Eigen::Vector3d kReceptacle(5.0, 0.0, -1.0);

// All of the sources that can stand together offered: recorded frames, the simulation, and
// (per test) one of scene, CSV or live nav.
struct Offered {
  std::shared_ptr<const SimulatedFlight> sim;
  PoseSources sources;
};
Offered recorded_and_sim() {
  auto opened = open_sources("sim://" + test::data_path("scenarios/short_approach.yaml") + "?rate=0");
  EXPECT_TRUE(opened) << opened.error().message;
  Offered o;
  o.sim = opened->sim;
  o.sources.recorded = true;
  o.sources.recorded_rig = Rig::paper_default();
  o.sources.sim = o.sim.get();
  return o;
}

TEST(ChoosePoses, SceneThenCsvThenRecordedThenSimulationThenNone) {
  const Rig rig = Rig::paper_default();
  const std::string scene = test::data_path("scenes/contact.yaml");
  const PosesFile csv = write_poses(test::output_dir("choose_poses_order"));

  Offered o = recorded_and_sim();
  o.sources.scene_path = scene;
  auto c = choose_poses(o.sources, rig, kReceptacle);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->provider->describe(), "the scene " + scene);
  EXPECT_FALSE(c->may_miss_frames) << "a scene answers every frame";
  ASSERT_EQ(c->scene_t_ns.size(), 1u);
  EXPECT_EQ(c->scene_t_ns[0], TimestampNs{1'000'000'000}) << "the scene file's own t_ns";
  // The scene's pose, whatever frame is asked.
  const auto want = load_scene(scene, rig, BoomDimensions{}, kReceptacle);
  ASSERT_TRUE(want);
  const FramePoses fp = c->provider->at(frame_at(123), 0);
  ASSERT_TRUE(fp.scene);
  expect_pose_eq(fp.scene->T_body_receiver, want->T_body_receiver, "the scene's receiver");

  o.sources.scene_path.clear();
  o.sources.poses_csv_path = csv.path;
  c = choose_poses(o.sources, rig, kReceptacle);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->provider->describe(), "the poses of " + csv.path);
  EXPECT_TRUE(c->may_miss_frames) << "a frame without its row";
  EXPECT_TRUE(c->scene_t_ns.empty());
  EXPECT_TRUE(c->provider->at(frame_at(1000), 0).scene) << "the CSV's row at t 1000";
  EXPECT_FALSE(c->provider->at(frame_at(1500), 0).scene) << "no row at t 1500 (tolerance 0)";

  o.sources.poses_csv_path.clear();
  c = choose_poses(o.sources, rig, kReceptacle);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->provider->describe(), "the poses recorded with each frame");
  EXPECT_TRUE(c->may_miss_frames) << "a frame recorded without a scene";

  o.sources.recorded = false;
  c = choose_poses(o.sources, rig, kReceptacle);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->provider->describe(), "the simulation's truth");
  EXPECT_FALSE(c->may_miss_frames);

  o.sources.sim = nullptr;
  c = choose_poses(o.sources, rig, kReceptacle);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_FALSE(c->provider) << "nothing offered: no provider (the command says what it needs)";
}

TEST(ChoosePoses, TheLiveNavBeforeRecordedAndSimulationWithTheCamerasOffsets) {
  const Rig rig = Rig::paper_default();
  const LiveNav nav(rig, BoomDimensions{}, kReceptacle, nav::InsConfig{}, nav::InsConfig{}, LiveNavOptions{});
  Offered o = recorded_and_sim();
  o.sources.live_nav = &nav;
  o.sources.camera_offset_ns = {0, 0};
  auto c = choose_poses(o.sources, rig, kReceptacle);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->provider->describe(), "the live nav (GPS/INS of both aircraft)");
  EXPECT_TRUE(c->provider->live());
  EXPECT_FALSE(c->may_miss_frames) << "a live frame without a pose is shown, marked stale";
  // No nav data yet: no pose, and the provider says why.
  const FramePoses fp = c->provider->at(frame_at(1000), 0);
  EXPECT_FALSE(fp.scene);
  EXPECT_FALSE(fp.problems.empty());
}

TEST(ChoosePoses, SceneCsvAndLiveNavAreAlternatives) {
  const Rig rig = Rig::paper_default();
  const LiveNav nav(rig, BoomDimensions{}, kReceptacle, nav::InsConfig{}, nav::InsConfig{}, LiveNavOptions{});
  const std::string scene = test::data_path("scenes/contact.yaml");
  const PosesFile csv = write_poses(test::output_dir("choose_poses_alternatives"));
  for (int mask : {3, 5, 6, 7}) {
    PoseSources s;
    if (mask & 1) s.scene_path = scene;
    if (mask & 2) s.poses_csv_path = csv.path;
    if (mask & 4) s.live_nav = &nav;
    auto c = choose_poses(s, rig, kReceptacle);
    ASSERT_FALSE(c) << "sources " << mask;
    EXPECT_NE(c.error().message.find("give one"), std::string::npos) << c.error().message;
  }
}

TEST(ChoosePoses, AFolderOfSceneFilesOnlyWhereTheCommandTakesOne) {
  const Rig rig = Rig::paper_default();
  const std::string dir = test::output_dir("choose_poses_folder");
  fs::copy_file(test::data_path("scenes/contact.yaml"), dir + "/0001.yaml");
  fs::copy_file(test::data_path("scenes/body.yaml"), dir + "/0002.yaml");
  PoseSources s;
  s.scene_path = dir;
  s.scene_folder_ok = true;
  auto c = choose_poses(s, rig, kReceptacle);
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_TRUE(c->may_miss_frames) << "a pair beyond the folder's files";
  ASSERT_EQ(c->scene_t_ns.size(), 2u) << "one per file, in name order";
  EXPECT_EQ(c->scene_t_ns[0], TimestampNs{1'000'000'000});
  EXPECT_FALSE(c->scene_t_ns[1]) << "body.yaml gives no t_ns";

  // Where a command takes one scene for every frame, a folder is a scene file that does not read.
  s.scene_folder_ok = false;
  c = choose_poses(s, rig, kReceptacle);
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find(dir), std::string::npos) << c.error().message;
}

TEST(ChoosePoses, ABadSceneOrCsvFailsNamingTheFile) {
  const Rig rig = Rig::paper_default();
  PoseSources s;
  s.scene_path = test::data_path("scenes/bad_syntax.yaml");
  auto c = choose_poses(s, rig, kReceptacle);
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("bad_syntax.yaml"), std::string::npos) << c.error().message;

  s.scene_path.clear();
  s.poses_csv_path = test::output_dir("choose_poses_bad_csv") + "/missing.csv";
  c = choose_poses(s, rig, kReceptacle);
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("missing.csv"), std::string::npos) << c.error().message;
}

}  // namespace
}  // namespace augrig::pipeline
