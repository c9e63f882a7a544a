// LatestPerChannel: what the live view's encoder threads (the JPEG and the H.264 topics) wait on:
// the newest job per channel, taken channels in turn (the one after the channel taken last), so
// that every topic gets its turn and a job still waiting when its channel's next comes is replaced
// (the caller counts it as dropped). The pipeline's thread offers; one worker takes.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <utility>

namespace augrig::net {

template <typename Job>
class LatestPerChannel {
 public:
  // False when it replaced a job still waiting on `channel` (or after stop(): the job is not kept).
  bool offer(std::uint32_t channel, Job job) {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopped_) return false;
    const bool fresh = pending_.insert_or_assign(channel, std::move(job)).second;
    cv_.notify_one();
    return fresh;
  }

  // Waits for the next channel's job; nullopt once stop() was called.
  std::optional<std::pair<std::uint32_t, Job>> take() {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait(lock, [&] { return stopped_ || !pending_.empty(); });
    if (stopped_) return std::nullopt;
    auto it = pending_.upper_bound(last_);
    if (it == pending_.end()) it = pending_.begin();
    auto node = pending_.extract(it);
    last_ = node.key();
    return std::make_pair(node.key(), std::move(node.mapped()));
  }

  // Wakes the worker for good; jobs still waiting are dropped.
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      stopped_ = true;
      pending_.clear();
    }
    cv_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::uint32_t, Job> pending_;
  std::uint32_t last_ = 0;
  bool stopped_ = false;
};

}  // namespace augrig::net
