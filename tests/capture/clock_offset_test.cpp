#include "capture/clock_offset.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace augrig {
namespace {

// A camera clock against the host: device time d, true host time of d
//   h(d) = host0 + (d - device0) (1 + drift_ppm 1e-6),
// and arrival = h(d) + latency, latency ~ Gamma(shape, mean) plus, with outlier_probability, a
// scheduling delay uniform in [5, 50] ms. Frames are delivered in order (a FIFO), so a late frame
// delays the ones queued behind it, as a driver's buffer queue does.
struct SyntheticClock {
  TimestampNs device0_ns = 1'400'000'000'000'000'000;  // a GPS-epoch-like device clock
  TimestampNs host0_ns = 123'456'789'012;              // CLOCK_MONOTONIC since boot
  double drift_ppm = 50.0;
  double fps = 30.0;
  double latency_mean_ns = 1e6;
  double latency_shape = 1.0;  // 1: exponential
  double outlier_probability = 0.02;
  std::uint64_t seed = 1;

  struct Sample {
    TimestampNs device_ns;
    TimestampNs arrival_ns;
    double true_host_ns;
  };

  double true_host(TimestampNs device_ns) const {
    return static_cast<double>(host0_ns) +
           static_cast<double>(device_ns - device0_ns) * (1.0 + drift_ppm * 1e-6);
  }
  std::vector<Sample> run(double duration_s) const {
    std::mt19937_64 rng(seed);
    std::gamma_distribution<double> latency(latency_shape, latency_mean_ns / latency_shape);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<Sample> out;
    TimestampNs last_arrival = 0;
    const auto n = static_cast<int>(duration_s * fps);
    for (int i = 0; i < n; ++i) {
      const TimestampNs d = device0_ns + s_to_ns(i / fps);
      double lat = latency(rng);
      if (u(rng) < outlier_probability) lat += 5e6 + 45e6 * u(rng);
      const auto arrival = std::max(last_arrival, static_cast<TimestampNs>(std::ceil(true_host(d) + lat)));
      last_arrival = arrival;
      out.push_back({d, arrival, true_host(d)});
    }
    return out;
  }
};

double error_ns(const ClockOffsetEstimator& e, const SyntheticClock::Sample& s) {
  return static_cast<double>(e.to_host(s.device_ns).value()) - s.true_host_ns;
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

ClockOffsetEstimator make(const ClockOffsetConfig& c) {
  auto e = ClockOffsetEstimator::create(c);
  EXPECT_TRUE(e) << e.error().message;
  return std::move(e).value();
}

// The case: 30 fps, 1 ms mean exponential latency, 50 ppm drift, 2 % scheduling outliers.
// The error at the NEWEST sample (what converting a new frame needs) over 50 clocks: the lower
// envelope's error falls as 1/n, with a long tail from the drift extrapolated over half the window.
TEST(ClockOffset, ConvergesOnExponentialLatencyWithOutliers) {
  std::vector<double> err_10s, err_30s, err_45s, drift_err_30s;
  for (std::uint64_t seed = 1; seed <= 50; ++seed) {
    SyntheticClock clock;
    clock.seed = seed;
    const auto samples = clock.run(45.0);
    ClockOffsetEstimator e;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      ASSERT_TRUE(e.add(samples[i].device_ns, samples[i].arrival_ns));
      if (i == 300) err_10s.push_back(std::abs(error_ns(e, samples[i])));
      if (i == 900) {
        err_30s.push_back(std::abs(error_ns(e, samples[i])));
        drift_err_30s.push_back(std::abs(e.estimate().drift_ppm - clock.drift_ppm));
        EXPECT_TRUE(e.estimate().converged);
      }
    }
    // The window (30 s) has slid: still as good.
    err_45s.push_back(std::abs(error_ns(e, samples.back())));
    EXPECT_EQ(e.stats().resets, 0u) << "seed " << seed;
    EXPECT_GT(e.stats().outliers, 0u);
  }
  for (double q : {0.5, 0.9, 1.0})
    std::printf("q%.1f: 10 s %.0f ns, 30 s %.0f ns, 45 s %.0f ns, drift at 30 s %.2f ppm\n", q,
                quantile(err_10s, q), quantile(err_30s, q), quantile(err_45s, q), quantile(drift_err_30s, q));
  EXPECT_LT(quantile(err_10s, 0.5), 12'000);
  EXPECT_LT(quantile(err_10s, 0.9), 40'000);
  EXPECT_LT(quantile(err_10s, 1.0), 100'000);
  for (const auto* err : {&err_30s, &err_45s}) {
    EXPECT_LT(quantile(*err, 0.5), 5'000);
    EXPECT_LT(quantile(*err, 0.9), 15'000);
    EXPECT_LT(quantile(*err, 1.0), 50'000);
  }
  EXPECT_LT(quantile(drift_err_30s, 1.0), 2.0);
}

// The lower-envelope line is the solution of Moon et al.'s linear program: among the lines below
// every (device, host - device) point, the one with the smallest sum of distances to them. A brute
// force over every line through two points must find the same one.
TEST(ClockOffset, MatchesABruteForceLinearProgram) {
  ClockOffsetConfig c;
  c.min_drift_span_ns = 0;
  c.max_abs_drift_ppm = 1e5;            // no clamp: the plain LP
  c.jump_threshold_ns = 1'000'000'000;  // and no restarts on the wild slopes of the first few samples
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    SyntheticClock clock;
    clock.seed = seed;
    clock.drift_ppm = -80.0;
    clock.fps = 10.0;
    const auto samples = clock.run(6.0);  // 60 samples
    ClockOffsetEstimator e = make(c);
    for (const auto& s : samples) ASSERT_TRUE(e.add(s.device_ns, s.arrival_ns));
    ASSERT_EQ(e.estimate().samples, samples.size());

    // Oracle: y = host - device relative to the first sample, x = device relative to it.
    const auto& s0 = samples.front();
    std::vector<long double> x, y;
    for (const auto& s : samples) {
      x.push_back(static_cast<long double>(s.device_ns - s0.device_ns));
      y.push_back(static_cast<long double>((s.arrival_ns - s.device_ns) - (s0.arrival_ns - s0.device_ns)));
    }
    long double best = std::numeric_limits<long double>::infinity(), best_slope = 0, best_c = 0;
    for (std::size_t i = 0; i < x.size(); ++i)
      for (std::size_t j = i + 1; j < x.size(); ++j) {
        const long double slope = (y[j] - y[i]) / (x[j] - x[i]), icpt = y[i] - slope * x[i];
        long double sum = 0;
        bool below_all = true;
        for (std::size_t k = 0; k < x.size() && below_all; ++k) {
          const long double r = y[k] - (icpt + slope * x[k]);
          below_all = r > -1e-6L;
          sum += r;
        }
        if (below_all && sum < best) best = sum, best_slope = slope, best_c = icpt;
      }
    ASSERT_TRUE(std::isfinite(static_cast<double>(best)));
    for (const auto& s : {samples.front(), samples[samples.size() / 2], samples.back()}) {
      const long double oracle_host = static_cast<long double>(s.device_ns) +
                                      static_cast<long double>(s0.arrival_ns - s0.device_ns) + best_c +
                                      best_slope * static_cast<long double>(s.device_ns - s0.device_ns);
      EXPECT_NEAR(static_cast<double>(e.to_host(s.device_ns).value() -
                                      static_cast<TimestampNs>(std::llround(oracle_host))),
                  0.0, 1.0)
          << "seed " << seed;
    }
    EXPECT_NEAR(e.estimate().drift_ppm, static_cast<double>(best_slope) * 1e6, 1e-6);
  }
}

// The reported uncertainty covers the true error at the newest sample in at least 97 % of the
// frames once converged (exponential latency), and shrinks as samples accumulate.
TEST(ClockOffset, UncertaintyCoversTheError) {
  std::size_t covered = 0, total = 0;
  std::vector<double> unc_5s, unc_30s;
  for (std::uint64_t seed = 101; seed <= 120; ++seed) {
    SyntheticClock clock;
    clock.seed = seed;
    const auto samples = clock.run(40.0);
    ClockOffsetEstimator e;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      ASSERT_TRUE(e.add(samples[i].device_ns, samples[i].arrival_ns));
      const ClockEstimate est = e.estimate();
      if (!est.converged) continue;
      ++total;
      covered += std::abs(error_ns(e, samples[i])) <= static_cast<double>(est.uncertainty_ns);
      if (i == 150) unc_5s.push_back(static_cast<double>(est.uncertainty_ns));
      if (i == 900) unc_30s.push_back(static_cast<double>(est.uncertainty_ns));
    }
  }
  ASSERT_GT(total, 20'000u);
  EXPECT_GE(static_cast<double>(covered), 0.97 * static_cast<double>(total));
  EXPECT_LT(quantile(unc_30s, 0.5), 0.5 * quantile(unc_5s, 0.5));
  EXPECT_LT(quantile(unc_30s, 0.5), 60'000);
}

// Latency with few near-zero values (Gamma, shape 3): the envelope sits on the smallest latency
// seen, which no arrival-time method can tell from the offset; the estimate is late by about it.
TEST(ClockOffset, GammaLatencyLeavesItsFloorInTheOffset) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    SyntheticClock clock;
    clock.seed = seed;
    clock.latency_shape = 3.0;
    const auto samples = clock.run(30.0);
    ClockOffsetEstimator e;
    for (const auto& s : samples) ASSERT_TRUE(e.add(s.device_ns, s.arrival_ns));
    const double err = error_ns(e, samples.back());
    EXPECT_GT(err, -50'000) << "seed " << seed;
    EXPECT_LT(err, 300'000) << "seed " << seed;
    EXPECT_NEAR(e.estimate().drift_ppm, clock.drift_ppm, 10.0) << "seed " << seed;
  }
}

// The device clock restarts (a camera reset or reconnect): its timestamp goes back. The estimate
// restarts, is counted, keeps the drift, and converges on the new offset.
TEST(ClockOffset, DeviceClockResetRestartsTheEstimate) {
  SyntheticClock before;
  before.outlier_probability = 0;
  const auto a = before.run(20.0);
  SyntheticClock after = before;
  after.seed = 2;
  after.device0_ns = 5'000'000;                         // counts from zero again...
  after.host0_ns = a.back().true_host_ns + 40'000'000;  // ...40 ms after the last frame
  const auto b = after.run(15.0);

  ClockOffsetEstimator e;
  for (const auto& s : a) ASSERT_TRUE(e.add(s.device_ns, s.arrival_ns));
  const double drift_before = e.estimate().drift_ppm;
  auto r = e.add(b[0].device_ns, b[0].arrival_ns);
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->reset);
  EXPECT_EQ(e.stats().resets, 1u);
  EXPECT_EQ(e.estimate().samples, 1u);
  for (std::size_t i = 1; i < b.size(); ++i) {
    r = e.add(b[i].device_ns, b[i].arrival_ns);
    ASSERT_TRUE(r);
    EXPECT_FALSE(r->reset);
    if (i == 30) {
      // One second in: not enough span for a drift of its own, so the old oscillator's is used.
      EXPECT_FALSE(e.estimate().drift_fitted);
      EXPECT_DOUBLE_EQ(e.estimate().drift_ppm, drift_before);
    }
  }
  EXPECT_EQ(e.stats().resets, 1u);
  EXPECT_LT(std::abs(error_ns(e, b.back())), 60'000);
}

// The device clock jumps forwards (a PTP step, a firmware hiccup): frames arrive "before" they were
// stamped, which latency cannot explain: reset at once.
TEST(ClockOffset, ForwardJumpIsAResetAtOnce) {
  SyntheticClock clock;
  const auto s = clock.run(10.0);
  ClockOffsetEstimator e;
  for (std::size_t i = 0; i < 200; ++i) ASSERT_TRUE(e.add(s[i].device_ns, s[i].arrival_ns));
  const TimestampNs jump = 3'000'000'000;
  auto r = e.add(s[200].device_ns + jump, s[200].arrival_ns);
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->reset);
  for (std::size_t i = 201; i < s.size(); ++i)
    ASSERT_FALSE(e.add(s[i].device_ns + jump, s[i].arrival_ns)->reset);
  EXPECT_EQ(e.stats().resets, 1u);
  // Converted times continue on the host clock across the jump.
  EXPECT_LT(
      std::abs(static_cast<double>(e.to_host(s.back().device_ns + jump).value()) - s.back().true_host_ns),
      200'000);
}

// A small step back (20 ms; the device time still increases): every arrival is late by the step.
// After reset_confirm_ns of host time of that it is a reset, not latency.
TEST(ClockOffset, PersistentLatenessIsAClockStep) {
  SyntheticClock clock;
  clock.outlier_probability = 0;
  const auto s = clock.run(30.0);
  ClockOffsetEstimator e;
  const TimestampNs step = -20'000'000;
  std::size_t reset_at = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const TimestampNs d = s[i].device_ns + (i >= 300 ? step : 0);
    auto r = e.add(d, s[i].arrival_ns);
    ASSERT_TRUE(r);
    if (r->reset) reset_at = i;
  }
  EXPECT_EQ(e.stats().resets, 1u);
  EXPECT_GE(reset_at, 300u + 30u);  // confirmed after about 1 s (30 frames) of late arrivals
  EXPECT_LE(reset_at, 300u + 33u);
  const double err =
      static_cast<double>(e.to_host(s.back().device_ns + step).value()) - s.back().true_host_ns;
  EXPECT_LT(std::abs(err), 60'000);
}

// The host stalls for 2 s: the frames of that time arrive together when it resumes. Late, but
// not a clock step: no reset, and the envelope ignores them.
TEST(ClockOffset, HostStallIsNotAReset) {
  SyntheticClock clock;
  clock.outlier_probability = 0;
  auto s = clock.run(30.0);
  const TimestampNs resume = s[360].arrival_ns;  // frames 300..359 wait until then
  for (std::size_t i = 300; i < 360; ++i) s[i].arrival_ns = resume;
  ClockOffsetEstimator e;
  for (const auto& x : s) ASSERT_FALSE(e.add(x.device_ns, x.arrival_ns)->reset);
  EXPECT_EQ(e.stats().resets, 0u);
  EXPECT_GE(e.stats().outliers, 50u);
  EXPECT_LT(std::abs(error_ns(e, s.back())), 30'000);
}

TEST(ClockOffset, BadInputIsRefusedClearlyAndChangesNothing) {
  SyntheticClock clock;
  const auto s = clock.run(5.0);
  ClockOffsetEstimator e;
  EXPECT_FALSE(e.has_estimate());
  auto none = e.to_host(1000);
  ASSERT_FALSE(none);
  EXPECT_NE(none.error().message.find("ClockOffsetEstimator::to_host(): no samples yet"), std::string::npos);

  for (std::size_t i = 0; i < 100; ++i) ASSERT_TRUE(e.add(s[i].device_ns, s[i].arrival_ns));
  const ClockEstimate before = e.estimate();

  auto back = e.add(s[100].device_ns, s[99].arrival_ns - 1);  // host time going backwards
  ASSERT_FALSE(back);
  EXPECT_NE(back.error().message.find("ClockOffsetEstimator::add(): host_arrival_ns"), std::string::npos);
  EXPECT_NE(back.error().message.find("cannot go backwards"), std::string::npos);
  auto zero = e.add(s[100].device_ns, 0);
  ASSERT_FALSE(zero);
  EXPECT_NE(zero.error().message.find("expected a CLOCK_MONOTONIC time > 0"), std::string::npos);
  auto dup = e.add(s[99].device_ns, s[100].arrival_ns);
  ASSERT_FALSE(dup);
  EXPECT_NE(dup.error().message.find("duplicate"), std::string::npos);

  EXPECT_EQ(e.stats().rejected, 3u);
  EXPECT_EQ(e.stats().resets, 0u);
  const ClockEstimate after = e.estimate();
  EXPECT_EQ(after.offset_ns, before.offset_ns);
  EXPECT_EQ(after.samples, before.samples);
  EXPECT_EQ(after.drift_ppm, before.drift_ppm);
  // And it carries on.
  EXPECT_TRUE(e.add(s[100].device_ns, s[100].arrival_ns));
}

TEST(ClockOffset, BadConfigurationNamesTheField) {
  ClockOffsetConfig c;
  c.window_ns = 0;
  auto e = ClockOffsetEstimator::create(c);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("ClockOffsetEstimator::create(): window_ns: expected > 0"),
            std::string::npos);
  c = {};
  c.initial_drift_ppm = 900;
  e = ClockOffsetEstimator::create(c);
  ASSERT_FALSE(e);
  EXPECT_NE(e.error().message.find("initial_drift_ppm"), std::string::npos);
  c = {};
  c.min_drift_span_ns = c.window_ns + 1;
  EXPECT_FALSE(ClockOffsetEstimator::create(c));
}

// The log row is the estimate at the newest sample, in consistent terms.
TEST(ClockOffset, LogRowIsConsistent) {
  SyntheticClock clock;
  const auto s = clock.run(12.0);
  ClockOffsetEstimator e;
  std::int64_t last_latency = 0;
  for (const auto& x : s) last_latency = e.add(x.device_ns, x.arrival_ns)->latency_ns;
  const ClockOffsetLog row = e.log(CameraId::kRight);
  EXPECT_EQ(row.camera, CameraId::kRight);
  EXPECT_EQ(row.t_device_ns, s.back().device_ns);
  EXPECT_EQ(row.t_host_ns, row.t_device_ns + row.offset_ns);
  EXPECT_EQ(row.t_host_ns, e.to_host(row.t_device_ns).value());
  EXPECT_EQ(row.residual_ns, last_latency);
  EXPECT_EQ(row.residual_ns, s.back().arrival_ns - row.t_host_ns);
  EXPECT_GE(row.residual_ns, 0);
  EXPECT_EQ(row.samples, s.size());
  EXPECT_NEAR(row.drift_ppm, 50.0, 15.0);
  EXPECT_GT(row.uncertainty_ns, 0);
  EXPECT_LT(std::abs(static_cast<double>(row.t_host_ns) - s.back().true_host_ns), 150'000);
}

}  // namespace
}  // namespace augrig
