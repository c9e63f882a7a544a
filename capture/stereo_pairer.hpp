// StereoPairer: turns the interleaved frames of two cameras into stereo frames. Two frames pair
// when their mid-exposure timestamps (same clock domain) differ by at most a tolerance; a frame
// that can no longer find a partner is dropped and counted, never silently lost.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>

#include "core/frame.hpp"

namespace augrig {

struct PairerStats {
  std::uint64_t pairs = 0;
  std::uint64_t unpaired_left = 0;  // left frames dropped without a partner
  std::uint64_t unpaired_right = 0;
  std::int64_t max_abs_skew_ns = 0;
};

class StereoPairer {
 public:
  // `tolerance_ns`: largest |t_right - t_left| accepted; `max_pending`: frames kept per camera while
  // waiting for a partner (older ones are dropped and counted).
  explicit StereoPairer(std::int64_t tolerance_ns, std::size_t max_pending = 8)
      : tolerance_ns_(tolerance_ns), max_pending_(max_pending) {}

  // Adds a frame; returns a stereo frame when it completes a pair. Frames of a camera must come
  // in timestamp order; a frame older than the camera's previous one is rejected (counted unpaired).
  std::optional<StereoFrame> push(Frame frame);
  // Drops whatever is pending (end of stream), counting it.
  void flush();
  const PairerStats& stats() const { return stats_; }

 private:
  std::int64_t tolerance_ns_;
  std::size_t max_pending_;
  std::deque<Frame> pending_[2];
  std::optional<TimestampNs> last_t_[2];
  PairerStats stats_;
  std::uint64_t next_pair_sequence_ = 0;
};

}  // namespace augrig
