#include "nav/live_fusion.hpp"

#include <algorithm>

#include "nav/ins_engine.hpp"

namespace augrig::nav {

LiveFusion::LiveFusion(const InsConfig& config, const LiveFusionOptions& options)
    : config_(config), options_(options), engine_(std::make_unique<FusionEngine>(config_)) {}

LiveFusion::~LiveFusion() = default;

void LiveFusion::add_imu(const ImuSample& sample) {
  std::lock_guard lock(mutex_);
  const TimestampNs t_prev_ns = engine_->imu_end_ns();
  if (Status s = engine_->append_imu(sample); !s) {
    ++status_.imu_refused;
    status_.last_error = s.error().message;
    return;
  }
  // A silence in the stream stays known after it ends (data_before()).
  const TimestampNs t_ns = engine_->imu_end_ns();
  if (t_prev_ns != 0 && t_ns - t_prev_ns > kImuGapNs) imu_gaps_.emplace_back(t_prev_ns, t_ns);
  const TimestampNs forget_before = t_ns - s_to_ns(options_.history_s);
  while (!imu_gaps_.empty() && imu_gaps_.front().second < forget_before) imu_gaps_.pop_front();
  run_filter();
}

void LiveFusion::add_fix(const GpsFix& fix) {
  std::lock_guard lock(mutex_);
  status_.t_fix_ns = fix.t_ns + config_.gps_time_offset_ns;
  status_.fix_quality = fix.quality;
  if (Status s = engine_->append_fix(fix); !s) {
    ++status_.fixes_late;
    status_.last_error = s.error().message;
    return;
  }
  if (fix.quality != FixQuality::kInvalid && fix.quality != FixQuality::kDeadReckoning) {
    status_.t_valid_fix_ns = status_.t_fix_ns;
    valid_fix_ns_.push_back(status_.t_fix_ns);
    const TimestampNs forget_before = status_.t_fix_ns - s_to_ns(options_.history_s);
    while (valid_fix_ns_.size() > 1 && valid_fix_ns_[1] <= forget_before) valid_fix_ns_.pop_front();
  }
  run_filter();
}

void LiveFusion::run_filter() {
  if (!engine_->try_initialise()) {
    // No fix to start from yet (a receiver without a fix): keep only recent IMU data.
    if (engine_->buffered_imu() > 4096)
      engine_->trim_before(engine_->imu_end_ns() - s_to_ns(options_.history_s));
    return;
  }
  // Certain up to the newest fix (fixes come in order), or up to the newest IMU sample less the
  // longest a fix may take to arrive.
  const TimestampNs t_imu = engine_->imu_end_ns();
  const TimestampNs t_safe = std::max(engine_->last_fix_ns(), t_imu - s_to_ns(options_.max_fix_latency_s));
  if (t_safe > engine_->filter_time_ns()) engine_->advance_to(t_safe);
  // Forget what no query will need; in batches, so the erases stay cheap.
  const TimestampNs keep_from = engine_->filter_time_ns() - s_to_ns(options_.history_s);
  if (engine_->buffered_imu() > 4096 || engine_->buffered_epochs() > 512) engine_->trim_before(keep_from);
}

Expected<NavState> LiveFusion::at(TimestampNs t_ns) const {
  std::lock_guard lock(mutex_);
  return engine_->at(t_ns, s_to_ns(options_.max_extrapolation_s));
}

LiveFusionStatus LiveFusion::status() const {
  std::lock_guard lock(mutex_);
  // What the filter knows is read from it; status_ holds only what arrived and was refused.
  LiveFusionStatus s = status_;
  const FusionReport& r = engine_->report();
  s.initialised = engine_->initialised();
  if (s.initialised) {
    s.init_summary = r.init_summary;
    s.t_filter_ns = engine_->filter_time_ns();
    s.t_used_fix_ns = engine_->last_used_fix_ns();
    s.converged = r.converged;
    s.t_converged_ns = r.converged_ns;
    s.imu_clock_estimated = r.imu_clock_estimated;
    s.imu_clock_offset_s = r.imu_clock_offset_s;
    s.imu_clock_offset_sigma_s = r.imu_clock_offset_sigma_s;
    s.imu_clock_drift_s_per_s = r.imu_clock_drift_s_per_s;
    s.imu_clock_drift_sigma = r.imu_clock_drift_sigma;
  }
  s.t_imu_ns = engine_->imu_end_ns();
  s.imu_samples = r.imu_samples;
  s.fixes = r.fixes;
  s.fixes_used = r.fixes_used;
  s.fixes_rejected = r.fixes_rejected;
  s.fixes_invalid = r.fixes_invalid;
  s.buffered_imu = engine_->buffered_imu();
  s.buffered_epochs = engine_->buffered_epochs();
  return s;
}

LiveFusionDataAt LiveFusion::data_before(TimestampNs t_ns) const {
  std::lock_guard lock(mutex_);
  LiveFusionDataAt d;
  // The newest valid fix at or before t (fixes arrive in order of their time of validity).
  const auto fix = std::upper_bound(valid_fix_ns_.begin(), valid_fix_ns_.end(), t_ns);
  if (fix != valid_fix_ns_.begin()) d.t_valid_fix_ns = *std::prev(fix);
  // The IMU: the newest sample if t is past it; inside a gap, the sample that opened it; else t
  // itself (the samples around t are spaced less than a gap).
  const TimestampNs t_end_ns = engine_->imu_end_ns();
  if (t_end_ns == 0) return d;
  d.t_imu_ns = std::min(t_ns, t_end_ns);
  const auto gap = std::upper_bound(imu_gaps_.begin(), imu_gaps_.end(), t_ns,
                                    [](TimestampNs t, const auto& g) { return t < g.second; });
  if (gap != imu_gaps_.end() && gap->first < t_ns) d.t_imu_ns = gap->first;
  return d;
}

}  // namespace augrig::nav
