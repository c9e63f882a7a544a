#include "capture/stereo_pairer.hpp"

#include <cstdlib>

namespace augrig {

std::optional<StereoFrame> StereoPairer::push(Frame frame) {
  const int me = index_of(frame.camera), other = 1 - me;
  std::uint64_t& my_unpaired = me == 0 ? stats_.unpaired_left : stats_.unpaired_right;
  std::uint64_t& other_unpaired = me == 0 ? stats_.unpaired_right : stats_.unpaired_left;
  if (last_t_[me] && frame.t_ns <= *last_t_[me]) {
    ++my_unpaired;  // out of order or duplicate: cannot be paired reliably
    return std::nullopt;
  }
  last_t_[me] = frame.t_ns;

  // Partners older than this frame by more than the tolerance will never pair: timestamps only grow.
  auto& theirs = pending_[other];
  while (!theirs.empty() && theirs.front().t_ns < frame.t_ns - tolerance_ns_) {
    theirs.pop_front();
    ++other_unpaired;
  }
  if (!theirs.empty() && std::llabs(theirs.front().t_ns - frame.t_ns) <= tolerance_ns_) {
    StereoFrame sf;
    Frame partner = std::move(theirs.front());
    theirs.pop_front();
    sf.left = me == 0 ? std::move(frame) : std::move(partner);
    sf.right = me == 0 ? std::move(partner) : std::move(frame);
    sf.skew_ns = sf.right.t_ns - sf.left.t_ns;
    sf.t_key_ns = sf.left.t_ns + sf.skew_ns / 2;
    sf.pair_sequence = next_pair_sequence_++;
    ++stats_.pairs;
    stats_.max_abs_skew_ns = std::max<std::int64_t>(stats_.max_abs_skew_ns, std::llabs(sf.skew_ns));
    return sf;
  }
  auto& mine = pending_[me];
  mine.push_back(std::move(frame));
  if (mine.size() > max_pending_) {
    mine.pop_front();
    ++my_unpaired;
  }
  return std::nullopt;
}

void StereoPairer::flush() {
  stats_.unpaired_left += pending_[0].size();
  stats_.unpaired_right += pending_[1].size();
  pending_[0].clear();
  pending_[1].clear();
}

}  // namespace augrig
