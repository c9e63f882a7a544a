// The scripted approach: frame order and timing of the source, the truth's geometry (contact at
// the nozzle tip, a C1 path, the receiver in both cameras' view), and sample frames to look at.
#include "sim/approach.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "render/gl_context.hpp"
#include "render/models.hpp"
#include "tests/support/gl_test.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

using namespace std::chrono_literals;

Eigen::Vector3d builtin_receptacle() {
  Eigen::Vector3d r;
  make_builtin_receiver(&r);
  return r;
}

Eigen::Vector3d nozzle_tip(const Rig& rig, const BoomDimensions& dims, const BoomArticulation& a) {
  return boom_pose(rig.boom.pivot_body_m, a) * Eigen::Vector3d(dims.nozzle_tip_m(a.extension_m), 0, 0);
}

class ApproachTest : public test::GlTest {};

TEST_F(ApproachTest, FrameOrderTimestampsAndEndOfStream) {
  ApproachOptions o;
  o.frames = 3;
  o.fps = 29.97;
  o.skew_ns = 1234.6;
  o.sensor.format = PixelFormat::kBayerRG8;
  auto src = ApproachSource::create(Rig::paper_default(), o);
  ASSERT_TRUE(src) << src.error().message;
  EXPECT_EQ((*src)->uri(), "sim://approach");
  EXPECT_EQ((*src)->frame_count(), 3u);
  Frame f;
  for (std::uint64_t seq = 0; seq < 3; ++seq) {
    for (CameraId cam : {CameraId::kLeft, CameraId::kRight}) {
      auto st = (*src)->read(f, 0ns);
      ASSERT_TRUE(st) << st.error().message;
      ASSERT_EQ(*st, ReadStatus::kFrame);
      EXPECT_EQ(f.camera, cam);
      EXPECT_EQ(f.sequence, seq);
      EXPECT_EQ(f.clock, ClockDomain::kSim);
      const auto t_left = static_cast<TimestampNs>(std::llround(seq / 29.97 * 1e9));
      EXPECT_EQ(f.t_ns, t_left + (cam == CameraId::kRight ? 1235 : 0));
      EXPECT_EQ((*src)->truth(seq).t_ns, t_left);
      EXPECT_EQ(f.image.width(), 1280);
      EXPECT_EQ(f.image.height(), 960);
      EXPECT_EQ(f.image.format(), PixelFormat::kBayerRG8);
    }
  }
  for (int i = 0; i < 2; ++i) {
    auto st = (*src)->read(f, 0ns);
    ASSERT_TRUE(st);
    EXPECT_EQ(*st, ReadStatus::kEndOfStream);
  }
  EXPECT_THROW((*src)->truth(3), std::out_of_range);
}

TEST_F(ApproachTest, BadOptionsAreErrors) {
  ApproachOptions o;
  o.frames = 0;
  auto a = ApproachSource::create(Rig::paper_default(), o);
  ASSERT_FALSE(a);
  EXPECT_NE(a.error().message.find("ApproachSource::create()"), std::string::npos);
  Rig mono = Rig::paper_default();
  mono.cameras.pop_back();
  EXPECT_FALSE(ApproachSource::create(mono, ApproachOptions{}));
}

// Pure geometry, no rendering.
TEST(ApproachTruthTest, ContactAtTheNozzleTipAtTheEnd) {
  const Rig rig = Rig::paper_default();
  const BoomDimensions dims;
  const Eigen::Vector3d rec = builtin_receptacle();
  const double duration = 89 / 30.0;
  const ApproachTruth end = approach_truth(rig, dims, rec, duration, duration);
  const Eigen::Vector3d tip = nozzle_tip(rig, dims, end.scene.boom);
  EXPECT_LT((end.scene.T_body_receiver * rec - tip).norm(), 1e-3);
  EXPECT_NEAR(end.scene.boom.extension_m, 3.5, 1e-9);
  EXPECT_NEAR(end.scene.boom.elevation_rad, 0.5236, 1e-12);
  EXPECT_EQ(end.scene.boom.azimuth_rad, 0.0);
  const ApproachTruth start = approach_truth(rig, dims, rec, 0.0, duration);
  EXPECT_NEAR(start.scene.boom.extension_m, 1.0, 1e-12);
  const Eigen::Vector3d off = start.scene.T_body_receiver * rec - nozzle_tip(rig, dims, start.scene.boom);
  EXPECT_LT((off - Eigen::Vector3d(-30, 2, 12)).norm(), 1e-9);
  // Straight and level tanker: yaw only, heading 090, moving east.
  const YawPitchRoll e = ypr_from_rotation(end.sky.R_ned_body);
  EXPECT_NEAR(e.yaw_rad, deg_to_rad(90.0), 1e-12);
  EXPECT_NEAR(e.pitch_rad, 0.0, 1e-12);
  EXPECT_NEAR(e.roll_rad, 0.0, 1e-12);
  EXPECT_NEAR(end.sky.north_east_m.y() - start.sky.north_east_m.y(), 150.0 * duration, 1e-6);
}

// Smooth (C1) and wobbling at most 1 deg: velocities change little between 1 ms samples.
TEST(ApproachTruthTest, PathIsSmooth) {
  const Rig rig = Rig::paper_default();
  const Eigen::Vector3d rec = builtin_receptacle();
  const double duration = 3.0, dt = 1e-3;
  auto pos = [&](double t) {
    return approach_truth(rig, BoomDimensions{}, rec, t, duration).scene.T_body_receiver * rec;
  };
  Eigen::Vector3d v_prev = (pos(dt) - pos(0)) / dt;
  double max_dv = 0, max_angle = 0;
  for (double t = dt; t + dt <= duration + 1e-12; t += dt) {
    const Eigen::Vector3d v = (pos(t + dt) - pos(t)) / dt;
    max_dv = std::max(max_dv, (v - v_prev).norm());
    v_prev = v;
    const YawPitchRoll e =
        ypr_from_rotation(approach_truth(rig, BoomDimensions{}, rec, t, duration).scene.T_body_receiver.R());
    max_angle = std::max({max_angle, std::abs(e.pitch_rad), std::abs(e.roll_rad), std::abs(e.yaw_rad)});
  }
  EXPECT_LT(max_dv, 0.2);          // m/s per ms: no velocity jumps
  EXPECT_LT(v_prev.norm(), 0.05);  // arrives at rest relative to the tanker
  EXPECT_LE(max_angle, deg_to_rad(1.0) + 1e-9);
  EXPECT_GT(max_angle, deg_to_rad(0.5));
}

// Every vertex of the receiver projects into both cameras in every frame of the default clip.
TEST(ApproachTruthTest, ReceiverInViewOfBothCamerasThroughout) {
  const Rig rig = Rig::paper_default();
  Eigen::Vector3d rec;
  const Model receiver = make_builtin_receiver(&rec);
  const ApproachOptions o;
  const double duration = (o.frames - 1) / o.fps;
  for (int i = 0; i < o.frames; ++i) {
    const ApproachTruth tr = approach_truth(rig, o.boom, rec, i / o.fps, duration);
    for (const RigCamera& cam : rig.cameras) {
      const Pose T_cam_recv = cam.T_body_cam.inverse() * tr.scene.T_body_receiver;
      double u0 = 1e9, u1 = -1e9, v0 = 1e9, v1 = -1e9;
      for (const Mesh& m : receiver.meshes)
        for (const auto& p : m.positions_m) {
          const auto uv = cam.model.project(T_cam_recv * p.cast<double>());
          ASSERT_TRUE(uv) << "frame " << i;
          u0 = std::min(u0, uv->x()), u1 = std::max(u1, uv->x());
          v0 = std::min(v0, uv->y()), v1 = std::max(v1, uv->y());
        }
      EXPECT_GE(u0, 0) << cam.name << " frame " << i;
      EXPECT_LE(u1, cam.model.width_px - 1) << cam.name << " frame " << i;
      EXPECT_GE(v0, 0) << cam.name << " frame " << i;
      EXPECT_LE(v1, cam.model.height_px - 1) << cam.name << " frame " << i;
    }
  }
}

void write_png(const std::string& path, const Image& img) {
  cv::Mat rgb(img.height(), img.width(), CV_8UC3, const_cast<std::uint8_t*>(img.data()), img.stride_bytes());
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  cv::imwrite(path, bgr);
}

// First, middle and last frames: the receiver is drawn (pixels change against an empty sky),
// and PNGs to look at.
TEST_F(ApproachTest, SampleFramesShowTheReceiver) {
  const Rig rig = Rig::paper_default();
  ApproachOptions o;
  o.sensor.noise_sigma = 1.5;
  auto src = ApproachSource::create(rig, o);
  ASSERT_TRUE(src) << src.error().message;
  auto renderer = SyntheticSceneRenderer::create(rig);
  ASSERT_TRUE(renderer) << renderer.error().message;
  const std::string dir = test::output_dir("sim");
  for (std::uint64_t seq : {0ull, 45ull, 89ull}) {
    const ApproachTruth& tr = (*src)->truth(seq);
    for (int c = 0; c < 2; ++c) {
      Image with, without;
      ASSERT_TRUE((*renderer)->render(c, tr.sky, tr.scene.T_body_receiver, true, SensorOptions{}, with));
      ASSERT_TRUE((*renderer)->render(c, tr.sky, tr.scene.T_body_receiver, false, SensorOptions{}, without));
      long changed = 0;
      for (int y = 0; y < with.height(); ++y)
        changed += std::memcmp(with.row(y), without.row(y), with.width() * 3) != 0;
      EXPECT_GT(changed, 100) << "rows showing the receiver, frame " << seq << " camera " << c;
      write_png(dir + "/approach_" + std::to_string(seq) + (c ? "_right" : "_left") + ".png", with);
    }
  }
  // The whole clip through the source, as the demo reads it (noisy frames), timed.
  Frame f;
  const auto t0 = std::chrono::steady_clock::now();
  for (std::uint64_t i = 0; i < 2 * 90; ++i) {
    auto st = (*src)->read(f, 0ns);
    ASSERT_TRUE(st && *st == ReadStatus::kFrame);
    if (i == 0 || i == 178) write_png(dir + "/source_" + std::to_string(f.sequence) + "_left.png", f.image);
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("ApproachSource: 90 stereo frames in %.1f s, %.1f ms per view\n", ms / 1000, ms / 180);
  EXPECT_EQ(f.sequence, 89u);
  EXPECT_EQ(*(*src)->read(f, 0ns), ReadStatus::kEndOfStream);
}

}  // namespace
}  // namespace augrig
