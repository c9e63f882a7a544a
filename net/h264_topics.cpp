// H264Topics (h264_topics.hpp): the worker's loop and the coding of one frame.
#include "net/h264_topics.hpp"

#include <chrono>

#include "core/thread_name.hpp"
#include "core/thread_priority.hpp"
#include "ros2/messages.hpp"

namespace augrig::net {

H264Topics::H264Topics(const H264Options& options, Deliver deliver)
    : options_(options), deliver_(std::move(deliver)), thread_([this] { loop(); }) {}

H264Topics::~H264Topics() {
  stop();
}

void H264Topics::stop() {
  jobs_.stop();
  if (thread_.joinable()) thread_.join();
}

void H264Topics::offer(std::uint32_t channel, TimestampNs t_ns, const char* frame_id, Image image) {
  if (jobs_.offer(channel, Job{t_ns, frame_id, std::move(image)})) return;
  std::lock_guard<std::mutex> lock(mu_);
  ++stats_.dropped;
}

void H264Topics::request_keyframe(std::uint32_t channel) {
  std::lock_guard<std::mutex> lock(mu_);
  want_key_.insert(channel);
}

H264TopicStats H264Topics::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

Expected<H264AccessUnit> H264Topics::code(std::uint32_t channel, const Job& job, bool keyframe) {
  auto& enc = encoders_[channel];
  // A channel's first frame, or a new size (a source that changed): a new stream, IDR first.
  if (!enc || enc->width() != job.image.width() || enc->height() != job.image.height()) {
    auto made = H264Encoder::create(job.image.width(), job.image.height(), options_);
    if (!made) return made.error();
    enc = std::move(*made);
  }
  return enc->encode(job.image.cview(), job.t_ns, keyframe);
}

void H264Topics::loop() {
  set_thread_name("augrig-h264");
  lower_thread_priority(10);  // x264 gives way to the pipeline: a frame it cannot take in time is dropped
  while (auto next = jobs_.take()) {
    const auto& [channel, job] = *next;
    bool keyframe = false;
    {
      std::lock_guard<std::mutex> lock(mu_);
      keyframe = want_key_.erase(channel) > 0;
    }
    const auto t0 = std::chrono::steady_clock::now();
    auto unit = code(channel, job, keyframe);
    SharedBytes message;
    if (unit) message = share_bytes(ros2::compressed_video(job.t_ns, job.frame_id, "h264", unit->data));
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (message) deliver_(channel, job.t_ns, message, unit->keyframe);
    std::lock_guard<std::mutex> lock(mu_);
    stats_.encode_ms += ms;
    if (!unit) {
      ++stats_.failed;
      want_key_.insert(channel);  // whatever comes next starts clean
      continue;
    }
    ++stats_.encoded;
    stats_.keyframes += unit->keyframe ? 1 : 0;
    stats_.bytes += unit->data.size();
  }
}

}  // namespace augrig::net
