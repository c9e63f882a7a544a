#include "capture/stereo_source.hpp"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

#include "core/thread_name.hpp"

namespace augrig {
struct StereoSource::Impl {
  std::vector<std::unique_ptr<FrameSource>> sources;
  StereoSourceOptions options;
  StereoPairer pairer;

  std::vector<std::thread> threads;
  mutable std::mutex mutex;
  std::condition_variable changed;  // a frame was queued, a queue has room, a source ended
  std::vector<std::deque<Frame>> queues;
  std::vector<bool> ended;
  std::vector<SourceHealth> health;  // snapshots taken by each capture thread after its reads
  std::optional<Error> failure;
  std::vector<std::string> skipped_errors;  // skip_read_errors: not yet taken
  bool stopping = false;
  StereoSourceStats counts;
  std::deque<StereoFrame> pairs;  // paired, not yet returned (consumer side)
  bool flushed = false;

  explicit Impl(StereoPairer p) : pairer(std::move(p)) {}

  // One source's capture loop: read, stamp the camera, queue (or drop the oldest / wait).
  void capture(std::size_t i) {
    FrameSource& src = *sources[i];
    for (;;) {
      {
        std::lock_guard lock(mutex);
        if (stopping) return;
      }
      Frame frame;
      Expected<ReadStatus> r = src.read(frame, options.read_timeout);
      const SourceHealth h = src.health();
      std::unique_lock lock(mutex);
      health[i] = h;
      if (!r && options.skip_read_errors) {
        if (skipped_errors.size() < 100) skipped_errors.push_back(r.error().message);
        continue;
      }
      if (!r) {
        failure = make_error("StereoSource: ", src.uri(), ": ", r.error().message);
        ended[i] = true;
        changed.notify_all();
        return;
      }
      if (*r == ReadStatus::kEndOfStream) {
        ended[i] = true;
        changed.notify_all();
        return;
      }
      if (*r == ReadStatus::kTimeout) continue;
      if (sources.size() == 2) frame.camera = i == 0 ? CameraId::kLeft : CameraId::kRight;
      counts.frames[index_of(frame.camera)]++;
      std::deque<Frame>& q = queues[i];
      if (q.size() >= options.queue_frames) {
        if (options.lossless) {
          changed.wait(lock, [&] { return stopping || q.size() < options.queue_frames; });
          if (stopping) {  // kept (over the bound) so that the stop's pending count has it
            q.push_back(std::move(frame));
            return;
          }
        } else {
          // Live: the oldest frame goes, so what reaches the display is the newest.
          counts.queue_drops[index_of(q.front().camera)]++;
          counts.queue_drop_t.add(q.front().t_ns);
          q.pop_front();
        }
      }
      q.push_back(std::move(frame));
      changed.notify_all();
    }
  }
};

StereoSource::StereoSource(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

std::vector<std::string> StereoSource::take_errors() {
  std::lock_guard lock(impl_->mutex);
  std::vector<std::string> e = std::move(impl_->skipped_errors);
  impl_->skipped_errors.clear();
  return e;
}

StereoSource::~StereoSource() {
  stop();
}

Expected<std::unique_ptr<StereoSource>> StereoSource::create(
    std::vector<std::unique_ptr<FrameSource>> sources, const StereoSourceOptions& options) {
  if (sources.empty() || sources.size() > 2)
    return make_error(
        "StereoSource::create(): expected one source with both cameras or two (left, right), got ",
        sources.size());
  for (const auto& s : sources)
    if (!s) return make_error("StereoSource::create(): a source is missing");
  if (options.queue_frames == 0)
    return make_error("StereoSource::create(): queue_frames: expected at least 1");
  auto pairer = StereoPairer::create(options.pairing);
  if (!pairer) return pairer.error();
  auto impl = std::make_unique<Impl>(std::move(*pairer));
  impl->options = options;
  impl->sources = std::move(sources);
  const std::size_t n = impl->sources.size();
  impl->queues.resize(n);
  impl->ended.assign(n, false);
  impl->health.resize(n);
  for (std::size_t i = 0; i < n; ++i) impl->health[i] = impl->sources[i]->health();
  Impl* raw = impl.get();
  for (std::size_t i = 0; i < n; ++i)
    impl->threads.emplace_back([raw, i] {
      set_thread_name("augrig-cap" + std::to_string(i));
      raw->capture(i);
    });
  return std::unique_ptr<StereoSource>(new StereoSource(std::move(impl)));
}

void StereoSource::stop() {
  if (!impl_) return;
  {
    std::lock_guard lock(impl_->mutex);
    impl_->stopping = true;
  }
  impl_->changed.notify_all();
  for (std::thread& t : impl_->threads)
    if (t.joinable()) t.join();
}

bool StereoSource::lossless() const {
  return impl_->options.lossless;
}

Expected<ReadStatus> StereoSource::read(StereoFrame& out, std::chrono::nanoseconds timeout) {
  Impl& m = *impl_;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    if (!m.pairs.empty()) {
      out = std::move(m.pairs.front());
      m.pairs.pop_front();
      return ReadStatus::kFrame;
    }
    std::vector<Frame> batch;
    bool all_ended = false;
    {
      std::unique_lock lock(m.mutex);
      // Frames go to the pairer oldest arrival first. Live, every queued frame goes at once: the
      // pairer takes the cameras' frames in any interleaving and pairs as soon as both partners are
      // in. (Holding a head until the other source had a frame queued too held the second frame of
      // every pair for the other camera's next frame, a whole frame period: 57 ms p50 at 20 fps.)
      // Lossless sources run lockstep: a head waits until every other source has a frame waiting
      // too (or has ended), so the pairer sees them interleaved as in real time.
      auto may_release = [&](std::size_t i) {
        if (!m.options.lossless) return true;
        for (std::size_t j = 0; j < m.queues.size(); ++j)
          if (j != i && m.queues[j].empty() && !m.ended[j]) return false;
        return true;
      };
      auto oldest = [&]() -> std::optional<std::size_t> {
        std::optional<std::size_t> pick;
        for (std::size_t i = 0; i < m.queues.size(); ++i)
          if (!m.queues[i].empty() &&
              (!pick || m.queues[i].front().t_host_ns < m.queues[*pick].front().t_host_ns))
            pick = i;
        return pick;
      };
      for (;;) {
        if (m.failure) return *m.failure;
        const auto now = std::chrono::steady_clock::now();
        const std::optional<std::size_t> pick = oldest();
        if (pick && may_release(*pick)) {
          batch.push_back(std::move(m.queues[*pick].front()));
          m.queues[*pick].pop_front();
          continue;
        }
        all_ended = !pick && std::all_of(m.ended.begin(), m.ended.end(), [](bool e) { return e; });
        if (!batch.empty() || all_ended) break;
        if (now >= deadline) return ReadStatus::kTimeout;
        m.changed.wait_until(lock, deadline);
      }
    }
    m.changed.notify_all();  // lossless capture threads wait for room
    for (Frame& f : batch)
      if (auto p = m.pairer.push(std::move(f))) m.pairs.push_back(std::move(*p));
    if (all_ended && m.pairs.empty()) {
      if (!m.flushed) {
        m.pairer.flush();
        m.flushed = true;
      }
      return ReadStatus::kEndOfStream;
    }
  }
}

std::string StereoSource::uri() const {
  if (impl_->sources.size() == 1) return impl_->sources[0]->uri();
  return "stereo://{" + impl_->sources[0]->uri() + "}{" + impl_->sources[1]->uri() + "}";
}

StereoSourceStats StereoSource::stats() const {
  StereoSourceStats s;
  {
    std::lock_guard lock(impl_->mutex);
    s = impl_->counts;
    for (const auto& q : impl_->queues)
      for (const Frame& f : q) s.pending.add(f.t_ns);
    for (const SourceHealth& h : impl_->health) {
      s.camera_drops += h.camera_drops;
      s.transport_drops += h.transport_drops;
    }
  }
  // The pairer belongs to the consumer thread, which is the one asking.
  s.pairing = impl_->pairer.stats();
  s.pending.add(impl_->pairer.pending_t());
  for (const StereoFrame& p : impl_->pairs) s.pending.add(p.left.t_ns), s.pending.add(p.right.t_ns);
  for (CameraId c : {CameraId::kLeft, CameraId::kRight})
    if (const ClockOffsetEstimator* e = impl_->pairer.clock_estimator(c); e && e->has_estimate())
      s.clocks.push_back(e->log(c));
  return s;
}

std::vector<SourceHealth> StereoSource::health() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->health;
}

const std::vector<std::unique_ptr<FrameSource>>& StereoSource::sources() const {
  return impl_->sources;
}

}  // namespace augrig
