#include "nav/live_fusion.hpp"

#include <algorithm>

#include "nav/ins_engine.hpp"

namespace augrig::nav {

LiveFusion::LiveFusion(const InsConfig& config, const LiveFusionOptions& options)
    : config_(config), options_(options), engine_(std::make_unique<FusionEngine>(config_)) {}

LiveFusion::~LiveFusion() = default;

void LiveFusion::add_imu(const ImuSample& sample) {
  std::lock_guard lock(mutex_);
  if (Status s = engine_->append_imu(sample); !s) {
    ++status_.imu_refused;
    status_.last_error = s.error().message;
    return;
  }
  ++status_.imu_samples;
  status_.t_imu_ns = engine_->imu_end_ns();
  run_filter();
}

void LiveFusion::add_fix(const GpsFix& fix) {
  std::lock_guard lock(mutex_);
  ++status_.fixes;
  status_.t_fix_ns = fix.t_ns + config_.gps_time_offset_ns;
  status_.fix_quality = fix.quality;
  if (Status s = engine_->append_fix(fix); !s) {
    ++status_.fixes_late;
    status_.last_error = s.error().message;
    return;
  }
  if (fix.quality != FixQuality::kInvalid && fix.quality != FixQuality::kDeadReckoning)
    status_.t_valid_fix_ns = status_.t_fix_ns;
  run_filter();
}

void LiveFusion::run_filter() {
  if (!engine_->try_initialise()) return;
  // Certain up to the newest fix (fixes come in order), or up to the newest IMU sample less the
  // longest a fix may take to arrive.
  const TimestampNs t_imu = engine_->imu_end_ns();
  const TimestampNs t_safe = std::max(engine_->last_fix_ns(), t_imu - s_to_ns(options_.max_fix_latency_s));
  if (t_safe > engine_->filter_time_ns()) engine_->advance_to(t_safe);
  // Forget what no query will need; in batches, so the erases stay cheap.
  const TimestampNs keep_from = engine_->filter_time_ns() - s_to_ns(options_.history_s);
  if (engine_->buffered_imu() > 4096 || engine_->buffered_epochs() > 512) engine_->trim_before(keep_from);

  const FusionReport& r = engine_->report();
  status_.initialised = true;
  status_.init_summary = r.init_summary;
  status_.t_filter_ns = engine_->filter_time_ns();
  status_.t_used_fix_ns = engine_->last_used_fix_ns();
  status_.fixes_used = r.fixes_used;
  status_.fixes_rejected = r.fixes_rejected;
  status_.fixes_invalid = r.fixes_invalid;
  status_.buffered_imu = engine_->buffered_imu();
  status_.buffered_epochs = engine_->buffered_epochs();
}

Expected<NavState> LiveFusion::at(TimestampNs t_ns) const {
  std::lock_guard lock(mutex_);
  return engine_->at(t_ns, s_to_ns(options_.max_extrapolation_s));
}

LiveFusionStatus LiveFusion::status() const {
  std::lock_guard lock(mutex_);
  LiveFusionStatus s = status_;
  s.fixes_invalid = engine_->report().fixes_invalid;
  return s;
}

}  // namespace augrig::nav
