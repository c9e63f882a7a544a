// FlightSource: delivered frames in timestamp order with their truth, dropped ones skipped, and
// rendered images that show the receiver where the truth puts it.
#include "sim/flight_source.hpp"

#include <gtest/gtest.h>

#include "render/gl_context.hpp"

namespace augrig::sim {
namespace {

TEST(FlightSource, TruthsAreInDeliveryOrderAndSkipDrops) {
  Scenario s = *builtin_scenario("demo");
  s.sensors.cameras.drop_probability = 0.05;
  const Flight f = *Flight::create(s);
  const SensorLogs logs = simulate_sensors(s, f);
  std::size_t delivered = 0;
  for (const auto& cam : logs.cameras)
    for (const auto& t : cam) delivered += t.dropped ? 0 : 1;
  const std::vector<FrameTruth> truths = frame_truths(s, f, logs.cameras);
  ASSERT_EQ(truths.size(), delivered);
  ASSERT_LT(delivered, 2 * logs.cameras[0].size());  // some were dropped
  for (std::size_t i = 1; i < truths.size(); ++i) EXPECT_LE(truths[i - 1].t_camera_ns, truths[i].t_camera_ns);
  for (const FrameTruth& t : truths) {
    // The camera-relative truth is the body-relative one through the rig's extrinsics.
    const Pose expect = s.rig.cameras[t.camera].T_body_cam.inverse() * t.T_body_receiver;
    EXPECT_LT((expect.translation_m - t.T_cam_receiver.translation_m).norm(), 1e-9);
    const nav::CameraPoseRow r = pose_row(t);
    EXPECT_EQ(r.sequence, t.sequence);
    EXPECT_EQ(r.t_ns, t.t_camera_ns);
    EXPECT_DOUBLE_EQ(r.z_m, t.T_cam_receiver.translation_m.z());
  }
}

TEST(FlightSource, RendersTheDeliveredFramesWithTheirStamps) {
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  ASSERT_TRUE(ctx) << ctx.error().message;
  const Scenario s = *builtin_scenario("demo");
  const Flight f = *Flight::create(s);
  const SensorLogs logs = simulate_sensors(s, f);
  std::vector<FrameTruth> truths = frame_truths(s, f, logs.cameras);
  truths.erase(truths.begin() + 4, truths.end());
  auto source = FlightSource::create(s, f, truths);
  ASSERT_TRUE(source) << source.error().message;
  Frame frame;
  for (std::size_t i = 0; i < 4; ++i) {
    ASSERT_EQ(*(*source)->read(frame, {}), ReadStatus::kFrame);
    EXPECT_EQ(frame.t_ns, truths[i].t_camera_ns);
    EXPECT_EQ(frame.clock, ClockDomain::kDevice);
    EXPECT_EQ(index_of(frame.camera), truths[i].camera);
    EXPECT_EQ(frame.image.width(), 1280);
    EXPECT_EQ((*source)->last_truth().t_camera_ns, truths[i].t_camera_ns);
    // The receiver is 30 m behind and 12 m below: the image is not one flat colour.
    std::uint8_t lo = 255, hi = 0;
    for (int y = 0; y < frame.image.height(); y += 8)
      for (int x = 0; x < 3 * frame.image.width(); x += 24) {
        lo = std::min(lo, frame.image.row(y)[x]);
        hi = std::max(hi, frame.image.row(y)[x]);
      }
    EXPECT_GT(hi - lo, 50);
  }
  EXPECT_EQ(*(*source)->read(frame, {}), ReadStatus::kEndOfStream);
}

}  // namespace
}  // namespace augrig::sim
