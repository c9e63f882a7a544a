// ReplaySource: plays a recording (docs/RECORDING.md) back as a FrameSource, `replay://<dir>`
// (docs/REPLAY.md).
//
//   recorder::ReplayOptions o;
//   o.mode = recorder::ReplayMode::kRealRate;   // or kFast (lockstep), kStep
//   auto src = recorder::ReplaySource::open("replay://flight-042", o);
//   Frame f;
//   for (;;) {
//     auto st = (*src)->read(f, 100ms);
//     if (!st) { log(st.error().message); continue; }   // a damaged frame: skipped, replay goes on
//     if (*st == ReadStatus::kEndOfStream) break;
//     if (*st == ReadStatus::kTimeout) continue;
//     const recorder::FrameRecord& rec = (*src)->current();   // poses, boom, stats of f's frame
//   }
//
// What comes out: for each recorded stereo frame, its left Frame and then its right Frame, exactly
// as recorded (image bytes, format, size, t_ns, clock, t_host_ns, sequence, camera, exposure).
// A camera whose recorded image is empty is not emitted. current() is the whole FrameRecord the
// last emitted Frame came from (metadata, poses, boom, stats, and the images asked for by
// ReplayOptions::parts), so a consumer can rebuild the recorded StereoFrame or re-augment the
// recorded scene. A raw image is moved, not copied, into the Frame that emits it: in current()
// the raw image of a Frame already emitted is empty (the right one is there until it is emitted).
//
// Modes:
//   kFast      as fast as the consumer reads (lockstep: read() never skips a frame);
//   kRealRate  each Frame is released when wall time since the anchor reaches
//              (t_ns - anchor t_ns) / rate; the anchor is the first frame emitted after open,
//              a seek, a loop or a pause. A consumer that falls behind gets the late frames at
//              once (none skipped) unless drop_late is set;
//   kStep      a stereo frame is released only for a step() (both its Frames for one step()).
// set_paused(true) holds any mode; step() then releases single stereo frames as in kStep.
//
// Damage: a frame whose row or blobs cannot be read makes read() return an Error naming the
// recording and the frame ("recorder::ReplaySource::read(): DIR/recording.sqlite: frame 12:
// ..."); that stereo frame is skipped (counted in damaged_frames() and, two Frames each, in
// frames_dropped()) and the next read() goes on with the following frame.
//
// Threads: read(), current() and the accessors of what was read belong to one thread; step(),
// set_paused(), seek_frame(), seek_time() and set_rate() may be called from any thread and wake a
// read() that waits.
//
// Read-ahead (ReplayOptions::read_ahead, on by default): a decode thread of the source's own,
// started by the first read(), reads and decodes the next stereo frames (with its own
// RecordingReader) into a small bounded queue while the consumer works on the last one, so that
// decoding overlaps augmenting. Nothing else changes: the gates (pause, step, real rate, drop_late)
// act in read() on the frames as they come out of the queue, a seek empties the queue (the next
// read() returns the sought frame), and the destructor stops and joins the thread (it never waits
// for a consumer that stopped reading).
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/frame.hpp"
#include "recorder/reader.hpp"
#include "recorder/store.hpp"

namespace augrig::recorder {

// Attached to every Frame a ReplaySource emits (Frame::attachment): the recorded stereo frame it
// came from, so a consumer downstream of queues and pairing still knows its recorded scene.
// `record` holds the metadata, poses, boom and statistics; its images are left empty.
// `raw_blobs` (index_of(CameraId)) are both cameras' raw images as the recording stores them
// (ReplayOptions::keep_raw_blobs): a Recorder given a FrameRecord whose raw Frames carry this
// attachment stores those bytes again as they are, without compressing (recorder.hpp, push()).
struct RecordedFrame final : FrameAttachment {
  std::size_t index = 0;  // in the recording
  int pass = 0;           // the loop pass (0: the first)
  FrameRecord record;
  std::array<StoredRawBlob, 2> raw_blobs;
  // Real rate, released on time: CLOCK_MONOTONIC when the stereo frame's first Frame was released,
  // the replayed mid-exposure on the host clock (latency runs from it, as from a camera's). 0 in
  // kFast and kStep, and while paused.
  TimestampNs released_host_ns = 0;

  std::optional<SourcePosition> position() const override { return SourcePosition{index, pass}; }
  TimestampNs due_host_ns() const override { return released_host_ns; }
  std::optional<RecordedPairing> recorded_pairing() const override {
    return RecordedPairing{record.raw.t_key_ns, record.raw.skew_ns, record.raw.pair_sequence};
  }
  const RecordedFrame* recorded() const override { return this; }
};

enum class ReplayMode : std::uint8_t { kFast, kRealRate, kStep };

struct ReplayOptions {
  ReplayMode mode = ReplayMode::kFast;
  // kRealRate: recorded time runs `rate` times as fast as wall time (2: twice as fast). > 0.
  double rate = 1.0;
  // Where playback, and every loop, begins: frame `start_frame`; or, when `start_t_ns` is set, the
  // first frame (in recording order) whose t_key_ns is at or after it; or, when `start_offset_ns`
  // is set, at or after the first frame's t_key_ns plus the offset.
  std::size_t start_frame = 0;
  std::optional<TimestampNs> start_t_ns;
  std::optional<std::int64_t> start_offset_ns;
  // How many times the range [start, last frame] plays; 0: forever.
  int passes = 1;
  // FrameParts (recorder/store.hpp) decoded into current(); the raw images are always decoded.
  // The recorded augmented images and masks are neither read nor decoded unless asked for here.
  unsigned parts = kPartRaw;
  // Keep each raw image's stored blob in the Frames' RecordedFrame (about 1.2 MB per 1280x960
  // Bayer stereo frame), so that recording the replayed frames copies them instead of compressing.
  bool keep_raw_blobs = true;
  // kRealRate: a stereo frame whose left Frame is due more than `late_tolerance` ago is skipped
  // and counted in frames_dropped() (as a live camera would lose it) instead of coming late.
  bool drop_late = false;
  std::chrono::nanoseconds late_tolerance = std::chrono::milliseconds(50);
  // Stereo frames a decode thread reads and decodes ahead of read() in kFast mode (decoded and
  // waiting, besides the one being decoded); while paced (kRealRate), stepped (kStep) or paused it
  // decodes only the next one, which is all such a replay can use. 0: no thread, read() reads and
  // decodes each stereo frame itself. Memory: about (read_ahead + 1) x 3.6 MB at 1280x960 Bayer
  // with keep_raw_blobs. A stereo frame read ahead and then passed over by a seek is not dropped
  // (it was never due) and is not counted anywhere.
  std::size_t read_ahead = 2;
};

class ReplaySource final : public FrameSource {
 public:
  // `uri_or_dir`: "replay://DIR", a recording folder, or its recording.sqlite. Fails when the
  // recording cannot be opened, the options are invalid, or the start is past the last frame.
  static Expected<std::unique_ptr<ReplaySource>> open(const std::string& uri_or_dir,
                                                      const ReplayOptions& options = {});
  ~ReplaySource() override;

  std::string uri() const override;  // "replay://DIR" as given (the .sqlite path when that was given)
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  // Frames not emitted: two per damaged stereo frame, and those drop_late skipped.
  std::uint64_t frames_dropped() const override;
  SourceCapabilities capabilities() const override { return {true, true, true, true}; }
  std::size_t pair_count() const override { return end_frame() - start_frame(); }  // one pass
  std::size_t range_start() const override { return start_frame(); }
  std::optional<TimestampNs> origin_t_ns() const override { return first_t_ns(); }
  Status set_range_end(std::size_t end) override { return set_end_frame(end); }

  // ---- Control (any thread) ----
  // Releases `n` more stereo frames in kStep mode or while paused.
  void step(std::size_t n = 1);
  void set_paused(bool paused);
  bool paused() const;
  // The next stereo frame read is frame `i` (a left Frame first), in the pass of the last one
  // emitted; the loop range is unchanged. An Error for a frame at or past the end (set_end_frame()).
  Status seek_frame(std::size_t i);
  // The next stereo frame read is the first (in recording order) with t_key_ns >= t_ns.
  Status seek_time(TimestampNs t_ns);
  // From the next stereo frame on: real rate at `rate` (> 0: kRealRate), or as fast as read (0:
  // kFast); kStep stays kStep. Real rate anchors afresh. An Error for a negative or non-finite rate.
  Status set_rate(double rate);
  // The rate in force: 0 for kFast and kStep.
  double rate() const;

  // ---- What was read (the reading thread) ----
  // The recorded stereo frame the last emitted Frame belongs to (empty before the first).
  const FrameRecord& current() const { return current_; }
  // Its index in the recording; nullopt before the first Frame.
  std::optional<std::size_t> current_index() const { return current_index_; }
  // The pass the last emitted Frame belongs to (0 for the first).
  int pass() const { return current_pass_; }
  std::uint64_t damaged_frames() const { return damaged_.load(); }
  // Stereo frames decoded ahead and waiting to be emitted (any thread; at most the depth above).
  std::size_t frames_read_ahead() const;
  // CPU time the read-ahead thread has spent reading and decoding (0 without read-ahead), ms.
  double read_ahead_cpu_ms() const { return static_cast<double>(read_ahead_cpu_us_.load()) * 1e-3; }

  // ---- The recording ----
  std::size_t frame_count() const { return t_key_ns_.size(); }
  // Every frame's t_key_ns (nullopt where even the frame's metadata could not be read).
  const std::vector<std::optional<TimestampNs>>& frame_times() const { return t_key_ns_; }
  std::size_t start_frame() const { return start_; }
  // Where playback (and every loop pass) ends: before frame `end`, clamped to frame_count(), so
  // that a part of a recording (frames [start, end)) plays exactly those frames whatever in it is
  // damaged or skipped downstream. Meant for before the first read(). An Error when `end` is not
  // after the start frame.
  Status set_end_frame(std::size_t end);
  std::size_t end_frame() const;
  // The recording's time origin: the left t_ns of its first frame whose metadata reads (whatever
  // the start); nullopt when none reads. A scripted boom's t = 0 (pipeline/boom_stage.hpp).
  std::optional<TimestampNs> first_t_ns() const { return first_t_ns_; }
  const RecordingReader& reader() const { return *reader_; }

 private:
  ReplaySource() = default;

  // A stereo frame read from the recording (or the error that stopped it), not yet emitted.
  struct Loaded {
    std::size_t index = 0;
    int pass = 0;
    FrameRecord record;
    std::array<StoredRawBlob, 2> blobs;
    std::optional<Error> error;
  };
  // Reads and decodes the next stereo frame (cursor_, pass_; loops) with `reader`, without mu_
  // held while decoding, and queues it in ready_; or marks the end (exhausted_). `lk` holds mu_.
  void load_next(std::unique_lock<std::mutex>& lk, const RecordingReader& reader);
  // The read-ahead thread: load_next() while the queue has room (depth()), until stopping_.
  void decode_loop();
  // Stereo frames the read-ahead thread keeps decoded (under mu_).
  std::size_t depth() const;

  std::string uri_;
  ReplayOptions options_;
  std::unique_ptr<RecordingReader> reader_;         // the reading thread's (and the accessors')
  std::unique_ptr<RecordingReader> decode_reader_;  // the read-ahead thread's own
  std::vector<std::optional<TimestampNs>> t_key_ns_;
  std::optional<TimestampNs> first_t_ns_;
  std::size_t start_ = 0;

  // Under mu_: control, the loader's position, and the stereo frames loaded but not yet emitted.
  mutable std::mutex mu_;
  std::condition_variable cv_;       // read() waits: a control call, a frame loaded, the end
  std::condition_variable room_cv_;  // the read-ahead thread waits: room, a seek, a mode change, the stop
  std::size_t end_ = 0;         // the range played ends before it (set_end_frame(); else frame_count())
  std::size_t cursor_ = 0;      // next stereo frame to load
  int pass_ = 0;                // the pass of the next stereo frame to load
  int emitted_pass_ = 0;        // the pass of the last stereo frame emitted (a seek goes on in it)
  std::uint64_t seek_gen_ = 0;  // bumped by every seek: what was being loaded before it is discarded
  bool exhausted_ = false;      // nothing more to load (the last pass has been loaded)
  bool stopping_ = false;       // the destructor: the read-ahead thread ends
  std::deque<Loaded> ready_;    // loaded, in order; the front is the next stereo frame to emit
  std::size_t permits_ = 0;     // step()s not yet used
  bool paused_ = false;
  bool anchored_ = false;  // kRealRate: the anchor below is valid
  std::chrono::steady_clock::time_point anchor_wall_;
  TimestampNs anchor_t_ns_ = 0;
  int anchor_pass_ = 0;         // the pass the anchor was taken in (a new pass anchors afresh)
  bool right_pending_ = false;  // current_'s right Frame is still to emit
  bool released_by_step_ = false;

  // The reading thread's: the read-ahead thread, started by the first read() (joined by the destructor).
  std::thread decoder_;

  // The reading thread's view.
  FrameRecord current_;
  std::optional<std::size_t> current_index_;
  int current_pass_ = 0;
  std::atomic<std::uint64_t> damaged_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<std::uint64_t> read_ahead_cpu_us_{0};
};

}  // namespace augrig::recorder
