// ReplaySource: what it emits is what was recorded, bit for bit; start, seek, loop, step and pause;
// real rate measured against the recorded spacing; a damaged frame is an error naming it and the
// replay goes on; open() errors.
#include "recorder/replay_source.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include "recorder/codec.hpp"
#include "recorder/recorder.hpp"
#include "recorder/store.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::recorder {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

constexpr TimestampNs kT0 = 5'000'000'000;
constexpr TimestampNs kPeriod = 20'000'000;  // 50 Hz

Image random_image(int w, int h, PixelFormat f, std::uint64_t seed, std::size_t stride = 0) {
  Image img(w, h, f, stride);
  std::mt19937_64 rng(seed);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w * bytes_per_pixel(f); ++x) img.row(y)[x] = static_cast<std::uint8_t>(rng());
  return img;
}

// Frame i: a Bayer left image and a padded RGB8 right image (incompressible, so a damaged blob
// stays local), distinct timestamps, clocks, sequences and exposures per camera.
FrameRecord frame(std::uint64_t i) {
  FrameRecord r;
  r.raw.pair_sequence = i;
  r.raw.left.t_ns = kT0 + static_cast<TimestampNs>(i) * kPeriod;
  r.raw.right.t_ns = r.raw.left.t_ns + 1500;
  r.raw.t_key_ns = r.raw.left.t_ns + 750;
  r.raw.skew_ns = 1500;
  r.raw.left.clock = r.raw.right.clock = ClockDomain::kDevice;
  r.raw.left.t_host_ns = 77'000 + static_cast<TimestampNs>(i);
  r.raw.right.t_host_ns = 88'000 + static_cast<TimestampNs>(i);
  r.raw.left.sequence = 1000 + i;
  r.raw.right.sequence = 2000 + i;
  r.raw.left.camera = CameraId::kLeft;
  r.raw.right.camera = CameraId::kRight;
  r.raw.left.exposure_ns = 3'000'000;
  r.raw.right.exposure_ns = 3'100'000;
  r.raw.left.image = random_image(96, 64, PixelFormat::kBayerGB8, 2 * i);
  r.raw.right.image = random_image(96, 64, PixelFormat::kRGB8, 2 * i + 1, 96 * 3 + 13);
  r.boom = BoomArticulation{deg_to_rad(30 + 0.1 * static_cast<double>(i)), deg_to_rad(1), 4.0};
  r.T_body_receiver =
      Pose::from(Eigen::Matrix3d::Identity(), Eigen::Vector3d(-20 - static_cast<double>(i), 0, 8));
  r.receiver_present = true;
  return r;
}

std::string make_recording(const std::string& name, int n) {
  const std::string dir = test::output_dir("replay_source/" + name);
  auto rec = Recorder::create(dir, RecordingInfo{});
  EXPECT_TRUE(rec) << rec.error().message;
  for (int i = 0; i < n; ++i) EXPECT_TRUE((*rec)->push(frame(static_cast<std::uint64_t>(i))));
  EXPECT_TRUE((*rec)->close());
  return dir;
}

// One recording of 10 frames for the tests that only read.
const std::string& recording10() {
  static const std::string dir =
      make_recording(std::string("ten_") + testing::UnitTest::GetInstance()->current_test_info()->name(), 10);
  return dir;
}

std::unique_ptr<ReplaySource> open_or_fail(const std::string& dir, const ReplayOptions& o = {}) {
  auto s = ReplaySource::open(dir, o);
  EXPECT_TRUE(s) << s.error().message;
  return s ? std::move(*s) : nullptr;
}

void expect_same_frame(const Frame& got, const Frame& want, const std::string& what) {
  EXPECT_TRUE(pixels_equal(got.image, want.image)) << what;
  EXPECT_EQ(got.image.format(), want.image.format()) << what;
  EXPECT_EQ(got.t_ns, want.t_ns) << what;
  EXPECT_EQ(got.clock, want.clock) << what;
  EXPECT_EQ(got.t_host_ns, want.t_host_ns) << what;
  EXPECT_EQ(got.sequence, want.sequence) << what;
  EXPECT_EQ(got.camera, want.camera) << what;
  EXPECT_EQ(got.exposure_ns, want.exposure_ns) << what;
}

// Reads one Frame in kFast mode and returns its recorded index (current_index()).
std::size_t read_index(ReplaySource& s, CameraId want_camera) {
  Frame f;
  auto st = s.read(f, 0ns);
  EXPECT_TRUE(st && *st == ReadStatus::kFrame);
  EXPECT_EQ(f.camera, want_camera);
  return s.current_index().value_or(9999);
}

TEST(ReplaySource, RawFramesAreBitIdenticalToTheRecording) {
  auto s = open_or_fail("replay://" + recording10());
  ASSERT_TRUE(s);
  EXPECT_EQ(s->uri(), "replay://" + recording10());
  EXPECT_EQ(s->frame_count(), 10u);
  EXPECT_FALSE(s->current_index());
  for (std::uint64_t i = 0; i < 10; ++i) {
    const FrameRecord want = frame(i);
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      Frame f;
      auto st = s->read(f, 1s);
      ASSERT_TRUE(st) << st.error().message;
      ASSERT_EQ(*st, ReadStatus::kFrame);
      expect_same_frame(f, want.raw[id], "frame " + std::to_string(i) + " " + std::string(to_string(id)));
      // The recorded per-frame data of the frame just emitted.
      ASSERT_EQ(s->current_index(), i);
      const FrameRecord& cur = s->current();
      EXPECT_EQ(cur.raw.t_key_ns, want.raw.t_key_ns);
      EXPECT_EQ(cur.raw.skew_ns, want.raw.skew_ns);
      EXPECT_EQ(cur.raw.pair_sequence, i);
      ASSERT_TRUE(cur.boom);
      EXPECT_EQ(cur.boom->elevation_rad, want.boom->elevation_rad);
      ASSERT_TRUE(cur.T_body_receiver);
      EXPECT_EQ(cur.T_body_receiver->translation_m, want.T_body_receiver->translation_m);
      EXPECT_TRUE(cur.augmented[0].empty()) << "only the raw images are decoded by default";
    }
  }
  Frame f;
  auto st = s->read(f, 1s);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kEndOfStream);
  EXPECT_EQ(s->frames_dropped(), 0u);
}

TEST(ReplaySource, AttachmentCarriesTheStoredRawBlobs) {
  auto s = open_or_fail(recording10());
  ASSERT_TRUE(s);
  auto db = Database::open(database_path(recording10()), SQLITE_OPEN_READONLY);
  ASSERT_TRUE(db) << db.error().message;
  auto q = Statement::prepare(db->get(), "SELECT left_raw, right_raw FROM frames WHERE id = ?");
  ASSERT_TRUE(q) << q.error().message;
  for (std::uint64_t i = 0; i < 10; ++i) {
    Frame left, right;
    ASSERT_EQ(*s->read(left, 1s), ReadStatus::kFrame);
    // The raw images are moved out to the Frames that emit them; the right one waits in current().
    EXPECT_TRUE(s->current().raw.left.image.empty());
    EXPECT_FALSE(s->current().raw.right.image.empty());
    EXPECT_EQ(s->current().raw.left.t_ns, left.t_ns);
    ASSERT_EQ(*s->read(right, 1s), ReadStatus::kFrame);
    EXPECT_TRUE(s->current().raw.right.image.empty());
    ASSERT_EQ(left.attachment, right.attachment) << "both Frames share their stereo frame's attachment";
    const RecordedFrame* rf = left.attachment->recorded();
    ASSERT_NE(rf, nullptr);
    EXPECT_EQ(rf->index, i);
    // The same through the generic accessors the pipeline uses.
    ASSERT_TRUE(left.attachment->position());
    EXPECT_EQ(left.attachment->position()->index, i);
    EXPECT_EQ(left.attachment->position()->pass, 0);
    ASSERT_TRUE(left.attachment->recorded_pairing());
    EXPECT_EQ(left.attachment->recorded_pairing()->t_key_ns, rf->record.raw.t_key_ns);
    EXPECT_EQ(left.attachment->recorded_pairing()->pair_sequence, rf->record.raw.pair_sequence);
    sqlite3_bind_int64(q->get(), 1, static_cast<sqlite3_int64>(i + 1));
    ASSERT_EQ(q->step(), SQLITE_ROW);
    for (const Frame* f : {&left, &right}) {
      const int c = index_of(f->camera);
      const StoredRawBlob& b = rf->raw_blobs[c];
      const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(q->get(), c));
      const std::vector<std::uint8_t> want(p, p + sqlite3_column_bytes(q->get(), c));
      EXPECT_EQ(b.bytes, want) << "frame " << i << " camera " << c << ": the blob as stored";
      EXPECT_EQ(b.format, f->image.format());
      EXPECT_EQ(b.width, f->image.width());
      EXPECT_EQ(b.height, f->image.height());
      EXPECT_EQ(b.t_ns, f->t_ns);
      EXPECT_EQ(b.fingerprint, raw_fingerprint(f->image.cview()));
      Image decoded;
      Decoder dec;
      ASSERT_TRUE(dec.decode_image(b.bytes.data(), b.bytes.size(), b.width, b.height, b.format, decoded));
      EXPECT_TRUE(pixels_equal(decoded, f->image));
    }
    q->reset();
  }

  // Not kept when not asked for.
  ReplayOptions o;
  o.keep_raw_blobs = false;
  auto t = open_or_fail(recording10(), o);
  ASSERT_TRUE(t);
  Frame f;
  ASSERT_EQ(*t->read(f, 1s), ReadStatus::kFrame);
  const auto* rf = dynamic_cast<const RecordedFrame*>(f.attachment.get());
  ASSERT_NE(rf, nullptr);
  EXPECT_TRUE(rf->raw_blobs[0].empty() && rf->raw_blobs[1].empty());
}

// What a recording can do, asked as capabilities rather than by its type.
TEST(ReplaySource, CapabilitiesAreARecordingsOnes) {
  ReplayOptions o;
  o.start_frame = 2;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  const SourceCapabilities c = s->capabilities();
  EXPECT_TRUE(c.finite && c.seekable && c.paced && c.ranged);
  EXPECT_EQ(s->pair_count(), 8u);
  EXPECT_EQ(s->range_start(), 2u);
  EXPECT_EQ(s->origin_t_ns(), s->first_t_ns());
  ASSERT_TRUE(s->set_range_end(5));
  EXPECT_EQ(s->pair_count(), 3u);
  EXPECT_FALSE(s->set_range_end(1));  // not after the start
}

TEST(ReplaySource, StartOptionsAndSeek) {
  ReplayOptions o;
  o.start_frame = 4;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 4u);

  o = {};
  o.start_t_ns = kT0 + 6 * kPeriod + 751;  // frame 6's t_key_ns + 1: the first frame at or after it is 7
  s = open_or_fail(recording10(), o);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 7u);

  o = {};
  o.start_offset_ns = 2 * kPeriod;  // t_key of frame 0 + 40 ms: frame 2
  s = open_or_fail(recording10(), o);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 2u);

  // Seeks from the middle of a stereo frame: its right Frame is discarded.
  ASSERT_TRUE(s->seek_frame(8));
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 8u);
  EXPECT_EQ(read_index(*s, CameraId::kRight), 8u);
  ASSERT_TRUE(s->seek_time(kT0 + 3 * kPeriod + 750));  // exactly frame 3's t_key_ns
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 3u);
  ASSERT_TRUE(s->seek_time(0));
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);

  auto bad = s->seek_frame(10);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("frame 10 is past the last frame (10 frames)"), std::string::npos);
  bad = s->seek_time(kT0 + 100 * kPeriod);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("no frame at or after t_ns"), std::string::npos);

  o = {};
  o.start_frame = 10;
  auto e = ReplaySource::open(recording10(), o);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("start frame 10 is past the last frame"), std::string::npos)
      << e.error().message;
  o = {};
  o.start_t_ns = kT0 + 100 * kPeriod;
  e = ReplaySource::open(recording10(), o);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("the last frame is at t_ns"), std::string::npos) << e.error().message;
}

TEST(ReplaySource, LoopPlaysTheRangeAgain) {
  ReplayOptions o;
  o.start_frame = 7;
  o.passes = 3;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  std::vector<std::pair<int, std::size_t>> seen;  // (pass, index) of each left Frame
  Frame f;
  for (;;) {
    auto st = s->read(f, 1s);
    ASSERT_TRUE(st);
    if (*st == ReadStatus::kEndOfStream) break;
    expect_same_frame(f, frame(*s->current_index()).raw[f.camera], "loop");
    if (f.camera == CameraId::kLeft) seen.emplace_back(s->pass(), *s->current_index());
  }
  const std::vector<std::pair<int, std::size_t>> want = {{0, 7}, {0, 8}, {0, 9}, {1, 7}, {1, 8},
                                                         {1, 9}, {2, 7}, {2, 8}, {2, 9}};
  EXPECT_EQ(seen, want);

  // passes = 0: forever.
  o.passes = 0;
  s = open_or_fail(recording10(), o);
  for (int k = 0; k < 60; ++k) {
    auto st = s->read(f, 1s);
    ASSERT_TRUE(st && *st == ReadStatus::kFrame);
  }
  EXPECT_EQ(s->pass(), 9);
}

TEST(ReplaySource, StepModeReleasesOneStereoFramePerStep) {
  ReplayOptions o;
  o.mode = ReplayMode::kStep;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  Frame f;
  auto st = s->read(f, 20ms);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout);
  s->step();
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  EXPECT_EQ(read_index(*s, CameraId::kRight), 0u);  // the right Frame comes without another step
  st = s->read(f, 0ns);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout);
  s->step(2);
  for (std::size_t want : {1u, 1u, 2u, 2u}) {
    st = s->read(f, 0ns);
    ASSERT_TRUE(st && *st == ReadStatus::kFrame);
    EXPECT_EQ(s->current_index(), want);
  }

  // A step from another thread wakes a read() that waits.
  const auto t0 = SteadyClock::now();
  auto stepper = std::async(std::launch::async, [&] {
    std::this_thread::sleep_for(50ms);
    s->step();
  });
  st = s->read(f, 10s);
  const auto waited = SteadyClock::now() - t0;
  stepper.get();
  ASSERT_TRUE(st && *st == ReadStatus::kFrame);
  EXPECT_EQ(s->current_index(), 3u);
  EXPECT_GE(waited, 45ms);
  EXPECT_LT(waited, 5s);
}

TEST(ReplaySource, PauseHoldsFastModeAndStepReleasesWhilePaused) {
  auto s = open_or_fail(recording10());
  ASSERT_TRUE(s);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  s->set_paused(true);
  EXPECT_TRUE(s->paused());
  EXPECT_EQ(read_index(*s, CameraId::kRight), 0u);  // pause acts between stereo frames
  Frame f;
  auto st = s->read(f, 10ms);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout);
  s->step();
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 1u);
  EXPECT_EQ(read_index(*s, CameraId::kRight), 1u);
  st = s->read(f, 0ns);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout);
  s->set_paused(false);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 2u);
}

// Wall time from the first to the last left Frame, against the recorded spacing divided by the
// rate. Not a performance test: the bounds are wide, what matters is that frames are paced.
double paced_seconds(double rate, int frames) {
  ReplayOptions o;
  o.mode = ReplayMode::kRealRate;
  o.rate = rate;
  o.passes = 1;
  auto s = open_or_fail(recording10(), o);
  Frame f;
  std::optional<SteadyClock::time_point> first;
  SteadyClock::time_point last;
  int lefts = 0;
  while (lefts < frames) {
    auto st = s->read(f, 1s);
    EXPECT_TRUE(st);
    if (!st || *st == ReadStatus::kEndOfStream) break;
    if (*st != ReadStatus::kFrame || f.camera != CameraId::kLeft) continue;
    last = SteadyClock::now();
    if (!first) first = last;
    ++lefts;
  }
  return std::chrono::duration<double>(last - *first).count();
}

TEST(ReplaySource, RealRateFollowsTheRecordedSpacing) {
  // 10 frames 20 ms apart: 180 ms from the first to the last at rate 1, 90 ms at rate 2.
  // Never early; late only by scheduling (wide bounds: tests run in parallel on 2 cores).
  const double at1 = paced_seconds(1.0, 10);
  EXPECT_GE(at1, 0.178);
  EXPECT_LT(at1, 0.180 * 2 + 0.1);
  const double at2 = paced_seconds(2.0, 10);
  EXPECT_GE(at2, 0.089);
  EXPECT_LT(at2, 0.090 * 2 + 0.1);
  EXPECT_LT(at2, 0.8 * at1) << "twice the rate, about half the time";
  const double at_half = paced_seconds(0.5, 4);  // 3 intervals of 40 ms
  EXPECT_GE(at_half, 0.119);
  EXPECT_LT(at_half, 0.120 * 2 + 0.1);
}

TEST(ReplaySource, RealRateTimesOutUntilTheFrameIsDue) {
  ReplayOptions o;
  o.mode = ReplayMode::kRealRate;
  o.rate = 0.1;  // 200 ms between frames
  auto s = open_or_fail(recording10(), o);
  Frame f;
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);  // the first frame sets the anchor: at once
  auto st = s->read(f, 100ms);                     // the right one is 15 us later
  ASSERT_TRUE(st && *st == ReadStatus::kFrame);
  EXPECT_EQ(f.camera, CameraId::kRight);
  st = s->read(f, 20ms);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout);
  st = s->read(f, 2s);
  ASSERT_TRUE(st && *st == ReadStatus::kFrame);
  EXPECT_EQ(s->current_index(), 1u);
}

// The window's rate control: a replay slowed to a crawl times out; set to "fast" (0) the next frame
// comes at once; set to a real rate again it paces from a fresh anchor.
TEST(ReplaySource, SetRateSwitchesBetweenRealRateAndFast) {
  ReplayOptions o;
  o.mode = ReplayMode::kRealRate;
  o.rate = 0.001;  // 33 s between frames
  auto s = open_or_fail(recording10(), o);
  EXPECT_DOUBLE_EQ(s->rate(), 0.001);
  Frame f;
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  ASSERT_TRUE(s->read(f, 100ms));  // its right Frame
  auto st = s->read(f, 20ms);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout) << "frame 1 is 33 s away";
  ASSERT_TRUE(s->set_rate(0));
  EXPECT_EQ(s->rate(), 0.0);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 1u) << "fast: at once";
  ASSERT_TRUE(s->read(f, 0ns));
  ASSERT_TRUE(s->set_rate(0.001));
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 2u) << "real rate again: the next frame anchors, at once";
  ASSERT_TRUE(s->read(f, 100ms));
  st = s->read(f, 20ms);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout);
  EXPECT_FALSE(s->set_rate(-1));
  // Paced frames carry their release time on the host clock (a replayed mid-exposure); fast ones none.
  const auto* paced = dynamic_cast<const RecordedFrame*>(f.attachment.get());
  ASSERT_TRUE(paced);
  EXPECT_GT(paced->released_host_ns, 0);
  ASSERT_TRUE(s->set_rate(0));
  Frame g;
  ASSERT_TRUE(s->read(g, 0ns));
  const auto* fast = dynamic_cast<const RecordedFrame*>(g.attachment.get());
  ASSERT_TRUE(fast);
  EXPECT_EQ(fast->released_host_ns, 0);
  EXPECT_FALSE(s->set_rate(std::numeric_limits<double>::infinity()));
}

TEST(ReplaySource, LateConsumerGetsEveryFrameUnlessDropLate) {
  ReplayOptions o;
  o.mode = ReplayMode::kRealRate;
  o.rate = 4.0;  // 5 ms between frames
  for (bool drop : {false, true}) {
    o.drop_late = drop;
    o.late_tolerance = 2ms;
    auto s = open_or_fail(recording10(), o);
    Frame f;
    std::size_t lefts = 0;
    for (;;) {
      auto st = s->read(f, 1s);
      ASSERT_TRUE(st);
      if (*st == ReadStatus::kEndOfStream) break;
      if (f.camera == CameraId::kLeft) {
        ++lefts;
        std::this_thread::sleep_for(25ms);  // a consumer five times too slow
      }
    }
    if (!drop) {
      EXPECT_EQ(lefts, 10u);
      EXPECT_EQ(s->frames_dropped(), 0u);
    } else {
      EXPECT_LT(lefts, 6u);
      EXPECT_EQ(s->frames_dropped(), 2 * (10 - lefts)) << "every skipped Frame is counted";
    }
  }
}

TEST(ReplaySource, DamagedFrameIsAnErrorNamingItAndReplayGoesOn) {
  const std::string dir = make_recording("damaged", 6);
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(
        d->exec("UPDATE frames SET right_raw = CAST(substr(right_raw, 1, 3000) || x'00' || "
                "substr(right_raw, 3002) AS BLOB) WHERE pair_sequence = 3"));
  }
  auto s = open_or_fail(dir);
  ASSERT_TRUE(s);
  std::vector<std::size_t> lefts;
  std::vector<std::string> errors;
  Frame f;
  for (;;) {
    auto st = s->read(f, 1s);
    if (!st) {
      errors.push_back(st.error().message);
      continue;
    }
    if (*st == ReadStatus::kEndOfStream) break;
    expect_same_frame(f, frame(*s->current_index()).raw[f.camera], "after damage");
    if (f.camera == CameraId::kLeft) lefts.push_back(*s->current_index());
  }
  EXPECT_EQ(lefts, (std::vector<std::size_t>{0, 1, 2, 4, 5}));
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].rfind("recorder::ReplaySource::read(): " + dir + "/recording.sqlite: frame 3: ", 0), 0u)
      << errors[0];
  EXPECT_NE(errors[0].find("replay goes on with frame 4"), std::string::npos) << errors[0];
  EXPECT_EQ(s->damaged_frames(), 1u);
  EXPECT_EQ(s->frames_dropped(), 2u);
}

// ---- Read-ahead (ReplayOptions::read_ahead): a decode thread fills a bounded queue ----

// Waits (at most 5 s) until `n` stereo frames are decoded ahead; false if that never happens.
// The left indices a source emits until its end.
std::vector<std::size_t> left_indices(ReplaySource& s) {
  std::vector<std::size_t> seen;
  Frame f;
  for (;;) {
    auto st = s.read(f, 1s);
    EXPECT_TRUE(st) << st.error().message;
    if (!st || *st == ReadStatus::kEndOfStream) break;
    if (f.camera == CameraId::kLeft) seen.push_back(*s.current_index());
  }
  return seen;
}

TEST(ReplaySource, EndFrameEndsTheRangeAndEveryLoopPass) {
  ReplayOptions o;
  o.start_frame = 3;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->end_frame(), 10u);  // the recording's end unless set
  ASSERT_TRUE(s->set_end_frame(6));
  EXPECT_EQ(s->end_frame(), 6u);
  EXPECT_EQ(left_indices(*s), (std::vector<std::size_t>{3, 4, 5}));

  o.passes = 2;  // every pass ends there
  s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s->set_end_frame(5));
  EXPECT_EQ(left_indices(*s), (std::vector<std::size_t>{3, 4, 3, 4}));

  o.passes = 1;
  o.read_ahead = 0;  // the same without the read-ahead thread
  s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s->set_end_frame(4));
  EXPECT_EQ(left_indices(*s), (std::vector<std::size_t>{3}));

  // Past the recording's end: clamped to it.
  s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s->set_end_frame(1000));
  EXPECT_EQ(s->end_frame(), 10u);
  EXPECT_EQ(left_indices(*s).size(), 7u);

  // Not after the start; a seek past the end of the range.
  auto bad = s->set_end_frame(3);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("recorder::ReplaySource::set_end_frame(): "), std::string::npos)
      << bad.error().message;
  EXPECT_NE(bad.error().message.find("the end (frame 3) is not after the start (frame 3)"), std::string::npos)
      << bad.error().message;
  s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s->set_end_frame(6));
  bad = s->seek_frame(6);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("frame 6 is past the end of the range played (frames 3..5)"), std::string::npos)
      << bad.error().message;
  ASSERT_TRUE(s->seek_frame(5));
  EXPECT_EQ(left_indices(*s), (std::vector<std::size_t>{5}));
}

TEST(ReplaySource, FirstTimeIsTheFirstReadableFramesLeftTimeWhateverTheStart) {
  ReplayOptions o;
  o.start_frame = 4;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->first_t_ns(), std::optional<TimestampNs>(kT0));  // frame 0's left t_ns, not its t_key_ns
  // Frame 0's metadata unreadable: frame 1 is the recording's first.
  const std::string dir = make_recording("first_unreadable", 3);
  {
    auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec("UPDATE frames SET pair_sequence = 'x' WHERE pair_sequence = 0"));
  }
  s = open_or_fail(dir);
  ASSERT_TRUE(s);
  EXPECT_FALSE(s->frame_times()[0]);
  EXPECT_EQ(s->first_t_ns(), std::optional<TimestampNs>(kT0 + kPeriod));
}

bool wait_read_ahead(const ReplaySource& s, std::size_t n) {
  const auto until = SteadyClock::now() + 5s;
  while (s.frames_read_ahead() < n) {
    if (SteadyClock::now() > until) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

// Damages frame `pair_sequence`'s right raw blob (one byte changed: its checksum fails).
void damage(const std::string& dir, int pair_sequence) {
  auto d = Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
  ASSERT_TRUE(d);
  // The byte flipped (set to 0 it may be 0 already).
  ASSERT_TRUE(d->exec("UPDATE frames SET right_raw = CAST(substr(right_raw, 1, 3000) || "
                      "CASE WHEN substr(right_raw, 3001, 1) = x'00' THEN x'01' ELSE x'00' END || "
                      "substr(right_raw, 3002) AS BLOB) WHERE pair_sequence = " +
                      std::to_string(pair_sequence)));
}

TEST(ReplaySource, ReadAheadIsBoundedAndFollowsTheMode) {
  ReplayOptions o;
  o.read_ahead = 3;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frames_read_ahead(), 0u) << "nothing is read before the first read()";
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  ASSERT_TRUE(wait_read_ahead(*s, 3)) << "frames 1, 2 and 3 are decoded while the consumer works";
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(s->frames_read_ahead(), 3u) << "and no more: the queue is bounded";
  EXPECT_EQ(read_index(*s, CameraId::kRight), 0u);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 1u);
  ASSERT_TRUE(wait_read_ahead(*s, 3));
  EXPECT_EQ(s->frames_read_ahead(), 3u);

  // Stepped (and paced, and paused) replay keeps only the next stereo frame decoded.
  o.mode = ReplayMode::kStep;
  s = open_or_fail(recording10(), o);
  s->step();
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  ASSERT_TRUE(wait_read_ahead(*s, 1));
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(s->frames_read_ahead(), 1u);

  // read_ahead = 0: no thread, read() decodes each frame itself (nothing waits decoded).
  o = {};
  o.read_ahead = 0;
  s = open_or_fail(recording10(), o);
  for (std::uint64_t i = 0; i < 10; ++i) {
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      Frame f;
      ASSERT_EQ(*s->read(f, 0ns), ReadStatus::kFrame);
      expect_same_frame(f, frame(i).raw[id], "without read-ahead");
    }
    std::this_thread::sleep_for(1ms);
    EXPECT_EQ(s->frames_read_ahead(), 0u);
  }
  Frame f;
  EXPECT_EQ(*s->read(f, 0ns), ReadStatus::kEndOfStream);
  EXPECT_EQ(s->read_ahead_cpu_ms(), 0.0);
}

TEST(ReplaySource, SeekDiscardsWhatWasReadAheadAndTheSoughtFrameComesNext) {
  ReplayOptions o;
  o.read_ahead = 4;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  ASSERT_TRUE(wait_read_ahead(*s, 4));  // frames 1 to 4 are waiting
  ASSERT_TRUE(s->seek_frame(7));
  EXPECT_EQ(s->frames_read_ahead(), 0u) << "the seek empties the queue";
  Frame f;
  ASSERT_EQ(*s->read(f, 0ns), ReadStatus::kFrame);
  EXPECT_EQ(s->current_index(), 7u);
  expect_same_frame(f, frame(7).raw.left, "the sought frame, left");
  EXPECT_EQ(read_index(*s, CameraId::kRight), 7u);
  ASSERT_TRUE(wait_read_ahead(*s, 2));  // 8 and 9
  ASSERT_TRUE(s->seek_frame(2));        // back, with 8 and 9 read ahead
  std::vector<std::size_t> rest;
  for (;;) {
    auto st = s->read(f, 1s);
    ASSERT_TRUE(st);
    if (*st == ReadStatus::kEndOfStream) break;
    expect_same_frame(f, frame(*s->current_index()).raw[f.camera], "after the seek back");
    if (f.camera == CameraId::kLeft) rest.push_back(*s->current_index());
  }
  EXPECT_EQ(rest, (std::vector<std::size_t>{2, 3, 4, 5, 6, 7, 8, 9}));
  // After the end, a seek plays on from the sought frame.
  ASSERT_TRUE(s->seek_frame(9));
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 9u);
  EXPECT_EQ(s->frames_dropped(), 0u) << "frames passed over by a seek are not dropped";

  // Seeks that land while the decode thread is in the middle of a frame (random moments): the
  // next read() is always the sought frame, never one loaded before the seek.
  std::mt19937 rng(7);
  for (int k = 0; k < 200; ++k) {
    const std::size_t want = rng() % 10;
    std::this_thread::sleep_for(std::chrono::microseconds(rng() % 300));
    ASSERT_TRUE(s->seek_frame(want));
    ASSERT_EQ(*s->read(f, 0ns), ReadStatus::kFrame);
    ASSERT_EQ(s->current_index(), want) << "seek " << k;
    ASSERT_EQ(f.camera, CameraId::kLeft);
    ASSERT_EQ(f.sequence, 1000 + want);
    if (rng() % 2) {
      ASSERT_EQ(*s->read(f, 0ns), ReadStatus::kFrame);  // its right Frame
      ASSERT_EQ(f.sequence, 2000 + want);
    }
  }
}

// Seeks from another thread while the reading thread reads and the decode thread reads ahead:
// after each seek, the first left Frame the reader gets is the sought one (the controller waits
// for it before the next seek), and every Frame is the recorded one.
TEST(ReplaySource, SeeksFromAnotherThreadNeverLetAStaleFrameThrough) {
  ReplayOptions o;
  o.read_ahead = 3;
  o.passes = 0;  // forever: the reader never runs out
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  std::mutex m;
  std::condition_variable cv;
  std::optional<std::size_t> sought;  // set by the controller, cleared by the reader when seen
  std::uint64_t seeks_done = 0;       // seek_frame() calls returned (under m)
  bool done = false;
  int mismatches = 0, seeks_seen = 0;
  std::thread reader([&] {
    Frame f;
    while (true) {
      std::uint64_t before = 0;
      {
        std::lock_guard lk(m);
        if (done) return;
        before = seeks_done;
      }
      auto st = s->read(f, 100ms);
      if (!st || *st != ReadStatus::kFrame) continue;
      const std::size_t i = *s->current_index();
      if (f.sequence != (f.camera == CameraId::kLeft ? 1000 : 2000) + i) ++mismatches;
      std::lock_guard lk(m);
      if (!sought) continue;
      const bool is_sought = f.camera == CameraId::kLeft && i == *sought;
      if (before == seeks_done) {
        // A read() that began after the seek returned: it must be the sought frame's left Frame.
        if (!is_sought) ++mismatches;
      } else if (!is_sought) {
        continue;  // a read() that overlapped the seek may come from before it
      }
      sought.reset();
      ++seeks_seen;
      cv.notify_all();
    }
  });
  std::mt19937 rng(11);
  for (int k = 0; k < 100; ++k) {
    std::unique_lock lk(m);
    const std::size_t want = rng() % 10;
    sought = want;
    EXPECT_TRUE(s->seek_frame(want));
    ++seeks_done;
    if (!cv.wait_for(lk, 5s, [&] { return !sought; })) {
      ADD_FAILURE() << "seek " << k << " never arrived";
      break;
    }
  }
  {
    std::lock_guard lk(m);
    done = true;
  }
  reader.join();
  EXPECT_EQ(seeks_seen, 100);
  EXPECT_EQ(mismatches, 0);
}

TEST(ReplaySource, PauseAndStepWithFramesReadAhead) {
  ReplayOptions o;
  o.read_ahead = 4;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  ASSERT_TRUE(wait_read_ahead(*s, 4));
  s->set_paused(true);
  EXPECT_EQ(read_index(*s, CameraId::kRight), 0u);
  Frame f;
  auto st = s->read(f, 20ms);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout) << "paused: frames decoded ahead are not released";
  s->step();
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 1u);
  EXPECT_EQ(read_index(*s, CameraId::kRight), 1u);
  st = s->read(f, 0ns);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout) << "one step, one stereo frame";
  // A seek while paused, then a step: the sought frame, not the next one read ahead.
  ASSERT_TRUE(s->seek_frame(6));
  st = s->read(f, 0ns);
  ASSERT_TRUE(st);
  EXPECT_EQ(*st, ReadStatus::kTimeout);
  s->step();
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 6u);
  EXPECT_EQ(read_index(*s, CameraId::kRight), 6u);
  // A step from another thread wakes a read() that waits.
  auto stepper = std::async(std::launch::async, [&] {
    std::this_thread::sleep_for(30ms);
    s->step();
  });
  st = s->read(f, 10s);
  stepper.get();
  ASSERT_TRUE(st && *st == ReadStatus::kFrame);
  EXPECT_EQ(s->current_index(), 7u);
  s->set_paused(false);
  std::vector<std::size_t> rest;
  for (;;) {
    st = s->read(f, 1s);
    ASSERT_TRUE(st);
    if (*st == ReadStatus::kEndOfStream) break;
    if (f.camera == CameraId::kLeft) rest.push_back(*s->current_index());
  }
  EXPECT_EQ(rest, (std::vector<std::size_t>{8, 9}));
  EXPECT_EQ(s->frames_dropped(), 0u);
}

TEST(ReplaySource, LoopWithReadAheadAcrossThePasses) {
  ReplayOptions o;
  o.start_frame = 7;
  o.passes = 3;
  o.read_ahead = 4;  // deeper than a pass: the queue holds frames of the next pass
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  std::vector<std::pair<int, std::size_t>> seen;
  Frame f;
  bool sought = false;
  for (;;) {
    auto st = s->read(f, 1s);
    ASSERT_TRUE(st);
    if (*st == ReadStatus::kEndOfStream) break;
    expect_same_frame(f, frame(*s->current_index()).raw[f.camera], "loop with read-ahead");
    if (f.camera != CameraId::kLeft) continue;
    seen.emplace_back(s->pass(), *s->current_index());
    if (!sought && s->pass() == 1 && *s->current_index() == 7) {
      // Pass 1's frame 7 is out and frames of pass 2 are decoded; a seek stays in pass 1.
      ASSERT_TRUE(wait_read_ahead(*s, 4));
      ASSERT_TRUE(s->seek_frame(8));
      sought = true;
    }
    std::this_thread::sleep_for(2ms);
  }
  const std::vector<std::pair<int, std::size_t>> want = {{0, 7}, {0, 8}, {0, 9}, {1, 7}, {1, 8},
                                                         {1, 9}, {2, 7}, {2, 8}, {2, 9}};
  EXPECT_EQ(seen, want);
  EXPECT_EQ(s->frames_dropped(), 0u);
}

// Real rate anchors afresh at every pass: each pass takes the recorded time, even though the next
// pass's frames were decoded while the last one played.
TEST(ReplaySource, RealRateLoopAnchorsEachPass) {
  ReplayOptions o;
  o.mode = ReplayMode::kRealRate;
  o.start_frame = 6;  // frames 6..9: 60 ms a pass
  o.passes = 2;
  o.read_ahead = 4;
  auto s = open_or_fail(recording10(), o);
  ASSERT_TRUE(s);
  Frame f;
  std::vector<std::pair<int, SteadyClock::time_point>> lefts;
  for (;;) {
    auto st = s->read(f, 1s);
    ASSERT_TRUE(st);
    if (*st == ReadStatus::kEndOfStream) break;
    if (*st == ReadStatus::kFrame && f.camera == CameraId::kLeft) lefts.emplace_back(s->pass(), SteadyClock::now());
  }
  ASSERT_EQ(lefts.size(), 8u);
  const double pass0 = std::chrono::duration<double>(lefts[3].second - lefts[0].second).count();
  const double pass1 = std::chrono::duration<double>(lefts[7].second - lefts[4].second).count();
  EXPECT_GE(pass0, 0.059);
  EXPECT_GE(pass1, 0.059) << "the second pass is paced from its own first frame";
  EXPECT_LT(pass1, 0.060 * 2 + 0.1);
}

TEST(ReplaySource, DamagedFrameReadAheadIsReportedInTurnAndCountedOnce) {
  const std::string dir = make_recording("damaged_read_ahead", 8);
  damage(dir, 3);
  ReplayOptions o;
  o.read_ahead = 4;
  o.passes = 2;
  auto s = open_or_fail(dir, o);
  ASSERT_TRUE(s);
  std::vector<std::string> order;  // "L<i>" per left Frame, "E<i>" per error
  Frame f;
  for (;;) {
    auto st = s->read(f, 1s);
    if (!st) {
      order.push_back("E");
      EXPECT_EQ(st.error().message.rfind("recorder::ReplaySource::read(): " + dir + "/recording.sqlite: frame 3: ", 0),
                0u)
          << st.error().message;
      EXPECT_NE(st.error().message.find("replay goes on with frame 4"), std::string::npos) << st.error().message;
      continue;
    }
    if (*st == ReadStatus::kEndOfStream) break;
    expect_same_frame(f, frame(*s->current_index()).raw[f.camera], "around the damage");
    if (f.camera == CameraId::kLeft) {
      order.push_back(std::to_string(*s->current_index()));
      if (*s->current_index() == 0) {
        ASSERT_TRUE(wait_read_ahead(*s, 4));  // 1, 2, 3 (damaged), 4 waiting
      }
    }
  }
  const std::vector<std::string> want = {"0", "1", "2", "E", "4", "5", "6", "7",
                                         "0", "1", "2", "E", "4", "5", "6", "7"};
  EXPECT_EQ(order, want);
  EXPECT_EQ(s->damaged_frames(), 2u) << "once per pass";
  EXPECT_EQ(s->frames_dropped(), 4u);

  // A damaged frame read ahead and then passed over by a seek is neither reported nor counted.
  s = open_or_fail(dir, o);
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
  ASSERT_TRUE(wait_read_ahead(*s, 4));  // 1, 2, 3 (damaged), 4
  ASSERT_TRUE(s->seek_frame(5));
  EXPECT_EQ(read_index(*s, CameraId::kLeft), 5u);
  EXPECT_EQ(s->damaged_frames(), 0u);
  EXPECT_EQ(s->frames_dropped(), 0u);
}

// Every recorded Frame is emitted or counted in frames_dropped() once: fast, and real rate with
// drop_late behind a slow consumer, with a damaged frame, with read-ahead.
TEST(ReplaySource, FrameCountsAddUpWithReadAhead) {
  const std::string dir = make_recording("counts_read_ahead", 10);
  damage(dir, 6);
  for (bool paced : {false, true}) {
    ReplayOptions o;
    o.read_ahead = 3;
    o.passes = 2;
    if (paced) {
      o.mode = ReplayMode::kRealRate;
      o.rate = 4.0;  // 5 ms between frames
      o.drop_late = true;
      o.late_tolerance = 2ms;
    }
    auto s = open_or_fail(dir, o);
    ASSERT_TRUE(s);
    std::uint64_t emitted = 0, errors = 0;
    Frame f;
    for (;;) {
      auto st = s->read(f, 1s);
      if (!st) {
        ++errors;
        continue;
      }
      if (*st == ReadStatus::kEndOfStream) break;
      if (*st != ReadStatus::kFrame) continue;
      ++emitted;
      if (paced && f.camera == CameraId::kLeft) std::this_thread::sleep_for(12ms);  // too slow
    }
    EXPECT_EQ(errors, 2u) << "paced " << paced;
    EXPECT_EQ(s->damaged_frames(), 2u);
    EXPECT_EQ(emitted + s->frames_dropped(), 40u) << "paced " << paced << ": emitted " << emitted;
    if (paced) {
      EXPECT_LT(emitted, 30u) << "the slow consumer lost frames";
    } else {
      EXPECT_EQ(emitted, 36u);
    }
  }
}

// Destroys `s` on another thread; a destructor that hangs fails the test binary at once (it
// cannot be recovered from) instead of leaving it to the test timeout.
void destroy_or_die(std::unique_ptr<ReplaySource>& s, const std::string& what) {
  auto done = std::async(std::launch::async, [&] { s.reset(); });
  if (done.wait_for(5s) != std::future_status::ready) {
    std::fprintf(stderr, "FAILED: ~ReplaySource() hangs (%s)\n", what.c_str());
    std::_Exit(1);
  }
}

// The destructor ends the decode thread while it waits for room (a consumer that stopped reading),
// while it decodes, and when nothing was read at all.
TEST(ReplaySource, DestructionWhileTheDecodeThreadWaitsForRoom) {
  for (int k = 0; k < 20; ++k) {
    ReplayOptions o;
    o.read_ahead = 2;
    auto s = open_or_fail(recording10(), o);
    ASSERT_TRUE(s);
    EXPECT_EQ(read_index(*s, CameraId::kLeft), 0u);
    if (k == 0) {
      ASSERT_TRUE(wait_read_ahead(*s, 2));  // the queue is full: the thread waits for room
      std::this_thread::sleep_for(20ms);
    } else {
      std::this_thread::sleep_for(std::chrono::microseconds(50 * k));  // mid-decode, some of them
    }
    const auto t0 = SteadyClock::now();
    destroy_or_die(s, "round " + std::to_string(k));  // on another thread than the one that read
    EXPECT_LT(SteadyClock::now() - t0, 1s) << "round " << k;
  }
  // Never read: no thread was started.
  auto s = open_or_fail(recording10());
  destroy_or_die(s, "never read");
}

TEST(ReplaySource, OpenErrorsNameThePath) {
  const std::string missing = test::output_dir("replay_source/missing") + "/nothing-here";
  auto e = ReplaySource::open("replay://" + missing);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find(missing + ": no such file"), std::string::npos) << e.error().message;

  const std::string empty = test::output_dir("replay_source/empty_folder");
  e = ReplaySource::open(empty);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("recording.sqlite: no such file (a recording folder holds"),
            std::string::npos)
      << e.error().message;

  const std::string junk = test::output_dir("replay_source/junk");
  std::ofstream(junk + "/recording.sqlite") << "this is not a database, just some text that is long enough\n";
  e = ReplaySource::open(junk);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find(junk + "/recording.sqlite"), std::string::npos) << e.error().message;

  e = ReplaySource::open("replay://");
  ASSERT_FALSE(e);
  ReplayOptions o;
  o.rate = 0;
  e = ReplaySource::open(recording10(), o);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("rate must be a positive number"), std::string::npos);
}

}  // namespace
}  // namespace augrig::recorder
