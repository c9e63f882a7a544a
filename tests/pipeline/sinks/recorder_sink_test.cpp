// The recorder sink: a pair's boxes taken at consume, its raw frame at release (moved, not
// copied), nothing while paused, events in, and at the close every ledger row the report gives.
#include <gtest/gtest.h>

#include "pipeline/report.hpp"
#include "pipeline/sinks/sinks.hpp"
#include "recorder/reader.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

StereoFrame raw_pair(std::uint64_t seq) {
  StereoFrame raw;
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
    raw[id].image = Image(16, 12, PixelFormat::kMono8);
    raw[id].camera = id;
    raw[id].t_ns = 1'000 + static_cast<TimestampNs>(seq) * 50'000'000;
    raw[id].clock = ClockDomain::kGps;
    raw[id].sequence = seq;
  }
  raw.t_key_ns = raw.left.t_ns;
  raw.pair_sequence = seq;
  return raw;
}

TEST(RecorderSink, RecordsPairsEventsAndTheLedger) {
  const std::string dir = test::output_dir("recorder_sink") + "/rec";
  recorder::RecordingInfo info;
  auto rec = recorder::Recorder::create(dir, info);
  ASSERT_TRUE(rec) << rec.error().message;
  const Rig rig = Rig::paper_default();
  RecorderSink sink(**rec, rig, false, nullptr);
  FramePoses poses;
  SceneState scene{};
  for (std::uint64_t i = 0; i < 4; ++i) {
    sink.set_on(i != 2);  // the window paused the recording for the third pair
    StereoFrame raw = raw_pair(i);
    StereoResult r;
    r.left.augmented = Image(4, 4, PixelFormat::kMono8);
    r.left.augmented_box = {2, 2, 6, 6};
    r.right.augmented = Image(4, 4, PixelFormat::kMono8);
    r.right.augmented_box = {2, 2, 6, 6};
    r.left.mask = Image(16, 12, PixelFormat::kMono8);
    r.right.mask = Image(16, 12, PixelFormat::kMono8);
    PairContext pair{.raw = raw, .result = &r, .scene = &scene, .poses = poses, .pair = i + 1};
    ASSERT_TRUE(sink.consume(pair));
    sink.release(pair);
    EXPECT_EQ(raw.left.image.size_bytes() == 0, i != 2) << "the raw frame is moved in only when recording";
  }
  EXPECT_EQ(sink.state(), "on");
  sink.event({5, ClockDomain::kHostMonotonic, "left camera lost", true, 0});
  PipelineReport report;
  report.failed_pairs = 1;
  report.failed_t.add(77);
  report.source.camera_drops = 3;
  ASSERT_TRUE(sink.close(report));
  ASSERT_TRUE(report.recording_closed);
  EXPECT_TRUE(*report.recording_closed);
  EXPECT_EQ(report.recorder_stats.frames_committed, 3u);

  auto reader = recorder::RecordingReader::open(dir);
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_EQ((*reader)->frame_count(), 3u);
  auto events = (*reader)->events();
  ASSERT_TRUE(events);
  ASSERT_EQ(events->size(), 1u);
  EXPECT_EQ(events->front().text, "left camera lost");
  auto drops = (*reader)->drops();
  ASSERT_TRUE(drops);
  std::uint64_t camera = 0, failed = 0;
  for (const recorder::DropRecord& d : *drops) {
    if (d.stage == recorder::DropStage::kCamera) camera += d.count;
    if (d.stage == recorder::DropStage::kProcessing) failed += d.count;
  }
  EXPECT_EQ(camera, 3u);
  EXPECT_EQ(failed, 2u) << "a failed pair is both its frames";
}

}  // namespace
}  // namespace augrig::pipeline
