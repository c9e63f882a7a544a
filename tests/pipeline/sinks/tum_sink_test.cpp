// The TUM trajectory sink: one line per pair with a receiver, the pose in the left camera that the
// rig and the scene give (checked by transforming a point both ways), GPS-sized times exact to
// the nanosecond, pairs without a receiver left out, an unwritable file named.
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

TEST(TumSink, WritesThePoseInTheLeftCameraPerPair) {
  const std::string file = test::output_dir("tum_sink") + "/traj.txt";
  const Rig rig = Rig::paper_default();
  auto sink = make_sink("tum:" + file, {rig});
  ASSERT_TRUE(sink) << sink.error().message;
  const Pose T_body_receiver = pose_from_ypr({-20.0, 1.5, 8.0}, 0.1, -0.05, 0.02);
  for (int i = 0; i < 3; ++i) {
    StereoFrame raw;
    raw.t_key_ns = 5;
    FramePoses poses;
    poses.t_nav_ns = 1'400'000'000'123'456'789 + i;  // GPS time in ns: 19 digits
    SceneState scene{};
    scene.T_body_receiver = T_body_receiver;
    scene.receiver_present = i != 1;  // the second pair has no receiver: no line
    PairContext pair{.raw = raw,
                     .result = nullptr,
                     .scene = &scene,
                     .poses = poses,
                     .pair = static_cast<std::uint64_t>(i + 1)};
    ASSERT_TRUE((*sink)->consume(pair));
  }
  PipelineReport report;
  ASSERT_TRUE((*sink)->close(report));
  sink->reset();

  std::ifstream in(file);
  std::vector<std::string> rows;
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') rows.push_back(line);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].substr(0, 21), "1400000000.123456789 ");
  EXPECT_EQ(rows[1].substr(0, 21), "1400000000.123456791 ");
  std::istringstream row(rows[0].substr(21));
  double t[3], q[4];
  row >> t[0] >> t[1] >> t[2] >> q[0] >> q[1] >> q[2] >> q[3];
  ASSERT_TRUE(row);
  const Pose T_cam_receiver{Eigen::Quaterniond(q[3], q[0], q[1], q[2]), Eigen::Vector3d(t[0], t[1], t[2])};
  // A receiver point seen through the file's pose and through the rig's camera agree.
  const Eigen::Vector3d p_receiver(3.0, -1.0, 0.5);
  const Eigen::Vector3d want = rig.cameras[0].T_body_cam.inverse() * (T_body_receiver * p_receiver);
  EXPECT_LT((T_cam_receiver * p_receiver - want).norm(), 1e-6);
}

TEST(TumSink, AnUnwritableFileIsNamed) {
  const Rig rig = Rig::paper_default();
  auto sink = make_sink("tum:/nonexistent-dir/traj.txt", {rig});
  ASSERT_FALSE(sink);
  EXPECT_EQ(sink.error().message, "tum sink: /nonexistent-dir/traj.txt: cannot write the file");
}

}  // namespace
}  // namespace augrig::pipeline
