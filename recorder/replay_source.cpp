#include "recorder/replay_source.hpp"

#include <algorithm>
#include <cmath>

#include "core/clock.hpp"
#include "core/thread_name.hpp"

namespace augrig::recorder {

namespace {

using SteadyClock = std::chrono::steady_clock;
constexpr std::string_view kScheme = "replay://";

// "module::function(): rest" -> "rest", so that errors read as the replay source's own.
std::string strip_function(const std::string& m) {
  const auto p = m.find("(): ");
  if (p != std::string::npos && p < 64 && m.find(' ') > p) return m.substr(p + 4);
  return m;
}

// After a Frame was moved out of current(): everything but its image back in place, so that
// current() still holds the recorded frame's timing.
void copy_frame_facts(const Frame& from, Frame& to) {
  to.t_ns = from.t_ns;
  to.clock = from.clock;
  to.t_host_ns = from.t_host_ns;
  to.sequence = from.sequence;
  to.camera = from.camera;
  to.exposure_ns = from.exposure_ns;
  to.attachment = from.attachment;
}

int cameras_with_images(const FrameRecord& r) {
  return !r.raw.left.image.empty() + !r.raw.right.image.empty();
}

}  // namespace

ReplaySource::~ReplaySource() {
  {
    std::lock_guard lk(mu_);
    stopping_ = true;
  }
  room_cv_.notify_all();
  cv_.notify_all();
  if (decoder_.joinable()) decoder_.join();
}

Expected<std::unique_ptr<ReplaySource>> ReplaySource::open(const std::string& uri_or_dir,
                                                           const ReplayOptions& options) {
  const std::string where = "recorder::ReplaySource::open(): ";
  std::string path = uri_or_dir;
  if (path.rfind(kScheme, 0) == 0) path = path.substr(kScheme.size());
  if (path.empty())
    return make_error(where, "'", uri_or_dir, "': expected replay://DIR or a recording folder");
  if (!(options.rate > 0) || !std::isfinite(options.rate))
    return make_error(where, path, ": the rate must be a positive number, got ", options.rate);
  if (options.passes < 0)
    return make_error(where, path, ": passes must be >= 0 (0: forever), got ", options.passes);

  auto reader = RecordingReader::open(path);
  if (!reader) return make_error(where, strip_function(reader.error().message));

  std::unique_ptr<ReplaySource> s(new ReplaySource());
  s->uri_ = std::string(kScheme) + path;
  s->options_ = options;
  s->options_.parts |= kPartRaw;
  s->reader_ = std::move(*reader);
  const std::size_t n = s->reader_->frame_count();
  s->t_key_ns_.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    auto info = s->reader_->read_frame_info(i);
    s->t_key_ns_.push_back(info ? std::optional<TimestampNs>(info->raw.t_key_ns) : std::nullopt);
    if (info && !s->first_t_ns_) s->first_t_ns_ = info->raw.left.t_ns;
  }
  s->end_ = n;

  std::optional<TimestampNs> start_t = options.start_t_ns;
  if (options.start_offset_ns) {
    const auto first =
        std::find_if(s->t_key_ns_.begin(), s->t_key_ns_.end(), [](const auto& t) { return t.has_value(); });
    if (first == s->t_key_ns_.end())
      return make_error(where, s->reader_->path(), ": no frame has a readable time to seek from");
    start_t = **first + *options.start_offset_ns;
  }
  if (start_t) {
    const auto it = std::find_if(s->t_key_ns_.begin(), s->t_key_ns_.end(),
                                 [&](const auto& t) { return t && *t >= *start_t; });
    if (it == s->t_key_ns_.end()) {
      std::string last = "no frame has a readable time";
      for (auto r = s->t_key_ns_.rbegin(); r != s->t_key_ns_.rend(); ++r) {
        if (*r) {
          last = "the last frame is at t_ns " + std::to_string(**r);
          break;
        }
      }
      return make_error(where, s->reader_->path(), ": no frame at or after t_ns ", *start_t, " (", last, ")");
    }
    s->start_ = static_cast<std::size_t>(it - s->t_key_ns_.begin());
  } else {
    if (options.start_frame > 0 && options.start_frame >= n)
      return make_error(where, s->reader_->path(), ": start frame ", options.start_frame,
                        " is past the last frame (", n, " frames)");
    s->start_ = options.start_frame;
  }
  s->cursor_ = s->start_;
  if (options.read_ahead > 0) {
    // The read-ahead thread reads with a connection of its own (a RecordingReader is one thread's).
    auto second = RecordingReader::open(path);
    if (!second) return make_error(where, strip_function(second.error().message));
    s->decode_reader_ = std::move(*second);
  }
  return s;
}

std::size_t ReplaySource::depth() const {
  // A paced, stepped or paused replay uses one stereo frame at a time: only the next is decoded.
  return options_.mode == ReplayMode::kFast && !paused_ ? options_.read_ahead : 1;
}

Status ReplaySource::set_end_frame(std::size_t end) {
  if (end <= start_)
    return make_error("recorder::ReplaySource::set_end_frame(): ", reader_->path(), ": the end (frame ", end,
                      ") is not after the start (frame ", start_, ")");
  {
    std::lock_guard lk(mu_);
    end_ = std::min(end, t_key_ns_.size());
    if (cursor_ < end_) exhausted_ = false;
  }
  room_cv_.notify_all();
  return {};
}

std::size_t ReplaySource::end_frame() const {
  std::lock_guard lk(mu_);
  return end_;
}

void ReplaySource::load_next(std::unique_lock<std::mutex>& lk, const RecordingReader& reader) {
  if (cursor_ >= end_) {
    if ((options_.passes == 0 || pass_ + 1 < options_.passes) && start_ < end_) {
      cursor_ = start_;
      ++pass_;
    } else {
      exhausted_ = true;  // the last pass is loaded (or the recording is empty)
      cv_.notify_all();
      return;
    }
  }
  Loaded l;
  l.index = cursor_;
  l.pass = pass_;
  const std::uint64_t gen = seek_gen_;
  const unsigned parts = options_.parts;
  const bool keep_blobs = options_.keep_raw_blobs;
  lk.unlock();  // decoding takes a while
  auto rec = reader.read_frame(l.index, parts, keep_blobs ? &l.blobs : nullptr);
  lk.lock();
  if (gen != seek_gen_) return;  // a seek came in meanwhile: it moved cursor_, this frame is not wanted
  cursor_ = l.index + 1;
  if (rec) {
    if (cameras_with_images(*rec) == 0) return;  // nothing to emit (not written by the Recorder)
    l.record = std::move(*rec);
  } else {
    l.error = make_error("recorder::ReplaySource::read(): ", strip_function(rec.error().message),
                         "; frame skipped, replay goes on with frame ", l.index + 1);
  }
  ready_.push_back(std::move(l));
  cv_.notify_all();
}

void ReplaySource::decode_loop() {
  set_thread_name("augrig-replay");
  std::unique_lock lk(mu_);
  for (;;) {
    room_cv_.wait(lk, [&] { return stopping_ || (!exhausted_ && ready_.size() < depth()); });
    if (stopping_) return;
    const double cpu0 = thread_cpu_ms();
    load_next(lk, *decode_reader_);
    read_ahead_cpu_us_.fetch_add(static_cast<std::uint64_t>(std::max(0.0, thread_cpu_ms() - cpu0) * 1e3));
  }
}

std::string ReplaySource::uri() const {
  return uri_;
}

std::uint64_t ReplaySource::frames_dropped() const {
  return dropped_.load();
}

void ReplaySource::step(std::size_t n) {
  {
    std::lock_guard lk(mu_);
    permits_ += n;
  }
  cv_.notify_all();
}

void ReplaySource::set_paused(bool paused) {
  {
    std::lock_guard lk(mu_);
    if (paused_ && !paused) anchored_ = false;  // real rate resumes from the next frame, not from the past
    paused_ = paused;
  }
  cv_.notify_all();
  room_cv_.notify_all();  // the read-ahead depth follows the pause
}

Status ReplaySource::set_rate(double rate) {
  if (!(rate >= 0) || !std::isfinite(rate))
    return make_error("recorder::ReplaySource::set_rate(): expected a rate >= 0 (0: as fast as read), got ", rate);
  {
    std::lock_guard lk(mu_);
    if (options_.mode != ReplayMode::kStep) options_.mode = rate > 0 ? ReplayMode::kRealRate : ReplayMode::kFast;
    if (rate > 0) options_.rate = rate;
    anchored_ = false;
  }
  cv_.notify_all();
  room_cv_.notify_all();  // the read-ahead depth follows the mode
  return {};
}

double ReplaySource::rate() const {
  std::lock_guard lk(mu_);
  return options_.mode == ReplayMode::kRealRate ? options_.rate : 0.0;
}

std::size_t ReplaySource::frames_read_ahead() const {
  std::lock_guard lk(mu_);
  return ready_.size();
}

bool ReplaySource::paused() const {
  std::lock_guard lk(mu_);
  return paused_;
}

Status ReplaySource::seek_frame(std::size_t i) {
  if (i >= t_key_ns_.size()) {
    return make_error("recorder::ReplaySource::seek_frame(): ", reader_->path(), ": frame ", i,
                      " is past the last frame (", t_key_ns_.size(), " frames)");
  }
  {
    std::lock_guard lk(mu_);
    if (i >= end_)
      return make_error("recorder::ReplaySource::seek_frame(): ", reader_->path(), ": frame ", i,
                        " is past the end of the range played (frames ", start_, "..", end_ - 1, ")");
    cursor_ = i;
    pass_ = emitted_pass_;  // the read-ahead may have begun the next pass already
    ++seek_gen_;
    exhausted_ = false;
    ready_.clear();  // what was read ahead is passed over: the next stereo frame read is frame i
    right_pending_ = false;
    anchored_ = false;
  }
  cv_.notify_all();
  room_cv_.notify_all();
  return {};
}

Status ReplaySource::seek_time(TimestampNs t_ns) {
  const auto it =
      std::find_if(t_key_ns_.begin(), t_key_ns_.end(), [&](const auto& t) { return t && *t >= t_ns; });
  if (it == t_key_ns_.end())
    return make_error("recorder::ReplaySource::seek_time(): ", reader_->path(),
                      ": no frame at or after t_ns ", t_ns);
  return seek_frame(static_cast<std::size_t>(it - t_key_ns_.begin()));
}

Expected<ReadStatus> ReplaySource::read(Frame& out, std::chrono::nanoseconds timeout) {
  const auto start = SteadyClock::now();
  // Very long timeouts are waited in slices of a day (no overflow of the time point).
  const auto deadline = start + std::clamp<std::chrono::nanoseconds>(timeout, std::chrono::nanoseconds(0),
                                                                     std::chrono::hours(24));
  if (decode_reader_ && !decoder_.joinable()) decoder_ = std::thread([this] { decode_loop(); });
  std::unique_lock lk(mu_);

  // Waits until `tp` or the deadline, whichever comes first, or until a control call wakes it.
  // false: the deadline has passed (the caller returns kTimeout).
  auto wait = [&](SteadyClock::time_point tp) {
    if (SteadyClock::now() >= deadline) return false;
    cv_.wait_until(lk, std::min(tp, deadline));
    return true;
  };
  auto due = [&](TimestampNs t_ns) {
    const double dt = static_cast<double>(t_ns - anchor_t_ns_) / options_.rate;
    return anchor_wall_ + std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(dt)));
  };

  for (;;) {
    // 1. The right Frame of the stereo frame whose left Frame went out last.
    if (right_pending_) {
      const Frame& f = current_.raw.right;
      if (options_.mode == ReplayMode::kRealRate && !released_by_step_ && !paused_ && anchored_) {
        const auto when = due(f.t_ns);
        if (SteadyClock::now() < when) {
          if (!wait(when)) return ReadStatus::kTimeout;
          continue;
        }
      }
      right_pending_ = false;
      out = std::move(current_.raw.right);
      current_.raw.right.image = Image();  // moved out (a moved-from vector is not promised empty)
      copy_frame_facts(out, current_.raw.right);
      return ReadStatus::kFrame;
    }

    // 2. The next stereo frame: loaded by the read-ahead thread, or here. Loading is work, not
    // waiting: as without read-ahead, read() waits for it whatever its timeout (the read-ahead
    // thread is never idle while the queue is empty and frames remain).
    if (ready_.empty()) {
      if (exhausted_) return ReadStatus::kEndOfStream;
      if (decode_reader_)
        cv_.wait(lk);
      else
        load_next(lk, *reader_);
      continue;
    }
    Loaded& next = ready_.front();

    // 3. Gates: pause and step, then real-rate timing, both on the stereo frame's first Frame.
    const bool gated = options_.mode == ReplayMode::kStep || paused_;
    if (gated && permits_ == 0) {
      if (!wait(SteadyClock::time_point::max())) return ReadStatus::kTimeout;
      continue;
    }
    if (next.error) {
      if (gated) --permits_;
      damaged_.fetch_add(1);
      dropped_.fetch_add(2);
      Error e = std::move(*next.error);
      ready_.pop_front();
      room_cv_.notify_all();
      return e;
    }
    const Frame& first = next.record.raw.left.image.empty() ? next.record.raw.right : next.record.raw.left;
    if (!gated && options_.mode == ReplayMode::kRealRate) {
      if (!anchored_ || anchor_pass_ != next.pass) {  // also at the start of every loop pass
        anchored_ = true;
        anchor_wall_ = SteadyClock::now();
        anchor_t_ns_ = first.t_ns;
        anchor_pass_ = next.pass;
      }
      const auto when = due(first.t_ns);
      const auto now = SteadyClock::now();
      if (options_.drop_late && now - when > options_.late_tolerance) {
        dropped_.fetch_add(static_cast<std::uint64_t>(cameras_with_images(next.record)));
        ready_.pop_front();
        room_cv_.notify_all();
        continue;
      }
      if (now < when) {
        if (!wait(when)) return ReadStatus::kTimeout;
        continue;
      }
    }
    if (gated) {
      --permits_;
      anchored_ = false;  // after a step or a pause, real rate starts afresh
    }
    released_by_step_ = gated;

    // 4. Emit the first Frame; the right one follows on the next read().
    current_ = std::move(next.record);
    current_index_ = next.index;
    current_pass_ = next.pass;
    emitted_pass_ = next.pass;
    std::array<StoredRawBlob, 2> blobs = std::move(next.blobs);
    ready_.pop_front();
    room_cv_.notify_all();
    {
      // Both Frames carry the recorded frame's scene (without images) for consumers downstream.
      auto att = std::make_shared<RecordedFrame>();
      att->index = *current_index_;
      att->pass = current_pass_;
      if (options_.mode == ReplayMode::kRealRate && !gated) att->released_host_ns = monotonic_now_ns();
      FrameRecord& m = att->record;
      m.raw.t_key_ns = current_.raw.t_key_ns;
      m.raw.skew_ns = current_.raw.skew_ns;
      m.raw.pair_sequence = current_.raw.pair_sequence;
      m.augmented_box = current_.augmented_box;
      m.T_cam_receiver = current_.T_cam_receiver;
      m.T_body_receiver = current_.T_body_receiver;
      m.receiver_present = current_.receiver_present;
      m.sigma_pos_m = current_.sigma_pos_m;
      m.sigma_att_deg = current_.sigma_att_deg;
      m.boom = current_.boom;
      m.stats = current_.stats;
      att->raw_blobs = std::move(blobs);
      current_.raw.left.attachment = att;
      current_.raw.right.attachment = std::move(att);
    }
    const bool left = !current_.raw.left.image.empty();
    right_pending_ = left && !current_.raw.right.image.empty();
    Frame& emitted = left ? current_.raw.left : current_.raw.right;
    out = std::move(emitted);
    emitted.image = Image();
    copy_frame_facts(out, emitted);
    return ReadStatus::kFrame;
  }
}

}  // namespace augrig::recorder
