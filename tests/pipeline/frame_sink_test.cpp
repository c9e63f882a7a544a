// FrameSink's contract, through a real pipeline over the simulated flight: every sink consumes a
// pair before any releases it; sinks reading the changed boxes see the augmenter's boxes even when
// a sink configured before them asks for whole images; the raw frame is intact until release; a
// sink's error stops the run with that error and every sink is still closed; events and the
// health reach the sinks that asked.
#include "pipeline/frame_sink.hpp"

#include <gtest/gtest.h>

#include "pipeline/pipeline.hpp"
#include "recorder/reader.hpp"
#include "tests/support/test_support.hpp"
#include "tests/support/pipeline_parts.hpp"

namespace augrig::pipeline {
namespace {

const std::string kScenario = "sim://" + test::data_path("scenarios/short_approach.yaml") + "?every=3&rate=0";

PipelineParts sim_parts() { return test::pipeline_parts(kScenario); }

// What one probe saw, shared with the test after the pipeline took the sink.
struct Seen {
  std::vector<std::string> calls;  // "consume NAME PAIR" / "release NAME PAIR" / "close NAME"
  std::vector<bool> whole;         // per consume: the left view whole when it was consumed
  std::vector<bool> raw_intact;    // per consume: the raw left image present
  int events = 0, health = 0;
};

class Probe final : public FrameSink {
 public:
  Probe(std::string name, Seen& seen, SinkNeeds needs, int fail_at = 0)
      : name_(std::move(name)), seen_(seen), needs_(needs), fail_at_(fail_at) {}
  SinkNeeds needs() const override { return needs_; }
  Status consume(PairContext& pair) override {
    seen_.calls.push_back("consume " + name_ + " " + std::to_string(pair.pair));
    if (needs_.whole_images) pair.make_whole();
    const Image& a = pair.result->left.augmented;
    seen_.whole.push_back(a.width() == pair.raw.left.image.width() &&
                          a.height() == pair.raw.left.image.height());
    seen_.raw_intact.push_back(!pair.raw.left.image.empty());
    if (fail_at_ && static_cast<int>(pair.pair) == fail_at_)
      return make_error("probe ", name_, ": disk full");
    return {};
  }
  void release(PairContext& pair) override {
    seen_.calls.push_back("release " + name_ + " " + std::to_string(pair.pair));
  }
  void event(const SinkEvent&) override { ++seen_.events; }
  void health(const RunHealth&) override { ++seen_.health; }
  Status close(PipelineReport&) override {
    seen_.calls.push_back("close " + name_);
    return {};
  }

 private:
  std::string name_;
  Seen& seen_;
  SinkNeeds needs_;
  int fail_at_;
};

TEST(FrameSink, BoxReadersFirstThenWholeThenReleaseInOrder) {
  const std::string out = test::output_dir("frame_sink_order");
  Seen seen;
  PipelineParts p = sim_parts();
  p.max_pairs = 3;
  // Configured whole-first: the pipeline still gives the box reader the boxes first.
  p.sinks.push_back(std::make_unique<Probe>("W", seen, SinkNeeds{.whole_images = true}));
  p.sinks.push_back(std::make_unique<Probe>("B", seen, SinkNeeds{}));
  recorder::RecordingInfo info;
  auto rec = recorder::Recorder::create(out + "/rec", info);
  ASSERT_TRUE(rec) << rec.error().message;
  p.recorder = std::move(*rec);
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  ASSERT_TRUE(report) << report.error().message;
  ASSERT_EQ(report->pairs, 3u);
  std::vector<std::string> want;
  for (int i = 1; i <= 3; ++i)
    for (const char* c : {"consume B ", "consume W ", "release B ", "release W "})
      want.push_back(c + std::to_string(i));
  want.push_back("close B");
  want.push_back("close W");
  EXPECT_EQ(seen.calls, want);
  // B (boxes) saw boxes smaller than the frame; W made them whole; the raw frame was there for both.
  for (std::size_t i = 0; i < seen.whole.size(); ++i) {
    EXPECT_EQ(seen.whole[i], i % 2 == 1) << "consume " << i;
    EXPECT_TRUE(seen.raw_intact[i]) << "consume " << i;
  }
  // The recorder (taking the raw frame at release) still stored it with its augmentation.
  auto reader = recorder::RecordingReader::open(out + "/rec");
  ASSERT_TRUE(reader) << reader.error().message;
  auto frame = (*reader)->read_frame(0);
  ASSERT_TRUE(frame) << frame.error().message;
  EXPECT_FALSE(frame->raw.left.image.empty());
  EXPECT_FALSE(frame->augmented[0].empty());
}

TEST(FrameSink, AnErrorStopsTheRunAndEverySinkIsClosed) {
  Seen seen;
  PipelineParts p = sim_parts();
  p.sinks.push_back(std::make_unique<Probe>("A", seen, SinkNeeds{}, /*fail_at=*/2));
  p.sinks.push_back(std::make_unique<Probe>("Z", seen, SinkNeeds{.health = true}));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  ASSERT_FALSE(report);
  EXPECT_EQ(report.error().message, "probe A: disk full");
  // Pair 2 reached A, failed there: Z never consumed it and nobody released it.
  const std::vector<std::string> want = {"consume A 1", "consume Z 1", "release A 1", "release Z 1",
                                         "consume A 2", "close A",     "close Z"};
  EXPECT_EQ(seen.calls, want);
}

TEST(FrameSink, EventsReachEverySink) {
  Seen seen;
  PipelineParts p = sim_parts();
  p.max_pairs = 40;  // the short approach's phases change within these
  p.sinks.push_back(std::make_unique<Probe>("A", seen, SinkNeeds{}));
  Pipeline pipeline(std::move(p));
  std::ostringstream o, e;
  auto report = pipeline.run(o, e);
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_NE(o.str().find("phase: "), std::string::npos) << o.str();
  EXPECT_GT(seen.events, 0);
}

TEST(PairContext, MakeWholeOnceAndOnlyWithAResult) {
  StereoFrame raw;
  for (CameraId id : {CameraId::kLeft, CameraId::kRight}) raw[id].image = Image(8, 6, PixelFormat::kMono8);
  raw.left.image.data()[0] = 7;
  StereoResult r;
  for (ViewResult* v : {&r.left, &r.right}) {
    v->augmented_box = {2, 1, 4, 3};
    v->augmented = Image(2, 2, PixelFormat::kMono8);
    v->augmented.data()[0] = 200;
  }
  FramePoses poses;
  PairContext pair{.raw = raw, .result = &r, .scene = nullptr, .poses = poses};
  pair.make_whole();
  EXPECT_TRUE(pair.made_whole);
  ASSERT_EQ(r.left.augmented.width(), 8);
  EXPECT_EQ(r.left.augmented.row(1)[2], 200);  // the box in its place
  EXPECT_EQ(r.left.augmented.row(0)[0], 7);    // the raw around it
  pair.make_whole();                           // a second call changes nothing
  EXPECT_EQ(r.left.augmented.row(1)[2], 200);
  PairContext none{.raw = raw, .result = nullptr, .scene = nullptr, .poses = poses};
  none.make_whole();
  EXPECT_FALSE(none.made_whole);
}

}  // namespace
}  // namespace augrig::pipeline
