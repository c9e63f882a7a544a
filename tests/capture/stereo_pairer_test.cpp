#include "capture/stereo_pairer.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace augrig {
namespace {

Frame make(CameraId cam, TimestampNs t, std::uint64_t seq) {
  Frame f;
  f.camera = cam;
  f.t_ns = t;
  f.sequence = seq;
  f.clock = ClockDomain::kSim;
  return f;
}

Frame make(CameraId cam, TimestampNs t, std::uint64_t seq, ClockDomain clock, TimestampNs t_host = 0) {
  Frame f = make(cam, t, seq);
  f.clock = clock;
  f.t_host_ns = t_host;
  return f;
}

// Every frame pushed is paired, counted unpaired (with a reason) or still pending.
void expect_ledger_balanced(const StereoPairer& p) {
  const PairerStats& s = p.stats();
  EXPECT_EQ(s.frames_left, s.pairs + s.unpaired_left + p.pending(CameraId::kLeft));
  EXPECT_EQ(s.frames_right, s.pairs + s.unpaired_right + p.pending(CameraId::kRight));
  EXPECT_EQ(std::accumulate(s.unpaired_by_reason.begin(), s.unpaired_by_reason.end(), std::uint64_t{0}),
            s.unpaired_left + s.unpaired_right);
}

bool has_message(const StereoPairer& p, const std::string& part) {
  for (const auto& m : p.stats().messages)
    if (m.find(part) != std::string::npos) return true;
  return false;
}

StereoPairer make_pairer(const StereoPairerConfig& c) {
  auto p = StereoPairer::create(c);
  EXPECT_TRUE(p) << p.error().message;
  return std::move(p).value();
}

constexpr std::int64_t kPeriod = 33'333'333;

TEST(StereoPairer, PairsWithinToleranceAndRecordsSkew) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 100'000'000, 0)));
  auto sf = p.push(make(CameraId::kRight, 100'400'000, 0));
  ASSERT_TRUE(sf);
  EXPECT_EQ(sf->skew_ns, 400'000);
  EXPECT_EQ(sf->t_key_ns, 100'200'000);
  EXPECT_EQ(sf->left.camera, CameraId::kLeft);
  EXPECT_EQ(sf->right.camera, CameraId::kRight);
  EXPECT_EQ(p.stats().pairs, 1u);
  EXPECT_EQ(p.stats().max_abs_skew_ns, 400'000);
}

// Unpaired frames carry their time span into the drop ledger (it was written with 0, 0), and the
// frames still waiting are counted with theirs.
TEST(StereoPairer, UnpairedAndPendingFramesHaveTheirTimeSpans) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 100 * kPeriod, 0)));
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 101 * kPeriod, 1)));
  EXPECT_TRUE(p.push(make(CameraId::kRight, 101 * kPeriod + 5, 1)));  // left 100 has no partner
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 103 * kPeriod, 3)));
  EXPECT_FALSE(p.push(make(CameraId::kRight, 104 * kPeriod, 4)));  // left 103 goes unpaired
  const TimeSpan u = p.stats().unpaired_t();
  EXPECT_EQ(u.count, p.stats().unpaired_left + p.stats().unpaired_right);
  EXPECT_EQ(u.count, 2u);
  EXPECT_EQ(u.first_t_ns, 100 * kPeriod);
  EXPECT_EQ(u.last_t_ns, 103 * kPeriod);
  const TimeSpan w = p.pending_t();
  EXPECT_EQ(w.count, 1u);
  EXPECT_EQ(w.first_t_ns, 104 * kPeriod);
  p.flush();
  EXPECT_EQ(p.stats().unpaired_t().count, 3u);
  EXPECT_EQ(p.stats().unpaired_t().last_t_ns, 104 * kPeriod);
  EXPECT_EQ(p.pending_t().count, 0u);
  expect_ledger_balanced(p);
}

// A camera whose stream starts later leaves the other's first frames without a partner: counted
// apart as "at the start". After the first pair, a lost partner is counted as such, and so are
// frames refused for their time even before it.
TEST(StereoPairer, FramesWithoutPartnerBeforeTheFirstPairAreCountedAtTheStart) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 100 * kPeriod, 0)));
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 100 * kPeriod, 1)));  // a duplicate: refused, not "start"
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 101 * kPeriod + 40, 2)));
  EXPECT_FALSE(p.push(make(CameraId::kRight, 101 * kPeriod - 9 * kPeriod / 10, 0)));  // no left near it
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 102 * kPeriod, 3)));
  EXPECT_TRUE(p.push(make(CameraId::kRight, 102 * kPeriod + 20, 1)));  // the first pair
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 103 * kPeriod, 4)));
  EXPECT_FALSE(p.push(make(CameraId::kRight, 104 * kPeriod, 2)));  // left 4 lost its partner
  const PairerStats& s = p.stats();
  EXPECT_EQ(s.pairs, 1u);
  // Left 0 and 2 and right 0 at the start; left 1 refused (out of order), left 4 after the start.
  EXPECT_EQ(s.unpaired_at_start.count, 3u);
  EXPECT_EQ(s.unpaired_at_start.first_t_ns, 100 * kPeriod);
  EXPECT_EQ(s.unpaired_at_start.last_t_ns, 101 * kPeriod + 40);
  EXPECT_EQ(s.unpaired_after_start.count, 2u);
  EXPECT_EQ(s.unpaired_after_start.last_t_ns, 103 * kPeriod);
  EXPECT_EQ(s.unpaired_at_start.count + s.unpaired_after_start.count, s.unpaired_t().count);
  EXPECT_EQ(s.unpaired(UnpairedReason::kOutOfOrder), 1u);
  p.flush();  // right 2: after the start
  EXPECT_EQ(p.stats().unpaired_after_start.count, 3u);
  EXPECT_EQ(p.stats().unpaired_at_start.count, 3u);
  expect_ledger_balanced(p);
}

TEST(StereoPairer, RightFirstAlsoPairs) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kRight, 50, 0)));
  auto sf = p.push(make(CameraId::kLeft, 60, 0));
  ASSERT_TRUE(sf);
  EXPECT_EQ(sf->skew_ns, -10);
}

TEST(StereoPairer, DroppedFrameIsCountedNotPairedWithTheWrongPartner) {
  const std::int64_t period = 33'333'333;
  StereoPairer p(2'000'000);
  int pairs = 0;
  for (int i = 0; i < 10; ++i) {
    if (i != 4) pairs += p.push(make(CameraId::kLeft, i * period, i)).has_value();  // left frame 4 lost
    auto sf = p.push(make(CameraId::kRight, i * period + 500'000, i));
    if (sf) {
      ++pairs;
      EXPECT_EQ(sf->left.sequence, sf->right.sequence);
    }
  }
  p.flush();
  EXPECT_EQ(pairs, 9);
  EXPECT_EQ(p.stats().unpaired_right, 1u);
  EXPECT_EQ(p.stats().unpaired_left, 0u);
}

TEST(StereoPairer, OutOfOrderAndDuplicateFramesAreRejected) {
  StereoPairer p(1000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 5000, 1)));
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 5000, 2)));  // duplicate timestamp
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 4000, 3)));  // goes back in time
  EXPECT_EQ(p.stats().unpaired_left, 2u);
  EXPECT_TRUE(p.push(make(CameraId::kRight, 5100, 1)));
}

TEST(StereoPairer, BoundedPendingQueue) {
  StereoPairer p(10, 3);
  for (int i = 0; i < 10; ++i) EXPECT_FALSE(p.push(make(CameraId::kLeft, i * 1000, i)));
  EXPECT_EQ(p.stats().unpaired_left, 7u);  // only 3 kept
  p.flush();
  EXPECT_EQ(p.stats().unpaired_left, 10u);
}

TEST(StereoPairer, ExistingTestsKeepTheLedgerBalanced) {
  StereoPairer p(2'000'000);
  for (int i = 0; i < 10; ++i) {
    if (i != 4) (void)p.push(make(CameraId::kLeft, i * kPeriod, i));
    (void)p.push(make(CameraId::kRight, i * kPeriod + 500'000, i));
  }
  expect_ledger_balanced(p);
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kNoPartner), 1u);
  EXPECT_EQ(p.pairing_clock(), ClockDomain::kSim);
}

// ---- Clock domains in timestamp mode ----------------------------------------------------------

TEST(StereoPairer, UnknownClockIsRefusedNotCompared) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 1000, 0, ClockDomain::kUnknown)));
  EXPECT_FALSE(p.push(make(CameraId::kRight, 1000, 0, ClockDomain::kUnknown)));
  EXPECT_EQ(p.stats().pairs, 0u);
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kClockMismatch), 2u);
  EXPECT_TRUE(has_message(p, "StereoPairer::push(): left frame 0 (t_ns 1000 unknown): clock domain unknown"));
  expect_ledger_balanced(p);
}

TEST(StereoPairer, DifferentDomainsAreRefusedNotCompared) {
  StereoPairer p(1'000'000);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 5'000'000, 0, ClockDomain::kHostMonotonic)));
  // Same number, other clock: comparing would pair them.
  EXPECT_FALSE(p.push(make(CameraId::kRight, 5'000'000, 0, ClockDomain::kDevice)));
  EXPECT_EQ(p.stats().pairs, 0u);
  EXPECT_EQ(p.stats().unpaired_right, 1u);
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kClockMismatch), 1u);
  EXPECT_TRUE(
      has_message(p, "clock domain device cannot be compared with the pairing domain host_monotonic"));
  // The right camera in the pairing domain pairs.
  EXPECT_TRUE(p.push(make(CameraId::kRight, 5'100'000, 1, ClockDomain::kHostMonotonic)));
}

TEST(StereoPairer, IndependentDeviceClocksNeedClockOffsets) {
  StereoPairerConfig c;
  c.tolerance_ns = 1'000'000;
  c.device_clock_shared = false;
  StereoPairer p = make_pairer(c);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 7000, 0, ClockDomain::kDevice)));
  EXPECT_FALSE(p.push(make(CameraId::kRight, 7000, 0, ClockDomain::kDevice)));
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kClockMismatch), 2u);
  EXPECT_TRUE(has_message(p, "turn on clock_offsets"));
  // Shared device clocks (the default: PTP, or a simulation) compare directly.
  StereoPairer shared(1'000'000);
  EXPECT_FALSE(shared.push(make(CameraId::kLeft, 7000, 0, ClockDomain::kDevice)));
  EXPECT_TRUE(shared.push(make(CameraId::kRight, 7000, 0, ClockDomain::kDevice)));
}

// Two cameras, each with its own device clock (offsets of seconds, drifts of opposite sign),
// exposing together (hardware sync, 20 us jitter). Arrivals carry 1 ms mean exponential latency.
// Through the per-camera clock offset estimates every frame pairs, and the recorded skew is the
// true one (from the known host times) within the estimators' error.
struct TwoCameraRig {
  double drift_ppm[2] = {20.0, -30.0};
  TimestampNs device0_ns[2] = {5'000'000'000, 900'000'000'000};
  TimestampNs host0_ns = 77'000'000'000;
  std::uint64_t seed = 3;
  double latency_mean_ns = 1e6;  // exponential arrival latency

  struct Shot {
    Frame frame;
    double true_host_ns;  // host time of its mid-exposure
  };
  // Frames of both cameras in arrival order.
  std::vector<Shot> run(int frames) const {
    std::mt19937_64 rng(seed);
    std::exponential_distribution<double> latency(1.0 / latency_mean_ns);
    std::normal_distribution<double> jitter(0.0, 20'000.0);
    std::vector<Shot> out;
    TimestampNs last_arrival[2] = {0, 0};
    for (int i = 0; i < frames; ++i)
      for (int cam = 0; cam < 2; ++cam) {
        const double t_host = static_cast<double>(host0_ns) + static_cast<double>(i) * kPeriod + jitter(rng);
        // device = device0 + (host - host0) / (1 + drift)
        const auto t_dev =
            device0_ns[cam] + static_cast<TimestampNs>(std::llround((t_host - static_cast<double>(host0_ns)) /
                                                                    (1.0 + drift_ppm[cam] * 1e-6)));
        const auto arrival = std::max(last_arrival[cam], static_cast<TimestampNs>(t_host + latency(rng)));
        last_arrival[cam] = arrival;
        out.push_back(
            {make(cam == 0 ? CameraId::kLeft : CameraId::kRight, t_dev, i, ClockDomain::kDevice, arrival),
             t_host});
      }
    std::stable_sort(out.begin(), out.end(),
                     [](const Shot& a, const Shot& b) { return a.frame.t_host_ns < b.frame.t_host_ns; });
    return out;
  }
};

TEST(StereoPairer, ClockOffsetsPairIndependentDeviceClocksOnHostTime) {
  StereoPairerConfig c;
  c.tolerance_ns = kPeriod / 2;
  c.device_clock_shared = false;
  c.clock_offsets = ClockOffsetConfig{};
  StereoPairer p = make_pairer(c);
  const auto shots = TwoCameraRig{}.run(1200);  // 40 s
  std::map<std::uint64_t, double> true_host[2];
  for (const auto& s : shots) true_host[index_of(s.frame.camera)][s.frame.sequence] = s.true_host_ns;
  double worst_skew_error_ns = 0;
  for (const auto& s : shots) {
    auto sf = p.push(s.frame);
    if (!sf) continue;
    ASSERT_EQ(sf->left.sequence, sf->right.sequence);
    // The frames keep their own stamps; skew and key are host monotonic times.
    EXPECT_EQ(sf->left.clock, ClockDomain::kDevice);
    const double true_skew = true_host[1][sf->right.sequence] - true_host[0][sf->left.sequence];
    if (sf->left.sequence >= 300)
      worst_skew_error_ns = std::max(worst_skew_error_ns, std::abs(sf->skew_ns - true_skew));
    EXPECT_NEAR(static_cast<double>(sf->t_key_ns),
                0.5 * (true_host[0][sf->left.sequence] + true_host[1][sf->right.sequence]),
                sf->left.sequence >= 300 ? 100'000 : 3'000'000);
  }
  p.flush();
  EXPECT_EQ(p.stats().pairs, 1200u);
  EXPECT_EQ(p.stats().unpaired_left + p.stats().unpaired_right, 0u);
  EXPECT_EQ(p.pairing_clock(), ClockDomain::kHostMonotonic);
  EXPECT_LT(worst_skew_error_ns, 40'000);  // after 10 s: the two estimators' errors (11 us seen)
  EXPECT_NEAR(p.clock_estimator(CameraId::kLeft)->estimate().drift_ppm, 20.0, 3.0);
  EXPECT_NEAR(p.clock_estimator(CameraId::kRight)->estimate().drift_ppm, -30.0, 3.0);
  EXPECT_LT(p.stats().skew.p99_abs_ns(), 200'000);
  expect_ledger_balanced(p);

  // The same frames compared raw, as if the device clocks were one: nothing pairs.
  StereoPairer raw(kPeriod / 2);
  for (const auto& s : shots) EXPECT_FALSE(raw.push(s.frame));
}

// Live latency: a pair comes out of the push of its second frame, never later (not at the next
// frame of either camera), in whichever order the two cameras' frames arrive.
TEST(StereoPairer, EachPairIsMadeByTheArrivalOfItsSecondFrame) {
  StereoPairerConfig c;
  c.tolerance_ns = kPeriod / 4;
  c.device_clock_shared = false;
  c.clock_offsets = ClockOffsetConfig{};
  StereoPairer p = make_pairer(c);
  TwoCameraRig rig;
  rig.latency_mean_ns = 3e6;            // enough to swap the cameras' arrival order often
  std::map<std::uint64_t, int> pushed;  // sequence -> frames of it pushed
  int left_second = 0, right_second = 0;
  for (const auto& s : rig.run(600)) {
    const std::uint64_t seq = s.frame.sequence;
    const CameraId cam = s.frame.camera;
    auto sf = p.push(s.frame);
    if (++pushed[seq] == 1) {
      EXPECT_FALSE(sf) << "frame " << seq << ": paired before its partner came";
      continue;
    }
    ASSERT_TRUE(sf) << "frame " << seq << ": both partners are in, the pair must come out now";
    EXPECT_EQ(sf->left.sequence, seq);
    EXPECT_EQ(sf->right.sequence, seq);
    ++(cam == CameraId::kLeft ? left_second : right_second);
  }
  EXPECT_EQ(p.stats().pairs, 600u);
  EXPECT_GT(left_second, 50) << "the test must see both arrival orders";
  EXPECT_GT(right_second, 50);
  expect_ledger_balanced(p);
}

// Triggered cameras (true skew ~20 us) with separate clocks behind a slow, noisy link (latency
// 5 ms on average): the host-time estimates are off by up to their uncertainty, far more than a
// 100 us tolerance. Pairs are refused only when the skew exceeds the tolerance beyond that
// uncertainty, so every frame pairs with its true partner; frames half a period apart never do.
TEST(StereoPairer, HostTimeToleranceGrowsByTheClockEstimatesUncertainty) {
  StereoPairerConfig c;
  c.tolerance_ns = 100'000;
  c.device_clock_shared = false;
  c.clock_offsets = ClockOffsetConfig{};
  TwoCameraRig rig;
  rig.latency_mean_ns = 5e6;
  StereoPairer p = make_pairer(c);
  const auto shots = rig.run(300);
  for (const auto& s : shots) {
    if (auto sf = p.push(s.frame)) {
      EXPECT_EQ(sf->left.sequence, sf->right.sequence);
    }
  }
  p.flush();
  EXPECT_GE(p.stats().pairs, 297u);
  EXPECT_GT(p.stats().pairs_within_uncertainty, 0u);
  EXPECT_LE(p.stats().pairs_within_uncertainty, p.stats().pairs);
  EXPECT_GT(p.stats().skew.max_abs_ns, c.tolerance_ns);  // what the widening let through
  expect_ledger_balanced(p);

  // The right camera half a period late: the widening stops at a quarter of the frame interval.
  auto late = shots;
  for (auto& s : late)
    if (s.frame.camera == CameraId::kRight) s.frame.t_ns += kPeriod / 2, s.frame.t_host_ns += kPeriod / 2;
  std::stable_sort(late.begin(), late.end(),
                   [](const auto& a, const auto& b) { return a.frame.t_host_ns < b.frame.t_host_ns; });
  StereoPairer q = make_pairer(c);
  for (const auto& s : late) EXPECT_FALSE(q.push(s.frame));
  q.flush();
  EXPECT_EQ(q.stats().pairs, 0u);
  expect_ledger_balanced(q);
}

TEST(StereoPairer, DeviceClockResetKeepsPairingOnHostTime) {
  StereoPairerConfig c;
  c.tolerance_ns = kPeriod / 2;
  c.clock_offsets = ClockOffsetConfig{};
  StereoPairer p = make_pairer(c);
  auto shots = TwoCameraRig{}.run(900);
  // The left camera resets at frame 450: its clock starts again near zero.
  const TimestampNs left_shift = -TwoCameraRig{}.device0_ns[0] - 450 * kPeriod + 1'000'000;
  for (auto& s : shots)
    if (s.frame.camera == CameraId::kLeft && s.frame.sequence >= 450) s.frame.t_ns += left_shift;
  std::uint64_t pairs_after = 0;
  for (const auto& s : shots)
    if (auto sf = p.push(s.frame)) {
      ASSERT_EQ(sf->left.sequence, sf->right.sequence);
      pairs_after += sf->left.sequence >= 451;
    }
  EXPECT_EQ(p.clock_estimator(CameraId::kLeft)->stats().resets, 1u);
  EXPECT_TRUE(has_message(p, "left frame 450"));
  EXPECT_TRUE(has_message(p, "device clock reset"));
  EXPECT_EQ(pairs_after, 900u - 451u);
  expect_ledger_balanced(p);
}

TEST(StereoPairer, FrameWithoutHostTimeIsRefusedWhenConverting) {
  StereoPairerConfig c;
  c.tolerance_ns = 1'000'000;
  c.clock_offsets = ClockOffsetConfig{};
  StereoPairer p = make_pairer(c);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 1'000'000, 0, ClockDomain::kDevice, 0)));
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kBadTime), 1u);
  EXPECT_TRUE(has_message(p, "ClockOffsetEstimator::add(): host_arrival_ns"));
}

// ---- Skew statistics --------------------------------------------------------------------------

TEST(StereoPairer, SkewStatisticsMatchTheExactValues) {
  StereoPairer p(2'000'000);
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<std::int64_t> skew(-1'500'000, 1'500'000);
  std::vector<std::int64_t> skews;
  for (int i = 0; i < 2000; ++i) {
    const std::int64_t k = skew(rng);
    (void)p.push(make(CameraId::kLeft, i * kPeriod, i));
    auto sf = p.push(make(CameraId::kRight, i * kPeriod + k, i));
    ASSERT_TRUE(sf);
    EXPECT_EQ(sf->skew_ns, k);
    skews.push_back(k);
  }
  const SkewStats& s = p.stats().skew;
  ASSERT_EQ(s.count, skews.size());
  const double mean = std::accumulate(skews.begin(), skews.end(), 0.0) / static_cast<double>(skews.size());
  EXPECT_NEAR(s.mean_ns(), mean, 1e-6 * std::abs(mean) + 1e-3);
  double sq = 0;
  for (auto k : skews) sq += static_cast<double>(k) * static_cast<double>(k);
  EXPECT_NEAR(s.rms_ns(), std::sqrt(sq / static_cast<double>(skews.size())), 1e-3);
  std::vector<std::int64_t> abs_skews;
  for (auto k : skews) abs_skews.push_back(std::llabs(k));
  std::sort(abs_skews.begin(), abs_skews.end());
  EXPECT_EQ(s.max_abs_ns, abs_skews.back());
  EXPECT_EQ(p.stats().max_abs_skew_ns, abs_skews.back());
  for (double q : {0.5, 0.9, 0.99}) {
    const auto exact = abs_skews[static_cast<std::size_t>(std::ceil(q * abs_skews.size())) - 1];
    const std::int64_t got = s.abs_quantile_ns(q);
    EXPECT_GE(got, exact) << q;
    EXPECT_LE(static_cast<double>(got), static_cast<double>(exact) * std::exp2(1.0 / 8.0) + 1) << q;
  }
  EXPECT_EQ(s.p50_abs_ns(), s.abs_quantile_ns(0.5));
  EXPECT_EQ(s.abs_quantile_ns(1.0), abs_skews.back());
}

TEST(StereoPairer, SkewHistogramBins) {
  EXPECT_EQ(SkewStats::bin_of(0), 0u);
  EXPECT_EQ(SkewStats::bin_of(100), 0u);
  EXPECT_EQ(SkewStats::bin_of(101), 1u);
  EXPECT_EQ(SkewStats::upper_edge_ns(8), 200);
  EXPECT_EQ(SkewStats::upper_edge_ns(80), 102'400);
  EXPECT_EQ(SkewStats::bin_of(SkewStats::upper_edge_ns(57)), 57u);
  EXPECT_EQ(SkewStats::bin_of(SkewStats::upper_edge_ns(57) + 1), 58u);
  EXPECT_EQ(SkewStats::bin_of(std::int64_t{1} << 62), SkewStats::kBins - 1);
  EXPECT_GT(SkewStats::upper_edge_ns(SkewStats::kBins - 1), 30'000'000'000);
}

// ---- Realistic failures -----------------------------------------------------------------------

// The right camera stalls for a second (its frames of that time are lost). The left frames do not
// wait for it: with a 200 ms age limit at most ~7 wait, the others are counted; pairing resumes.
TEST(StereoPairer, StalledCameraDoesNotHoldItsPartnerForever) {
  StereoPairerConfig c;
  c.tolerance_ns = 2'000'000;
  c.max_pending = 100;
  c.max_age_ns = 200'000'000;
  StereoPairer p = make_pairer(c);
  std::size_t most_pending = 0;
  for (int i = 0; i < 120; ++i) {
    const TimestampNs t = 10'000'000'000 + i * kPeriod;
    (void)p.push(make(CameraId::kLeft, t, i, ClockDomain::kHostMonotonic, t + 1'000'000));
    if (i < 30 || i >= 60)
      (void)p.push(make(CameraId::kRight, t + 300'000, i, ClockDomain::kHostMonotonic, t + 1'200'000));
    most_pending = std::max(most_pending, p.pending(CameraId::kLeft));
  }
  EXPECT_LE(most_pending, 7u);
  EXPECT_EQ(p.stats().pairs, 90u);
  EXPECT_EQ(p.stats().unpaired_left, 30u);
  EXPECT_GT(p.stats().unpaired(UnpairedReason::kMaxAge), 20u);
  EXPECT_EQ(p.stats().unpaired_right, 0u);
  expect_ledger_balanced(p);
}

// The right camera's frames are not lost but arrive a second late, in a burst. Those whose partners
// aged out are counted at once instead of filling the queue; the last few (partners younger than
// max_age_ns) still pair.
TEST(StereoPairer, LateBacklogIsCountedAtOnce) {
  StereoPairerConfig c;
  c.tolerance_ns = 2'000'000;
  c.max_age_ns = 200'000'000;
  StereoPairer p = make_pairer(c);
  std::vector<Frame> backlog;
  int pairs_after_burst = 0, backlog_pairs = 0;
  for (int i = 0; i < 120; ++i) {
    const TimestampNs t = 10'000'000'000 + i * kPeriod;
    (void)p.push(make(CameraId::kLeft, t, i, ClockDomain::kHostMonotonic, t + 1'000'000));
    Frame r = make(CameraId::kRight, t + 300'000, i, ClockDomain::kHostMonotonic, t + 1'200'000);
    if (i >= 30 && i < 60) {
      backlog.push_back(r);
      continue;
    }
    if (i == 60)
      for (Frame& b : backlog) {
        b.t_host_ns = r.t_host_ns;
        const std::uint64_t seq = b.sequence;
        if (auto sf = p.push(std::move(b))) {
          ++backlog_pairs;
          EXPECT_EQ(sf->left.sequence, seq);
        }
        EXPECT_EQ(p.pending(CameraId::kRight), 0u);
      }
    if (p.push(r)) pairs_after_burst += i >= 60;
  }
  // Left frames 55..59 are younger than 200 ms when the burst arrives at frame 60's time.
  EXPECT_EQ(backlog_pairs, 5);
  EXPECT_EQ(pairs_after_burst, 60);
  EXPECT_EQ(p.stats().unpaired_right, 25u);
  EXPECT_EQ(p.stats().unpaired_left, 25u);
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kNoPartner), 25u);
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kMaxAge), 25u);
  expect_ledger_balanced(p);
}

// Left frames arrive in bursts of 5 before the right ones: all pair.
TEST(StereoPairer, BurstsOfOneCameraStillPair) {
  for (PairingMode mode : {PairingMode::kTimestamp, PairingMode::kTriggerId}) {
    StereoPairerConfig c;
    c.mode = mode;
    c.tolerance_ns = 2'000'000;
    StereoPairer p = make_pairer(c);
    int pairs = 0;
    for (int burst = 0; burst < 20; ++burst) {
      for (int k = 0; k < 5; ++k) {
        const int i = burst * 5 + k;
        EXPECT_FALSE(p.push(make(CameraId::kLeft, i * kPeriod, i)));
      }
      for (int k = 0; k < 5; ++k) {
        const int i = burst * 5 + k;
        auto sf = p.push(make(CameraId::kRight, i * kPeriod + 400'000, i));
        ASSERT_TRUE(sf) << to_string(mode) << " " << i;
        EXPECT_EQ(sf->left.sequence, sf->right.sequence);
        ++pairs;
      }
    }
    EXPECT_EQ(pairs, 100);
    EXPECT_EQ(p.stats().unpaired_left + p.stats().unpaired_right, 0u);
  }
}

// Each camera drops 5 % of its frames (random, independently): in both modes exactly the frames
// present on both sides pair, each with its own partner, and every other frame is counted.
TEST(StereoPairer, SingleDropsAreCountedAndNeverMispaired) {
  for (PairingMode mode : {PairingMode::kTimestamp, PairingMode::kTriggerId}) {
    StereoPairerConfig c;
    c.mode = mode;
    c.tolerance_ns = 2'000'000;
    StereoPairer p = make_pairer(c);
    std::mt19937_64 rng(11);
    std::bernoulli_distribution lost(0.05);
    std::uint64_t both = 0, present[2] = {0, 0}, pairs = 0;
    for (int i = 0; i < 3000; ++i) {
      const bool have[2] = {!lost(rng), !lost(rng)};
      both += have[0] && have[1];
      for (int cam = 0; cam < 2; ++cam) {
        if (!have[cam]) continue;
        ++present[cam];
        auto sf = p.push(make(cam == 0 ? CameraId::kLeft : CameraId::kRight, i * kPeriod + cam * 300'000, i));
        if (sf) {
          ++pairs;
          EXPECT_EQ(sf->left.sequence, sf->right.sequence);
          EXPECT_EQ(sf->skew_ns, 300'000);
        }
      }
    }
    p.flush();
    EXPECT_EQ(pairs, both) << to_string(mode);
    EXPECT_EQ(p.stats().unpaired_left, present[0] - both);
    EXPECT_EQ(p.stats().unpaired_right, present[1] - both);
    EXPECT_LE(p.stats().unpaired(UnpairedReason::kFlushed), 1u);
    expect_ledger_balanced(p);
  }
}

// ---- Trigger id mode --------------------------------------------------------------------------

// Hardware-triggered cameras with independent clocks and no estimation: ids pair them; the skew
// is unknown and said so.
TEST(StereoPairer, TriggerIdPairsAcrossClocksWithConfiguredOffset) {
  StereoPairerConfig c;
  c.mode = PairingMode::kTriggerId;
  c.device_clock_shared = false;
  c.trigger_id_offset = 3;  // the right camera was armed 3 triggers late: its count is 3 behind
  StereoPairer p = make_pairer(c);
  int pairs = 0;
  for (int i = 0; i < 50; ++i) {
    (void)p.push(make(CameraId::kLeft, 1'000'000'000 + i * kPeriod, i, ClockDomain::kDevice));
    if (i >= 3)
      if (auto sf =
              p.push(make(CameraId::kRight, 9'000'000'000 + i * kPeriod, i - 3, ClockDomain::kDevice))) {
        ++pairs;
        EXPECT_EQ(sf->left.sequence, sf->right.sequence + 3);
        EXPECT_EQ(sf->skew_ns, 0);
      }
  }
  EXPECT_EQ(pairs, 47);
  EXPECT_EQ(p.stats().pairs_without_skew, 47u);
  EXPECT_EQ(p.stats().skew.count, 0u);
  EXPECT_EQ(p.stats().unpaired_left, 3u);  // triggers 0..2 had no right frame; counted once passed
  expect_ledger_balanced(p);
}

// Without a configured offset it is learned from the first frames that pair by timestamp; the
// skew is recorded.
TEST(StereoPairer, TriggerIdLearnsTheOffsetFromTimestamps) {
  StereoPairerConfig c;
  c.mode = PairingMode::kTriggerId;
  c.tolerance_ns = 2'000'000;
  StereoPairer p = make_pairer(c);
  int pairs = 0;
  for (int i = 0; i < 100; ++i) {
    (void)p.push(make(CameraId::kLeft, i * kPeriod, 500 + i));
    if (auto sf = p.push(make(CameraId::kRight, i * kPeriod - 250'000, 7 + i))) {
      ++pairs;
      EXPECT_EQ(sf->left.sequence, sf->right.sequence + 493);
      EXPECT_EQ(sf->skew_ns, -250'000);
    }
  }
  EXPECT_EQ(pairs, 100);
  EXPECT_EQ(p.trigger_id_offset(), 493);
  EXPECT_EQ(p.stats().trigger_offsets_learned, 1u);
  EXPECT_EQ(p.stats().skew.count, 100u);
  EXPECT_TRUE(has_message(p, "trigger id offset learned: right id = right sequence + 493"));
}

// The right camera reconnects: 0.5 s of its frames are lost and its count starts again at 0.
// The restart is counted, the offset learned again, and pairing resumes with the right partners.
TEST(StereoPairer, TriggerIdSequenceRestartAfterReconnect) {
  StereoPairerConfig c;
  c.mode = PairingMode::kTriggerId;
  c.tolerance_ns = 2'000'000;
  StereoPairer p = make_pairer(c);
  int pairs = 0;
  for (int i = 0; i < 200; ++i) {
    (void)p.push(make(CameraId::kLeft, i * kPeriod, i));
    if (i >= 100 && i < 115) continue;  // reconnecting
    const std::uint64_t right_seq = i < 100 ? i : i - 115;
    if (auto sf = p.push(make(CameraId::kRight, i * kPeriod + 100'000, right_seq))) {
      ++pairs;
      EXPECT_EQ(sf->right.t_ns - sf->left.t_ns, 100'000);  // the true partner
    }
  }
  p.flush();
  EXPECT_EQ(pairs, 185);
  EXPECT_EQ(p.stats().sequence_restarts, 1u);
  EXPECT_EQ(p.stats().trigger_offsets_learned, 2u);
  EXPECT_EQ(p.trigger_id_offset(), 115);
  EXPECT_EQ(p.stats().unpaired_left, 15u);
  EXPECT_TRUE(has_message(p, "sequence restarted (previous 99)"));
  expect_ledger_balanced(p);
}

// The left camera misses trigger 50 without counting it: from then on its ids are one behind.
// The equal-id pair with timestamps a period apart is refused, the offset learned again, and no
// wrong pair is ever made.
TEST(StereoPairer, TriggerIdMissedTriggerIsCaughtByTheSkewCheck) {
  StereoPairerConfig c;
  c.mode = PairingMode::kTriggerId;
  c.tolerance_ns = 2'000'000;
  StereoPairer p = make_pairer(c);
  int pairs = 0;
  for (int i = 0; i < 120; ++i) {
    if (i != 50) (void)p.push(make(CameraId::kLeft, i * kPeriod, i < 50 ? i : i - 1));
    if (auto sf = p.push(make(CameraId::kRight, i * kPeriod + 100'000, i))) {
      ++pairs;
      EXPECT_EQ(sf->skew_ns, 100'000) << "left " << sf->left.sequence << " right " << sf->right.sequence;
    }
  }
  p.flush();
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kSkewCheck), 1u);
  EXPECT_EQ(p.stats().trigger_offsets_learned, 2u);
  EXPECT_EQ(p.trigger_id_offset(), -1);
  EXPECT_EQ(pairs, 119);  // every trigger but 50
  EXPECT_TRUE(has_message(p, "more than tolerance_ns 2000000"));
  expect_ledger_balanced(p);
}

TEST(StereoPairer, TriggerIdCannotLearnAcrossClocks) {
  StereoPairerConfig c;
  c.mode = PairingMode::kTriggerId;
  c.tolerance_ns = 2'000'000;
  c.device_clock_shared = false;
  StereoPairer p = make_pairer(c);
  EXPECT_FALSE(p.push(make(CameraId::kLeft, 1000, 0, ClockDomain::kDevice)));
  EXPECT_FALSE(p.push(make(CameraId::kRight, 1000, 0, ClockDomain::kDevice)));
  EXPECT_EQ(p.stats().unpaired(UnpairedReason::kClockMismatch), 2u);
  EXPECT_TRUE(has_message(p, "cannot learn the trigger id offset from timestamps"));
  EXPECT_TRUE(has_message(p, "set trigger_id_offset"));
}

TEST(StereoPairer, BadConfigurationNamesTheField) {
  StereoPairerConfig c;
  c.tolerance_ns = -1;
  auto p = StereoPairer::create(c);
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find("StereoPairer::create(): tolerance_ns: expected >= 0"), std::string::npos);
  c = {};
  c.mode = PairingMode::kTriggerId;
  p = StereoPairer::create(c);
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find("trigger_id_offset"), std::string::npos);
  c = {};
  c.max_pending = 0;
  EXPECT_FALSE(StereoPairer::create(c));
  c = {};
  c.clock_offsets = ClockOffsetConfig{};
  c.clock_offsets->window_ns = -5;
  p = StereoPairer::create(c);
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().message.find(
                "StereoPairer::create(): clock_offsets: ClockOffsetEstimator::create(): window_ns"),
            std::string::npos);
}

}  // namespace
}  // namespace augrig
