// StereoPairer: turns the interleaved frames of two cameras into stereo frames, in one of two modes:
//   kTimestamp  two frames pair when their mid-exposure timestamps differ by at most a tolerance.
//               Timestamps are compared only within one clock domain: frames stamped by a camera's
//               own clock (ClockDomain::kDevice) pair on host monotonic time when clock offset
//               estimation is on (capture/clock_offset.hpp), and a frame whose domain cannot be
//               compared is refused and counted, never compared silently.
//   kTriggerId  hardware-triggered cameras: two frames pair when their trigger ids are equal (left:
//               Frame::sequence; right: Frame::sequence + an offset, configured or learned from the
//               first frames that pair by timestamp, and learned again after a camera restarts).
// Every pair's skew (right - left) is recorded in the StereoFrame and in PairerStats::skew; every
// frame that finds no partner is dropped and counted with its reason, and no frame waits forever
// (max_pending, max_age_ns). docs/PAIRING.md describes both modes and what is counted.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "capture/clock_offset.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"

namespace augrig {

// kAdjacent: one source delivers each stereo frame as its left Frame and then its right one (a
// recording played back): they pair as delivered, whatever their times (a loop or a seek goes back).
enum class PairingMode : std::uint8_t { kTimestamp, kTriggerId, kAdjacent };
constexpr std::string_view to_string(PairingMode m) {
  return m == PairingMode::kTimestamp   ? "timestamp"
         : m == PairingMode::kTriggerId ? "trigger_id"
                                        : "adjacent";
}

// Why a frame was dropped without a partner.
enum class UnpairedReason : std::uint8_t {
  kOutOfOrder,     // timestamp mode: not later than its camera's previous frame (or a duplicate)
  kClockMismatch,  // its clock domain cannot be compared with the pairing domain
  kBadTime,        // the clock offset estimator refused its (device, host) times
  kNoPartner,      // the other camera has moved past it: its partner was lost
  kMaxPending,     // its camera's queue was full (max_pending)
  kMaxAge,         // it waited longer than max_age_ns of host time
  kRestart,        // trigger mode: pending when its camera's sequence restarted
  kSkewCheck,      // trigger mode: ids matched but the timestamps differ by more than the tolerance
  kFlushed,        // pending at flush()
};
inline constexpr std::size_t kUnpairedReasonCount = 9;
std::string_view to_string(UnpairedReason r);

// The distribution of the pairs' skew (right - left, ns): moments, the largest |skew| and a
// histogram of |skew| whose bins grow by 2^(1/8) (9 %) from 100 ns to 49 s; quantiles are read
// off the histogram.
struct SkewStats {
  static constexpr std::size_t kBins = 232;
  std::uint64_t count = 0;
  double sum_ns = 0.0;
  double sum_sq_ns2 = 0.0;
  std::int64_t max_abs_ns = 0;
  std::array<std::uint64_t, kBins> abs_histogram{};

  void add(std::int64_t skew_ns);
  double mean_ns() const { return count ? sum_ns / static_cast<double>(count) : 0.0; }
  double rms_ns() const;
  // The q-quantile (0..1) of |skew|, rounded up to its bin's upper edge (at most 9 % high) and
  // capped at max_abs_ns; 0 without pairs.
  std::int64_t abs_quantile_ns(double q) const;
  std::int64_t p50_abs_ns() const { return abs_quantile_ns(0.5); }
  std::int64_t p99_abs_ns() const { return abs_quantile_ns(0.99); }
  // Bin k holds |skew| in (upper_edge_ns(k-1), upper_edge_ns(k)]; bin 0 holds [0, 100].
  static std::int64_t upper_edge_ns(std::size_t bin);
  static std::size_t bin_of(std::int64_t abs_skew_ns);
};

struct PairerStats {
  std::uint64_t pairs = 0;
  std::uint64_t unpaired_left = 0;  // left frames dropped without a partner (all reasons)
  std::uint64_t unpaired_right = 0;
  std::int64_t max_abs_skew_ns = 0;  // = skew.max_abs_ns
  SkewStats skew;                    // every pair whose skew is known
  // Trigger mode with timestamps that cannot be compared: paired by id, skew_ns = 0, not in `skew`.
  std::uint64_t pairs_without_skew = 0;
  // Timestamp mode on host time through clock_offsets: pairs whose |skew| exceeded tolerance_ns
  // but not the tolerance widened by the two clock estimates' uncertainty (in `skew` too).
  std::uint64_t pairs_within_uncertainty = 0;
  std::uint64_t frames_left = 0;  // pushed; frames = 2 pairs + unpaired + still pending
  std::uint64_t frames_right = 0;
  // Unpaired frames of both cameras by reason (index: UnpairedReason); sums to unpaired_left +
  // unpaired_right.
  std::array<std::uint64_t, kUnpairedReasonCount> unpaired_by_reason{};
  // The unpaired frames' t_ns (both cameras) in two parts (unpaired_t() joins them). First the
  // frames that waited in vain for a partner (no partner, max pending, max age) before the first
  // pair: cameras start streaming at different moments (a free-running camera's first frame comes
  // when its acquisition starts, in no step with the other's), so one camera's first frames may
  // have no partner to wait for. The drop ledger shows them on a row of their own. A camera that
  // never delivers leaves all its partner's frames here, and no pair.
  TimeSpan unpaired_at_start;
  TimeSpan unpaired_after_start;              // the other unpaired frames
  std::uint64_t sequence_restarts = 0;        // trigger mode: a camera's sequence went backwards
  std::uint64_t trigger_offsets_learned = 0;  // trigger mode: times the id offset was (re)learned
  // What was refused or restarted and why, "StereoPairer::push(): ..." (at most max_messages).
  std::vector<std::string> messages;

  std::uint64_t unpaired(UnpairedReason r) const { return unpaired_by_reason[static_cast<std::size_t>(r)]; }
  // Every unpaired frame's t_ns (both cameras): the two parts together.
  TimeSpan unpaired_t() const {
    TimeSpan all = unpaired_at_start;
    all.add(unpaired_after_start);
    return all;
  }
};

struct StereoPairerConfig {
  PairingMode mode = PairingMode::kTimestamp;
  // Timestamp mode: the largest |t_right - t_left| that pairs (keep it below half the frame period).
  // Compared on host time through clock_offsets, the tolerance grows by the sum of the two
  // estimates' uncertainty_ns (a pair is refused only when the clocks can tell that its skew is
  // too large), up to a quarter of the shorter frame interval.
  // Trigger mode: the id offset is learned from the first frames pairing by timestamp within it,
  // and an id pair whose timestamps (when comparable) differ by more is refused; 0: neither (then
  // trigger_id_offset must be set).
  std::int64_t tolerance_ns = 0;
  std::size_t max_pending = 8;  // frames kept per camera while waiting (the oldest is dropped)
  // A pending frame is dropped once a frame arrives whose t_host_ns is later than its own by more
  // than this (one camera stalls: its partner's frames do not wait forever). 0: no age limit;
  // frames without t_host_ns are not aged.
  std::int64_t max_age_ns = 1'000'000'000;
  // Both cameras stamp ClockDomain::kDevice: true when that is one clock (PTP-synchronised GigE
  // cameras, a simulation), so the stamps compare directly; false when each camera has its own,
  // and then such frames pair only on host time through clock_offsets.
  bool device_clock_shared = true;
  // Set: each camera gets a ClockOffsetEstimator fed with every kDevice frame's (t_ns, t_host_ns),
  // and such frames are compared on their host monotonic time (a frame without t_host_ns is refused).
  std::optional<ClockOffsetConfig> clock_offsets;
  // Trigger mode: the left id is left.sequence, the right id right.sequence + trigger_id_offset.
  // Unset: learned from timestamps (tolerance_ns), and learned again after a camera restarts.
  std::optional<std::int64_t> trigger_id_offset;
  std::size_t max_messages = 100;
};

class StereoPairer {
 public:
  // Timestamp mode, the other settings as in StereoPairerConfig: `tolerance_ns`: largest
  // |t_right - t_left| accepted; `max_pending`: frames kept per camera while waiting for a partner
  // (older ones are dropped and counted).
  explicit StereoPairer(std::int64_t tolerance_ns, std::size_t max_pending = 8);
  // Checks the configuration: "StereoPairer::create(): tolerance_ns: ..." on bad values.
  static Expected<StereoPairer> create(const StereoPairerConfig& config);

  // Adds a frame; returns a stereo frame when it completes a pair. Each camera's frames must come
  // in order (timestamps increasing in timestamp mode, sequences in trigger mode; a sequence going
  // back in trigger mode is a restart of that camera). The two cameras may interleave in any way
  // as long as a frame's partner arrives within max_pending frames and max_age_ns.
  // In timestamp mode (and trigger mode with comparable clocks) skew_ns and t_key_ns are in the
  // pairing domain: host monotonic for frames converted through clock_offsets; the frames' own
  // t_ns and clock are left as the source stamped them.
  std::optional<StereoFrame> push(Frame frame);
  // Drops whatever is pending (end of stream), counting it.
  void flush();

  const PairerStats& stats() const { return stats_; }
  const StereoPairerConfig& config() const { return config_; }
  // The clock domain timestamps are compared in; set by the first frame that needed it.
  std::optional<ClockDomain> pairing_clock() const { return pairing_clock_; }
  // Trigger mode: right id = right.sequence + this; unset until learned.
  std::optional<std::int64_t> trigger_id_offset() const { return id_offset_; }
  // The camera's clock offset estimator; nullptr without clock_offsets.
  const ClockOffsetEstimator* clock_estimator(CameraId camera) const;
  std::size_t pending(CameraId camera) const { return pending_[index_of(camera)].size(); }
  // The frames waiting for a partner, both cameras (for a ledger at a stop without flush()).
  TimeSpan pending_t() const;

 private:
  struct Pending {
    Frame frame;
    TimestampNs key_ns;     // the time pairs are compared on
    ClockDomain key_clock;  // its domain
  };
  explicit StereoPairer(const StereoPairerConfig& config);
  void drop(const Frame& frame, UnpairedReason reason);
  template <class It>
  void drop_all(It begin, It end, UnpairedReason reason) {
    for (; begin != end; ++begin) drop(begin->frame, reason);
  }
  void note(const Frame& frame, const std::string& what);
  // Whether a time in `clock` can be compared with the other camera's; sets the pairing domain.
  bool comparable_domain(ClockDomain clock, std::string& why);
  bool comparable(const Pending& a, const Pending& b) const;
  std::int64_t id_of(int cam, std::uint64_t sequence) const;  // the trigger id
  void drop_aged(TimestampNs host_now_ns);
  StereoFrame make_pair(Pending mine, Pending theirs);
  std::optional<StereoFrame> push_timestamp(Pending p);
  // Timestamp mode: the tolerance for this frame (tolerance_ns, widened on estimated host time).
  std::int64_t timestamp_tolerance() const;
  std::optional<StereoFrame> push_trigger(Pending p);
  std::optional<StereoFrame> push_adjacent(Pending p);
  std::optional<StereoFrame> learn_trigger_offset(Pending p);
  void enqueue(Pending p);

  StereoPairerConfig config_;
  std::deque<Pending> pending_[2];
  std::optional<TimestampNs> last_key_[2];
  std::int64_t interval_ns_[2] = {0, 0};  // each camera's latest frame interval (pairing time)
  std::optional<std::uint64_t> last_sequence_[2];
  std::optional<ClockOffsetEstimator> clock_[2];
  std::optional<ClockDomain> pairing_clock_;
  std::optional<std::int64_t> id_offset_;
  TimestampNs newest_host_ns_ = 0;
  PairerStats stats_;
  std::uint64_t next_pair_sequence_ = 0;
};

}  // namespace augrig
