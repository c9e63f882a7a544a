#include "capture/stereo_source.hpp"

#include <thread>

#include <gtest/gtest.h>

namespace augrig {
namespace {

using namespace std::chrono_literals;

// A finite source of numbered frames: camera `camera` (or alternating left/right when `both`),
// 30 fps, `skew_ns` late (when `both`: its right camera's frames). Fails at frame `fail_at` when set.
class ScriptedSource final : public FrameSource {
 public:
  ScriptedSource(int frames, CameraId camera, bool both = false, std::int64_t skew_ns = 100'000,
                 int fail_at = -1)
      : frames_(frames), camera_(camera), both_(both), skew_ns_(skew_ns), fail_at_(fail_at) {}
  std::string uri() const override { return "scripted://" + std::string(to_string(camera_)); }
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds) override {
    const int total = both_ ? 2 * frames_ : frames_;
    if (next_ == fail_at_) return make_error("scripted failure at frame ", next_);
    if (next_ >= total) return ReadStatus::kEndOfStream;
    const int i = both_ ? next_ / 2 : next_;
    const CameraId cam = both_ ? (next_ % 2 ? CameraId::kRight : CameraId::kLeft) : camera_;
    out = Frame{};
    out.image = Image(4, 2, PixelFormat::kMono8);
    out.image.data()[0] = static_cast<std::uint8_t>(i);
    out.camera = cam;
    out.sequence = static_cast<std::uint64_t>(i);
    out.clock = ClockDomain::kDevice;
    out.t_ns = 1'000'000'000 + i * 33'333'333LL + (!both_ || cam == CameraId::kRight ? skew_ns_ : 0);
    out.t_host_ns = out.t_ns;
    ++next_;
    return ReadStatus::kFrame;
  }

 private:
  int frames_;
  CameraId camera_;
  bool both_;
  std::int64_t skew_ns_;
  int fail_at_;
  int next_ = 0;
};

std::vector<std::unique_ptr<FrameSource>> two(int frames, int fail_at = -1) {
  std::vector<std::unique_ptr<FrameSource>> v;
  v.push_back(std::make_unique<ScriptedSource>(frames, CameraId::kLeft, false, 0));
  // The second source's frames say "left": its position makes them the right camera's.
  v.push_back(std::make_unique<ScriptedSource>(frames, CameraId::kLeft, false, 100'000, fail_at));
  return v;
}

StereoSourceOptions options(bool lossless, std::size_t queue) {
  StereoSourceOptions o;
  o.pairing.tolerance_ns = 2'000'000;
  o.pairing.max_pending = 64;
  o.lossless = lossless;
  o.queue_frames = queue;
  return o;
}

std::vector<StereoFrame> drain(StereoSource& s) {
  std::vector<StereoFrame> out;
  for (;;) {
    StereoFrame f;
    auto r = s.read(f, 2s);
    EXPECT_TRUE(r) << r.error().message;
    if (!r || *r == ReadStatus::kEndOfStream) return out;
    if (*r == ReadStatus::kFrame) out.push_back(std::move(f));
  }
}

TEST(StereoSource, PairsTwoSourcesAndEnds) {
  auto s = StereoSource::create(two(50), options(true, 4));
  ASSERT_TRUE(s) << s.error().message;
  const std::vector<StereoFrame> pairs = drain(**s);
  ASSERT_EQ(pairs.size(), 50u);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    EXPECT_EQ(pairs[i].left.camera, CameraId::kLeft);
    EXPECT_EQ(pairs[i].right.camera, CameraId::kRight) << "set by the source's position";
    EXPECT_EQ(pairs[i].left.image.data()[0], pairs[i].right.image.data()[0]);
    EXPECT_EQ(pairs[i].left.sequence, i);
    EXPECT_EQ(pairs[i].skew_ns, 100'000);
  }
  const StereoSourceStats st = (*s)->stats();
  EXPECT_EQ(st.frames[0], 50u);
  EXPECT_EQ(st.frames[1], 50u);
  EXPECT_EQ(st.pairing.pairs, 50u);
  EXPECT_EQ(st.queue_drops[0] + st.queue_drops[1], 0u);
  EXPECT_EQ((*s)->uri(), "stereo://{scripted://left}{scripted://left}");
}

TEST(StereoSource, OneSourceWithBothCameras) {
  std::vector<std::unique_ptr<FrameSource>> v;
  v.push_back(std::make_unique<ScriptedSource>(20, CameraId::kLeft, true));
  auto s = StereoSource::create(std::move(v), options(true, 2));
  ASSERT_TRUE(s);
  EXPECT_EQ(drain(**s).size(), 20u);
}

// A consumer that does not keep up: live capture drops the oldest frames and counts them; every
// frame read is accounted for.
TEST(StereoSource, LiveCaptureNeverWaitsAndCountsWhatItDrops) {
  auto s = StereoSource::create(two(400), options(false, 2));
  ASSERT_TRUE(s);
  std::this_thread::sleep_for(300ms);  // the sources run dry while nobody reads
  const std::vector<StereoFrame> pairs = drain(**s);
  const StereoSourceStats st = (*s)->stats();
  EXPECT_EQ(st.frames[0], 400u) << "capture never waited";
  EXPECT_EQ(st.frames[1], 400u);
  const std::uint64_t queue = st.queue_drops[0] + st.queue_drops[1];
  EXPECT_GT(queue, 0u);
  EXPECT_LT(pairs.size(), 400u);
  EXPECT_EQ(st.pairing.pairs, pairs.size());
  EXPECT_EQ(800u, 2 * pairs.size() + queue + st.pairing.unpaired_left + st.pairing.unpaired_right)
      << "every frame is paired or counted";
}

// Stopped part-way (a run's --duration), the frames read but neither returned in a pair nor
// dropped are counted as pending, with their time span: read = 2 pairs + unpaired + queue + pending.
TEST(StereoSource, StoppedPartWayCountsThePendingFrames) {
  for (bool lossless : {true, false}) {
    SCOPED_TRACE(lossless ? "lossless" : "live");
    auto s = StereoSource::create(two(400), options(lossless, 4));
    ASSERT_TRUE(s);
    std::size_t pairs = 0;
    for (int k = 0; k < 10; ++k) {
      StereoFrame f;
      auto r = (*s)->read(f, 2s);
      ASSERT_TRUE(r) << r.error().message;
      pairs += *r == ReadStatus::kFrame;
    }
    std::this_thread::sleep_for(100ms);
    (*s)->stop();
    const StereoSourceStats st = (*s)->stats();
    const std::uint64_t read = st.frames[0] + st.frames[1];
    const std::uint64_t queue = st.queue_drops[0] + st.queue_drops[1];
    // Live capture ran dry into its bounded queues and ten reads may have taken all that was left.
    if (lossless) {
      EXPECT_GT(st.pending.count, 0u);
    }
    EXPECT_EQ(read,
              2 * pairs + st.pairing.unpaired_left + st.pairing.unpaired_right + queue + st.pending.count);
    EXPECT_EQ(st.queue_drop_t.count, queue);
    EXPECT_LE(st.pending.first_t_ns, st.pending.last_t_ns);
    if (st.pending.count) {
      EXPECT_GT(st.pending.first_t_ns, 0);
    }
  }
}

TEST(StereoSource, LosslessCaptureWaitsForTheConsumer) {
  auto s = StereoSource::create(two(200), options(true, 2));
  ASSERT_TRUE(s);
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(drain(**s).size(), 200u);
  EXPECT_EQ((*s)->stats().queue_drops[0], 0u);
}

// A live camera that delivers one frame (t_ns = t_host_ns = `t_ns`) and then nothing, as a
// camera between two frames.
class OneFrameSource final : public FrameSource {
 public:
  explicit OneFrameSource(TimestampNs t_ns) : t_ns_(t_ns) {}
  std::string uri() const override { return "one://"; }
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override {
    if (done_) {
      std::this_thread::sleep_for(std::min<std::chrono::nanoseconds>(timeout, 5ms));
      return ReadStatus::kTimeout;
    }
    done_ = true;
    out = Frame{};
    out.image = Image(4, 2, PixelFormat::kMono8);
    out.clock = ClockDomain::kHostMonotonic;
    out.t_ns = out.t_host_ns = t_ns_;
    return ReadStatus::kFrame;
  }

 private:
  TimestampNs t_ns_;
  bool done_ = false;
};

// Live: once both frames of a pair are captured, read() returns the pair at once; it does not
// hold the later frame until the other camera's next frame comes (a whole frame period).
TEST(StereoSource, LivePairIsReturnedOnceBothFramesAreIn) {
  for (bool right_later : {true, false}) {
    SCOPED_TRACE(right_later ? "right arrives later" : "left arrives later");
    std::vector<std::unique_ptr<FrameSource>> v;
    v.push_back(std::make_unique<OneFrameSource>(1'000'000'000 + (right_later ? 0 : 200'000)));
    v.push_back(std::make_unique<OneFrameSource>(1'000'000'000 + (right_later ? 200'000 : 0)));
    auto s = StereoSource::create(std::move(v), options(false, 8));
    ASSERT_TRUE(s);
    while ((*s)->stats().frames[0] + (*s)->stats().frames[1] < 2) std::this_thread::sleep_for(1ms);
    StereoFrame f;
    auto r = (*s)->read(f, 0ns);  // no waiting: both frames are in
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(*r, ReadStatus::kFrame);
    EXPECT_EQ(f.skew_ns, right_later ? 200'000 : -200'000);
  }
}

TEST(StereoSource, SourceFailureNamesTheSource) {
  auto s = StereoSource::create(two(50, 10), options(true, 4));
  ASSERT_TRUE(s);
  Expected<ReadStatus> r = ReadStatus::kTimeout;
  for (int i = 0; i < 100 && r; ++i) {
    StereoFrame f;
    r = (*s)->read(f, 1s);
  }
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("StereoSource: scripted://left: scripted failure at frame 10"),
            std::string::npos)
      << r.error().message;
}

TEST(StereoSource, BadArgumentsAreErrors) {
  EXPECT_FALSE(StereoSource::create({}, options(true, 2)));
  EXPECT_FALSE(StereoSource::create(two(1), options(true, 0)));
  StereoSourceOptions bad = options(true, 2);
  bad.pairing.tolerance_ns = -1;
  auto s = StereoSource::create(two(1), bad);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("tolerance_ns"), std::string::npos) << s.error().message;
}

}  // namespace
}  // namespace augrig
