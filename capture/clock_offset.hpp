// ClockOffsetEstimator: relates one camera's device clock to host CLOCK_MONOTONIC, continuously,
// from what every frame carries: its device timestamp and the host time it arrived at. The model is
//   host = device * (1 + skew) + offset
// (a line in device time). Arrival times are the true host time of the device stamp plus a latency
// that is positive and variable (transfer, driver, scheduling; sometimes tens of ms), so the line
// is fitted to the LOWER ENVELOPE of the (device, arrival) points, not through them: the line
// below all points of a sliding window that is closest to them on average (the linear program of
// Moon, Skelly and Towsley, "Estimation and removal of clock skew from network delay
// measurements", 1999), solved exactly on the lower convex hull. Late samples cannot pull it; a
// constant part of the latency cannot be told from the offset and stays in it. docs/PAIRING.md
// states the model, the defaults and the accuracy the tests prove.
//
// A device clock reset (its timestamp going backwards, jumping forwards past its arrival, or
// stepping so that every arrival is late by the same large amount for reset_confirm_ns) restarts
// the estimate and is counted; the drift estimate survives a reset (same oscillator). Bad input
// (host times going backwards, a repeated device time, a zero host time) is refused with an Error
// and leaves the estimate unchanged.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"

namespace augrig {

struct ClockOffsetConfig {
  std::int64_t window_ns = 30'000'000'000;  // samples older than this (device time) leave the fit
  std::size_t max_samples = 8192;           // hard cap on the window (oldest leave first)
  // Below this span of device time the drift is not estimated; the prior (initial_drift_ppm, or
  // the estimate from before a reset) is used, so a few samples cannot produce a wild slope.
  std::int64_t min_drift_span_ns = 2'000'000'000;
  double initial_drift_ppm = 0.0;
  double max_abs_drift_ppm = 500.0;  // a fitted slope is clamped to this (crystals: tens of ppm)
  std::size_t min_samples = 16;      // with min_drift_span_ns, when the estimate counts as converged
  // A sample whose arrival lies more than this BELOW the envelope cannot be latency: the device
  // clock jumped forwards (reset at once). One more than this ABOVE is a late arrival (counted as
  // an outlier) unless arrivals stay that late for reset_confirm_ns of host time: the clock stepped.
  std::int64_t jump_threshold_ns = 5'000'000;
  std::int64_t reset_confirm_ns = 1'000'000'000;
};

// The current estimate. offset_ns = host - device at the newest sample's device time.
struct ClockEstimate {
  TimestampNs t_device_ns = 0;  // the newest sample's device time
  TimestampNs t_host_ns = 0;    // its host time according to the fit (= t_device_ns + offset_ns)
  std::int64_t offset_ns = 0;
  double drift_ppm = 0.0;  // skew * 1e6: host time advances (1 + drift_ppm 1e-6) ns per device ns
  // Conservative bound of |offset error| at the newest sample: the largest of the smallest
  // latencies above the envelope in 8 equal slices of the window (docs/PAIRING.md). It does not
  // contain the constant part of the latency, which no arrival-time method can see.
  std::int64_t uncertainty_ns = 0;
  std::size_t samples = 0;    // in the window
  std::int64_t span_ns = 0;   // device time covered by the window
  bool drift_fitted = false;  // false: drift_ppm is the prior (span below min_drift_span_ns)
  bool converged = false;     // samples >= min_samples and drift_fitted
};

// What add() made of one sample.
struct ClockSampleResult {
  std::int64_t latency_ns = 0;  // arrival minus the fitted host time: the latency above the envelope
  bool reset = false;           // this sample restarted the estimate
  bool outlier = false;         // latency above jump_threshold_ns
};

struct ClockOffsetStats {
  std::uint64_t samples = 0;   // accepted by add()
  std::uint64_t rejected = 0;  // refused by add() with an Error
  std::uint64_t resets = 0;    // device clock resets detected (the estimate restarted)
  std::uint64_t outliers = 0;  // arrivals later than jump_threshold_ns above the envelope
};

// One row of the clock log (the recorder stores these; recorder/ is not tied to this type yet).
struct ClockOffsetLog {
  TimestampNs t_host_ns = 0;    // host monotonic time the row refers to (fitted, of t_device_ns)
  TimestampNs t_device_ns = 0;  // the newest device timestamp
  CameraId camera = CameraId::kLeft;
  std::int64_t offset_ns = 0;       // host - device at t_device_ns
  double drift_ppm = 0.0;           // as ClockEstimate
  std::int64_t residual_ns = 0;     // the newest sample's latency above the envelope
  std::int64_t uncertainty_ns = 0;  // as ClockEstimate
  std::uint64_t samples = 0;        // in the window
  std::uint64_t resets = 0;         // so far
};

class ClockOffsetEstimator {
 public:
  ClockOffsetEstimator() = default;  // the default configuration (valid)
  // Checks the configuration: "ClockOffsetEstimator::create(): window_ns: ..." on bad values.
  static Expected<ClockOffsetEstimator> create(const ClockOffsetConfig& config);
  static Status validate(const ClockOffsetConfig& config);

  // Adds one frame's (device timestamp, host arrival time). Host times must not decrease and must
  // be > 0; a device time equal to the previous one is refused (a duplicate); a smaller one is a
  // device clock reset.
  Expected<ClockSampleResult> add(TimestampNs device_t_ns, TimestampNs host_arrival_ns);

  bool has_estimate() const { return !window_.empty(); }
  ClockEstimate estimate() const;
  // The host monotonic time of a device timestamp; an Error before the first sample.
  Expected<TimestampNs> to_host(TimestampNs device_t_ns) const;
  ClockOffsetLog log(CameraId camera) const;
  const ClockOffsetStats& stats() const { return stats_; }
  const ClockOffsetConfig& config() const { return config_; }

 private:
  struct Sample {
    TimestampNs device_ns;
    TimestampNs host_ns;
  };
  explicit ClockOffsetEstimator(const ClockOffsetConfig& config) : config_(config) {}
  void restart();
  void refit();
  // (host - device) predicted by the fit at a device time, minus base_offset_ns_.
  double relative_offset_ns(TimestampNs device_t_ns) const;
  std::int64_t latency_of(const Sample& s) const;

  ClockOffsetConfig config_;
  std::deque<Sample> window_;  // device (and host) times increasing
  // Late samples in a row (> jump_threshold_ns above the envelope): a possible clock step.
  std::vector<Sample> late_run_;
  // The fit: host - device = base_offset_ns_ + intercept_ns_ + slope_ * (device - anchor_device_ns_).
  // The integer base keeps full precision when device and host epochs are far apart.
  TimestampNs anchor_device_ns_ = 0;
  std::int64_t base_offset_ns_ = 0;
  double intercept_ns_ = 0.0;
  double slope_ = 0.0;        // skew
  double prior_slope_ = 0.0;  // used while the window is too short to fit the drift
  bool drift_fitted_ = false;
  std::int64_t uncertainty_ns_ = 0;
  std::int64_t last_latency_ns_ = 0;
  bool have_last_ = false;
  Sample last_{0, 0};
  ClockOffsetStats stats_;
};

}  // namespace augrig
