// live_fusion: one aircraft's GPS/INS fusion in real time. The same error-state Kalman filter as
// nav::fuse() (nav/ins.hpp, docs/NAV_FUSION.md), fed sample by sample as the live inputs deliver
// them (nav/live_input.hpp), and asked for the state at a camera frame's mid-exposure time.
//
//   add_imu / add_fix  from the input threads, in each stream's own order; thread-safe.
//   the filter         runs over what is certain: up to the newest fix received, or to the newest
//                      IMU sample less max_fix_latency_s (a fix whose time of validity is older
//                      than that is not waited for; if it comes later it is counted late, unused).
//   at(t)              the filter's last epoch before t mechanized forward over the buffered IMU
//                      increments to t (the covariance propagated with it); a little past the
//                      newest IMU sample the last rates are held (max_extrapolation_s). Frames
//                      usually lie between the filter's time and the newest IMU sample.
//   data_before(t)     the newest IMU sample and valid fix at or before t: what at(t) rests on,
//                      however late it is asked (a frame handled a second late inside a gap is
//                      still in the gap, though data after it have come since).
//   status()           what a display needs to say whether to trust it: the newest fix's age and
//                      quality, the newest IMU sample, counts of what was used and refused.
// Memory stays bounded: epochs and IMU increments older than history_s are forgotten.
#pragma once

#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/ins.hpp"
#include "nav/types.hpp"

namespace augrig::nav {

class FusionEngine;

struct LiveFusionOptions {
  double max_fix_latency_s = 0.3;    // how long the filter waits for a fix after its time of validity
  double max_extrapolation_s = 1.0;  // at(): how far past the newest IMU sample (rates held)
  double history_s = 5.0;            // at(): how far back from the filter's time
};

struct LiveFusionStatus {
  bool initialised = false;
  std::string init_summary;        // how the first state was obtained
  TimestampNs t_filter_ns = 0;     // the filter's time (nav clock)
  TimestampNs t_imu_ns = 0;        // the newest IMU sample (nav clock; 0: none)
  TimestampNs t_fix_ns = 0;        // the newest fix received, valid or not (nav clock; 0: none)
  TimestampNs t_valid_fix_ns = 0;  // the newest valid fix (0: none)
  TimestampNs t_used_fix_ns = 0;   // the newest fix the filter used
  // The filter's attitude sigmas have settled (InsConfig::convergence_window_s); before, its sigma
  // is optimistic (docs/NAV_FUSION.md, "Consistency").
  bool converged = false;
  TimestampNs t_converged_ns = 0;
  // The IMU clock minus GPS time and its drift, with 1-sigma, as the filter knows them at its time
  // (InsConfig::imu_clock.estimate; FusionReport's imu_clock_*).
  bool imu_clock_estimated = false;
  double imu_clock_offset_s = 0, imu_clock_offset_sigma_s = 0;
  double imu_clock_drift_s_per_s = 0, imu_clock_drift_sigma = 0;
  FixQuality fix_quality = FixQuality::kInvalid;   // of the newest fix received
  std::uint64_t imu_samples = 0, imu_refused = 0;  // refused: not after the previous one, non-finite
  std::uint64_t fixes = 0, fixes_used = 0, fixes_rejected = 0, fixes_invalid = 0;
  std::uint64_t fixes_late = 0;  // arrived after the filter had passed their time, or out of order
  std::size_t buffered_imu = 0, buffered_epochs = 0;
  std::string last_error;  // the latest refused sample, in words
};

// The newest data at or before a time (nav clock; 0: none kept).
struct LiveFusionDataAt {
  TimestampNs t_imu_ns = 0;        // the IMU sample
  TimestampNs t_valid_fix_ns = 0;  // the valid fix
};

class LiveFusion {
 public:
  explicit LiveFusion(const InsConfig& config, const LiveFusionOptions& options = {});
  ~LiveFusion();
  LiveFusion(const LiveFusion&) = delete;
  LiveFusion& operator=(const LiveFusion&) = delete;

  // Samples in their stream's time order; a sample that is not is refused and counted (never thrown).
  void add_imu(const ImuSample& sample);
  void add_fix(const GpsFix& fix);

  // The state at t_ns (nav clock). Errors: not initialised yet; t older than the history kept;
  // t more than max_extrapolation_s past the newest IMU sample.
  Expected<NavState> at(TimestampNs t_ns) const;
  LiveFusionStatus status() const;
  // Kept for history_s behind the newest sample; older times get the oldest kept (or 0).
  LiveFusionDataAt data_before(TimestampNs t_ns) const;
  const InsConfig& config() const { return config_; }

 private:
  void run_filter();  // with mutex_ held

  InsConfig config_;
  LiveFusionOptions options_;
  mutable std::mutex mutex_;
  std::unique_ptr<FusionEngine> engine_;
  LiveFusionStatus status_;
  // For data_before(): the valid fixes' times, and the IMU stream's gaps (previous sample, next
  // sample) longer than kImuGapNs; both forgotten after history_s.
  static constexpr TimestampNs kImuGapNs = 50'000'000;
  std::deque<TimestampNs> valid_fix_ns_;
  std::deque<std::pair<TimestampNs, TimestampNs>> imu_gaps_;
};

}  // namespace augrig::nav
