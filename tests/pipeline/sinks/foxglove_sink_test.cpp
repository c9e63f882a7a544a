// The network view as a sink: pairs, events and the health go to a real server without
// blocking, and at the close the report carries its counts.
#include <gtest/gtest.h>

#include "pipeline/report.hpp"
#include "pipeline/sinks/sinks.hpp"

namespace augrig::pipeline {
namespace {

TEST(FoxgloveSink, PublishesWithoutClientsAndReportsAtTheClose) {
  net::ServeOptions o;
  o.name = "augrig-sink-test";
  const Rig rig = Rig::paper_default();
  auto server = net::FoxgloveServer::start(o, rig);
  ASSERT_TRUE(server) << server.error().message;
  std::shared_ptr<net::FoxgloveServer> shared = std::move(*server);
  auto sink = make_foxglove_sink(shared);
  EXPECT_TRUE(sink->needs().health);
  StereoFrame raw;
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) raw[id].image = Image(16, 12, PixelFormat::kMono8);
  FramePoses poses;
  PairContext pair{.raw = raw, .result = nullptr, .scene = nullptr, .poses = poses, .pair = 1};
  ASSERT_TRUE(sink->consume(pair));
  sink->release(pair);
  sink->event({1, ClockDomain::kHostMonotonic, "pose stale", true, 0});
  RunHealth h;
  h.pairs = 1;
  h.recording = "stopped";
  h.cameras = {SourceHealth{}, SourceHealth{false, "right camera lost", 1, 0, 0, 0}};
  // The online camera clocks' line and values go out with the rest (run --camera-clock online).
  h.camera_clocks = {"left: +3.712 +- 0.321 ms, drift not observable, applied"};
  h.camera_clock_values = {{"camera0_clock_offset_ms", "3.7120"}, {"camera0_clock_applied", "1"}};
  sink->health(h);
  PipelineReport report;
  report.pairs = 1;
  ASSERT_TRUE(sink->close(report));
  ASSERT_TRUE(report.serve);
  EXPECT_EQ(report.serve->clients_ever, 0u);
  EXPECT_EQ(report.serve->messages_dropped, 0u);
}

}  // namespace
}  // namespace augrig::pipeline
