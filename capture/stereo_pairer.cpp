#include "capture/stereo_pairer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace augrig {

namespace {

// Upper edges of the |skew| histogram bins: 100 ns * 2^(k/8).
const std::array<std::int64_t, SkewStats::kBins>& skew_bin_edges() {
  static const std::array<std::int64_t, SkewStats::kBins> edges = [] {
    std::array<std::int64_t, SkewStats::kBins> e{};
    for (std::size_t k = 0; k < e.size(); ++k)
      e[k] = std::llround(100.0 * std::exp2(static_cast<double>(k) / 8.0));
    return e;
  }();
  return edges;
}

std::string describe(const Frame& f) {
  return make_error(to_string(f.camera), " frame ", f.sequence, " (t_ns ", f.t_ns, " ", to_string(f.clock),
                    ")")
      .message;
}

}  // namespace

std::string_view to_string(UnpairedReason r) {
  switch (r) {
    case UnpairedReason::kOutOfOrder:
      return "out_of_order";
    case UnpairedReason::kClockMismatch:
      return "clock_mismatch";
    case UnpairedReason::kBadTime:
      return "bad_time";
    case UnpairedReason::kNoPartner:
      return "no_partner";
    case UnpairedReason::kMaxPending:
      return "max_pending";
    case UnpairedReason::kMaxAge:
      return "max_age";
    case UnpairedReason::kRestart:
      return "restart";
    case UnpairedReason::kSkewCheck:
      return "skew_check";
    case UnpairedReason::kFlushed:
      return "flushed";
  }
  return "?";
}

// ---- SkewStats ----------------------------------------------------------------------------------

std::int64_t SkewStats::upper_edge_ns(std::size_t bin) {
  return skew_bin_edges()[std::min(bin, kBins - 1)];
}

std::size_t SkewStats::bin_of(std::int64_t abs_skew_ns) {
  const auto& e = skew_bin_edges();
  const auto it = std::lower_bound(e.begin(), e.end(), abs_skew_ns);
  return it == e.end() ? kBins - 1 : static_cast<std::size_t>(it - e.begin());
}

void SkewStats::add(std::int64_t skew_ns) {
  const std::int64_t a = skew_ns < 0 ? -skew_ns : skew_ns;
  ++count;
  sum_ns += static_cast<double>(skew_ns);
  sum_sq_ns2 += static_cast<double>(skew_ns) * static_cast<double>(skew_ns);
  max_abs_ns = std::max(max_abs_ns, a);
  ++abs_histogram[bin_of(a)];
}

double SkewStats::rms_ns() const {
  return count ? std::sqrt(sum_sq_ns2 / static_cast<double>(count)) : 0.0;
}

std::int64_t SkewStats::abs_quantile_ns(double q) const {
  if (count == 0) return 0;
  // The smallest value with at least ceil(q count) samples at or below it.
  const auto rank = static_cast<std::uint64_t>(
      std::clamp(std::ceil(q * static_cast<double>(count)), 1.0, static_cast<double>(count)));
  std::uint64_t seen = 0;
  for (std::size_t k = 0; k < kBins; ++k) {
    seen += abs_histogram[k];
    if (seen >= rank) return std::min(upper_edge_ns(k), max_abs_ns);
  }
  return max_abs_ns;
}

// ---- StereoPairer -------------------------------------------------------------------------------

StereoPairer::StereoPairer(std::int64_t tolerance_ns, std::size_t max_pending)
    : StereoPairer([&] {
        StereoPairerConfig c;
        c.tolerance_ns = tolerance_ns;
        c.max_pending = max_pending;
        return c;
      }()) {}

StereoPairer::StereoPairer(const StereoPairerConfig& config) : config_(config) {
  if (config_.clock_offsets)
    for (auto& c : clock_) c = ClockOffsetEstimator::create(*config_.clock_offsets).value();
  id_offset_ = config_.trigger_id_offset;
}

Expected<StereoPairer> StereoPairer::create(const StereoPairerConfig& c) {
  const char* where = "StereoPairer::create(): ";
  if (c.tolerance_ns < 0) return make_error(where, "tolerance_ns: expected >= 0, got ", c.tolerance_ns);
  if (c.max_pending < 1) return make_error(where, "max_pending: expected >= 1, got ", c.max_pending);
  if (c.max_age_ns < 0)
    return make_error(where, "max_age_ns: expected >= 0 (0: no limit), got ", c.max_age_ns);
  if (c.mode == PairingMode::kTriggerId && !c.trigger_id_offset && c.tolerance_ns == 0)
    return make_error(
        where,
        "trigger_id mode: expected trigger_id_offset, or tolerance_ns > 0 to learn it from timestamps");
  if (c.clock_offsets)
    if (Status s = ClockOffsetEstimator::validate(*c.clock_offsets); !s)
      return make_error(where, "clock_offsets: ", s.error().message);
  return StereoPairer(c);
}

const ClockOffsetEstimator* StereoPairer::clock_estimator(CameraId camera) const {
  const auto& c = clock_[index_of(camera)];
  return c ? &*c : nullptr;
}

void StereoPairer::drop(const Frame& frame, UnpairedReason reason) {
  (frame.camera == CameraId::kLeft ? stats_.unpaired_left : stats_.unpaired_right) += 1;
  stats_.unpaired_by_reason[static_cast<std::size_t>(reason)] += 1;
  const bool waited = reason == UnpairedReason::kNoPartner || reason == UnpairedReason::kMaxPending ||
                      reason == UnpairedReason::kMaxAge;
  (waited && stats_.pairs == 0 ? stats_.unpaired_at_start : stats_.unpaired_after_start).add(frame.t_ns);
}

TimeSpan StereoPairer::pending_t() const {
  TimeSpan s;
  for (const auto& q : pending_)
    for (const Pending& p : q) s.add(p.frame.t_ns);
  return s;
}

void StereoPairer::note(const Frame& frame, const std::string& what) {
  if (stats_.messages.size() < config_.max_messages)
    stats_.messages.push_back("StereoPairer::push(): " + describe(frame) + ": " + what);
}

bool StereoPairer::comparable_domain(ClockDomain clock, std::string& why) {
  if (clock == ClockDomain::kUnknown) {
    why = "clock domain unknown: the source must say which clock stamped its frames";
    return false;
  }
  if (clock == ClockDomain::kDevice && !config_.device_clock_shared) {
    why =
        "each camera has its own device clock (device_clock_shared = false): "
        "turn on clock_offsets to pair on host time";
    return false;
  }
  if (pairing_clock_ && *pairing_clock_ != clock) {
    why = make_error("clock domain ", to_string(clock), " cannot be compared with the pairing domain ",
                     to_string(*pairing_clock_),
                     " (set by the first frame): stamp both cameras in one domain, or turn on clock_offsets")
              .message;
    return false;
  }
  pairing_clock_ = clock;
  return true;
}

bool StereoPairer::comparable(const Pending& a, const Pending& b) const {
  return a.key_clock == b.key_clock && a.key_clock != ClockDomain::kUnknown &&
         (a.key_clock != ClockDomain::kDevice || config_.device_clock_shared);
}

std::int64_t StereoPairer::id_of(int cam, std::uint64_t sequence) const {
  const auto seq = static_cast<std::int64_t>(sequence);
  return cam == 0 ? seq : seq + id_offset_.value_or(0);
}

void StereoPairer::drop_aged(TimestampNs host_now_ns) {
  if (config_.max_age_ns <= 0 || host_now_ns <= 0) return;
  for (int cam = 0; cam < 2; ++cam) {
    auto& q = pending_[cam];
    // stable_partition, not remove_if: the dropped frames are still read (their timestamps).
    const auto old = std::stable_partition(q.begin(), q.end(), [&](const Pending& p) {
      return !(p.frame.t_host_ns > 0 && host_now_ns - p.frame.t_host_ns > config_.max_age_ns);
    });
    drop_all(old, q.end(), UnpairedReason::kMaxAge);
    q.erase(old, q.end());
  }
}

void StereoPairer::enqueue(Pending p) {
  const int me = index_of(p.frame.camera);
  pending_[me].push_back(std::move(p));
  if (pending_[me].size() > config_.max_pending) {
    drop(pending_[me].front().frame, UnpairedReason::kMaxPending);
    pending_[me].pop_front();
  }
}

StereoFrame StereoPairer::make_pair(Pending mine, Pending theirs) {
  const bool left_is_mine = mine.frame.camera == CameraId::kLeft;
  Pending& l = left_is_mine ? mine : theirs;
  Pending& r = left_is_mine ? theirs : mine;
  StereoFrame sf;
  if (comparable(l, r)) {
    sf.skew_ns = r.key_ns - l.key_ns;
    sf.t_key_ns = l.key_ns + sf.skew_ns / 2;
    stats_.skew.add(sf.skew_ns);
    stats_.max_abs_skew_ns = stats_.skew.max_abs_ns;
  } else {
    sf.skew_ns = 0;  // trigger mode across clocks: the ids say they belong together, the times cannot
    sf.t_key_ns = l.key_ns;
    ++stats_.pairs_without_skew;
  }
  sf.left = std::move(l.frame);
  sf.right = std::move(r.frame);
  sf.pair_sequence = next_pair_sequence_++;
  ++stats_.pairs;
  return sf;
}

std::optional<StereoFrame> StereoPairer::push(Frame frame) {
  const int me = index_of(frame.camera);
  ++(me == 0 ? stats_.frames_left : stats_.frames_right);
  if (frame.t_host_ns > 0) newest_host_ns_ = std::max(newest_host_ns_, frame.t_host_ns);
  // Adjacent frames pair as delivered: a recording's host times say nothing about waiting.
  if (config_.mode != PairingMode::kAdjacent) drop_aged(newest_host_ns_);

  Pending p{std::move(frame), 0, ClockDomain::kUnknown};
  p.key_ns = p.frame.t_ns;
  p.key_clock = p.frame.clock;
  if (p.frame.clock == ClockDomain::kDevice && clock_[me]) {
    // Device stamps become host monotonic times through this camera's own offset estimate.
    ClockOffsetEstimator& est = *clock_[me];
    const Expected<ClockSampleResult> r = est.add(p.frame.t_ns, p.frame.t_host_ns);
    if (!r) {
      note(p.frame, r.error().message);
      drop(p.frame, UnpairedReason::kBadTime);
      return std::nullopt;
    }
    if (r->reset)
      note(p.frame, make_error("device clock reset (clock offset estimate restarted, ", est.stats().resets,
                               " so far for this camera)")
                        .message);
    p.key_ns = est.to_host(p.frame.t_ns).value();
    p.key_clock = ClockDomain::kHostMonotonic;
  }
  switch (config_.mode) {
    case PairingMode::kTimestamp:
      return push_timestamp(std::move(p));
    case PairingMode::kTriggerId:
      return push_trigger(std::move(p));
    case PairingMode::kAdjacent:
      break;
  }
  return push_adjacent(std::move(p));
}

std::optional<StereoFrame> StereoPairer::push_adjacent(Pending p) {
  // A left Frame waits for the right one that follows it; anything else has no partner.
  auto& lefts = pending_[0];
  if (p.frame.camera == CameraId::kLeft) {
    drop_all(lefts.begin(), lefts.end(), UnpairedReason::kNoPartner);
    lefts.clear();
    lefts.push_back(std::move(p));
    return std::nullopt;
  }
  if (lefts.empty()) {
    drop(p.frame, UnpairedReason::kNoPartner);
    return std::nullopt;
  }
  Pending l = std::move(lefts.front());
  lefts.clear();
  return make_pair(std::move(p), std::move(l));
}

// Host times estimated from two device clocks are each off by up to their estimate's uncertainty
// (large while an estimate is young, or when the host's latency is noisy): refusing a pair whose
// skew is within that of the tolerance would drop frames for the estimators' noise, not for the
// cameras'. The widening stays under a quarter of the shorter frame interval, so a frame can
// never be taken for its neighbour's partner.
std::int64_t StereoPairer::timestamp_tolerance() const {
  const std::int64_t tol = config_.tolerance_ns;
  if (!clock_[0] || !clock_[1] || !clock_[0]->has_estimate() || !clock_[1]->has_estimate()) return tol;
  if (interval_ns_[0] <= 0 || interval_ns_[1] <= 0) return tol;
  const std::int64_t cap = std::min(interval_ns_[0], interval_ns_[1]) / 4;
  const std::int64_t widened =
      tol + clock_[0]->estimate().uncertainty_ns + clock_[1]->estimate().uncertainty_ns;
  return std::max(tol, std::min(widened, cap));
}

std::optional<StereoFrame> StereoPairer::push_timestamp(Pending p) {
  const int me = index_of(p.frame.camera), other = 1 - me;
  std::string why;
  if (!comparable_domain(p.key_clock, why)) {
    note(p.frame, why);
    drop(p.frame, UnpairedReason::kClockMismatch);
    return std::nullopt;
  }
  if (last_key_[me] && p.key_ns <= *last_key_[me]) {
    // Out of order or a duplicate: cannot be paired reliably.
    note(p.frame, make_error("not later than the previous ", to_string(p.frame.camera), " frame (t ",
                             *last_key_[me], " ", to_string(p.key_clock), ")")
                      .message);
    drop(p.frame, UnpairedReason::kOutOfOrder);
    return std::nullopt;
  }
  if (last_key_[me]) interval_ns_[me] = p.key_ns - *last_key_[me];
  last_key_[me] = p.key_ns;

  // Partners older than this frame by more than the tolerance will never pair: timestamps only grow.
  const std::int64_t tol = timestamp_tolerance();
  auto& theirs = pending_[other];
  while (!theirs.empty() && theirs.front().key_ns < p.key_ns - tol) {
    drop(theirs.front().frame, UnpairedReason::kNoPartner);
    theirs.pop_front();
  }
  if (!theirs.empty() && std::llabs(theirs.front().key_ns - p.key_ns) <= tol) {
    if (std::llabs(theirs.front().key_ns - p.key_ns) > config_.tolerance_ns)
      ++stats_.pairs_within_uncertainty;
    Pending partner = std::move(theirs.front());
    theirs.pop_front();
    return make_pair(std::move(p), std::move(partner));
  }
  // The other camera is already past this frame: its partner was lost.
  if (last_key_[other] && *last_key_[other] > p.key_ns + tol) {
    drop(p.frame, UnpairedReason::kNoPartner);
    return std::nullopt;
  }
  enqueue(std::move(p));
  return std::nullopt;
}

std::optional<StereoFrame> StereoPairer::push_trigger(Pending p) {
  const int me = index_of(p.frame.camera), other = 1 - me;
  auto& mine = pending_[me];
  auto& theirs = pending_[other];
  if (last_sequence_[me] && p.frame.sequence <= *last_sequence_[me]) {
    // A reconnect or re-arm: this camera counts from scratch. Its waiting frames belong to the old
    // count; a learned offset no longer holds.
    ++stats_.sequence_restarts;
    note(p.frame, make_error("sequence restarted (previous ", *last_sequence_[me], "): ", mine.size(),
                             " pending frame(s) of this camera dropped",
                             config_.trigger_id_offset ? "" : "; the trigger id offset is learned again")
                      .message);
    drop_all(mine.begin(), mine.end(), UnpairedReason::kRestart);
    mine.clear();
    if (!config_.trigger_id_offset) id_offset_.reset();
  }
  last_sequence_[me] = p.frame.sequence;
  const std::int64_t tol = config_.tolerance_ns;

  if (!id_offset_) return learn_trigger_offset(std::move(p));

  const std::int64_t id = id_of(me, p.frame.sequence);
  // The other camera's frames with smaller ids will not pair: this camera is past them.
  while (!theirs.empty() && id_of(other, theirs.front().frame.sequence) < id) {
    drop(theirs.front().frame, UnpairedReason::kNoPartner);
    theirs.pop_front();
  }
  if (!theirs.empty() && id_of(other, theirs.front().frame.sequence) == id) {
    Pending partner = std::move(theirs.front());
    theirs.pop_front();
    if (tol > 0 && comparable(p, partner) && std::llabs(partner.key_ns - p.key_ns) > tol) {
      // Equal ids, different moments: a camera missed a trigger (its count slipped) or the offset
      // is wrong. The older frame's partner is gone; a learned offset is learned again, and the
      // newer frame may still pair by timestamp.
      const bool mine_newer = p.key_ns > partner.key_ns;
      Pending& older = mine_newer ? partner : p;
      note(p.frame, make_error("its id partner ", describe(partner.frame), " differs by ",
                               partner.key_ns - p.key_ns, " ns, more than tolerance_ns ", tol, ": ",
                               config_.trigger_id_offset ? "both dropped"
                                                         : "the older dropped, the offset is learned again")
                        .message);
      drop(older.frame, UnpairedReason::kSkewCheck);
      if (config_.trigger_id_offset) {
        drop((mine_newer ? p : partner).frame, UnpairedReason::kSkewCheck);
        return std::nullopt;
      }
      id_offset_.reset();
      if (!mine_newer) {
        theirs.push_front(std::move(partner));
        return std::nullopt;
      }
      return learn_trigger_offset(std::move(p));
    }
    return make_pair(std::move(p), std::move(partner));
  }
  // The other camera is already past this id: its partner was lost.
  if (last_sequence_[other] && id_of(other, *last_sequence_[other]) > id) {
    drop(p.frame, UnpairedReason::kNoPartner);
    return std::nullopt;
  }
  enqueue(std::move(p));
  return std::nullopt;
}

std::optional<StereoFrame> StereoPairer::learn_trigger_offset(Pending p) {
  // Learning: pair by timestamp; the first pair fixes the offset.
  const int me = index_of(p.frame.camera), other = 1 - me;
  auto& mine = pending_[me];
  auto& theirs = pending_[other];
  const std::int64_t tol = config_.tolerance_ns;
  std::string why;
  if (!comparable_domain(p.key_clock, why)) {
    note(p.frame,
         "cannot learn the trigger id offset from timestamps: " + why + " (or set trigger_id_offset)");
    drop(p.frame, UnpairedReason::kClockMismatch);
    return std::nullopt;
  }
  // Frames queued while the offset was known may be of another domain (no timestamps needed then).
  const auto foreign =
      std::stable_partition(theirs.begin(), theirs.end(), [&](const Pending& q) { return comparable(q, p); });
  drop_all(foreign, theirs.end(), UnpairedReason::kClockMismatch);
  theirs.erase(foreign, theirs.end());
  while (!theirs.empty() && theirs.front().key_ns < p.key_ns - tol) {
    drop(theirs.front().frame, UnpairedReason::kNoPartner);
    theirs.pop_front();
  }
  if (theirs.empty() || std::llabs(theirs.front().key_ns - p.key_ns) > tol) {
    enqueue(std::move(p));
    return std::nullopt;
  }
  Pending partner = std::move(theirs.front());
  theirs.pop_front();
  const Frame& l = me == 0 ? p.frame : partner.frame;
  const Frame& r = me == 0 ? partner.frame : p.frame;
  id_offset_ = static_cast<std::int64_t>(l.sequence) - static_cast<std::int64_t>(r.sequence);
  ++stats_.trigger_offsets_learned;
  note(p.frame, make_error("trigger id offset learned: right id = right sequence + ", *id_offset_).message);
  // This camera's older frames have ids below the pair's, and the other camera is past them.
  drop_all(mine.begin(), mine.end(), UnpairedReason::kNoPartner);
  mine.clear();
  return make_pair(std::move(p), std::move(partner));
}

void StereoPairer::flush() {
  for (int cam = 0; cam < 2; ++cam) {
    drop_all(pending_[cam].begin(), pending_[cam].end(), UnpairedReason::kFlushed);
    pending_[cam].clear();
  }
}

}  // namespace augrig
