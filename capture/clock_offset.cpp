#include "capture/clock_offset.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace augrig {

namespace {

// Slices of the window for the uncertainty (ClockEstimate::uncertainty_ns).
constexpr int kSlices = 8;

struct Point {
  std::int64_t x;  // device time since the window's first sample
  std::int64_t y;  // (host - device) minus the first sample's
};

// Twice the signed area of (a, b, c): > 0 when c lies left of a->b (a counter-clockwise turn).
// Exact: x spans up to the window (~1e11 ns) and y the latencies, so the products need 128 bits.
__int128 cross(const Point& a, const Point& b, const Point& c) {
  return static_cast<__int128>(b.x - a.x) * (c.y - a.y) - static_cast<__int128>(b.y - a.y) * (c.x - a.x);
}

struct Line {
  double slope = 0.0;
  double intercept = 0.0;  // at x = 0
  double at(double x) const { return intercept + slope * x; }
};

// The lower-envelope line of points with strictly increasing x. With `fit_slope`, the line under
// all points with the smallest mean distance to them: the supporting line at the mean x, i.e. the
// lower-hull edge spanning it (Moon et al.'s linear program, solved exactly), its slope clamped
// to +-max_slope. Without, the highest line of slope `prior_slope` under all points.
Line fit_envelope(const std::vector<Point>& pts, bool fit_slope, double prior_slope, double max_slope) {
  auto support = [&pts](double slope) {
    Line l{slope, std::numeric_limits<double>::infinity()};
    for (const Point& p : pts)
      l.intercept = std::min(l.intercept, static_cast<double>(p.y) - slope * static_cast<double>(p.x));
    return l;
  };
  if (!fit_slope || pts.size() < 2) return support(prior_slope);
  std::vector<std::size_t> hull;  // indices into pts
  for (std::size_t i = 0; i < pts.size(); ++i) {
    while (hull.size() >= 2 && cross(pts[hull[hull.size() - 2]], pts[hull.back()], pts[i]) <= 0)
      hull.pop_back();
    hull.push_back(i);
  }
  double mean_x = 0;
  for (const Point& p : pts) mean_x += static_cast<double>(p.x);
  mean_x /= static_cast<double>(pts.size());
  std::size_t j = 0;
  while (j + 2 < hull.size() && static_cast<double>(pts[hull[j + 1]].x) < mean_x) ++j;
  const Point& a = pts[hull[j]];
  const Point& b = pts[hull[j + 1]];
  const double slope = static_cast<double>(b.y - a.y) / static_cast<double>(b.x - a.x);
  // The objective is concave in the slope: a bounded optimum lies on the bound.
  if (std::abs(slope) > max_slope) return support(std::clamp(slope, -max_slope, max_slope));
  return {slope, static_cast<double>(a.y) - slope * static_cast<double>(a.x)};
}

}  // namespace

Status ClockOffsetEstimator::validate(const ClockOffsetConfig& c) {
  const char* where = "ClockOffsetEstimator::create(): ";
  if (c.window_ns <= 0) return make_error(where, "window_ns: expected > 0, got ", c.window_ns);
  if (c.max_samples < 2) return make_error(where, "max_samples: expected >= 2, got ", c.max_samples);
  if (c.min_drift_span_ns < 0 || c.min_drift_span_ns > c.window_ns)
    return make_error(where, "min_drift_span_ns: expected in [0, window_ns = ", c.window_ns, "], got ",
                      c.min_drift_span_ns);
  if (!(c.max_abs_drift_ppm >= 0) || !std::isfinite(c.max_abs_drift_ppm))
    return make_error(where, "max_abs_drift_ppm: expected a finite value >= 0, got ", c.max_abs_drift_ppm);
  if (!std::isfinite(c.initial_drift_ppm) || std::abs(c.initial_drift_ppm) > c.max_abs_drift_ppm)
    return make_error(where, "initial_drift_ppm: expected within +-max_abs_drift_ppm = ", c.max_abs_drift_ppm,
                      ", got ", c.initial_drift_ppm);
  if (c.jump_threshold_ns <= 0)
    return make_error(where, "jump_threshold_ns: expected > 0, got ", c.jump_threshold_ns);
  if (c.reset_confirm_ns <= 0)
    return make_error(where, "reset_confirm_ns: expected > 0, got ", c.reset_confirm_ns);
  return {};
}

Expected<ClockOffsetEstimator> ClockOffsetEstimator::create(const ClockOffsetConfig& config) {
  if (Status s = validate(config); !s) return s.error();
  ClockOffsetEstimator e(config);
  e.prior_slope_ = config.initial_drift_ppm * 1e-6;
  e.slope_ = e.prior_slope_;
  return e;
}

Expected<ClockSampleResult> ClockOffsetEstimator::add(TimestampNs device_t_ns, TimestampNs host_arrival_ns) {
  const char* where = "ClockOffsetEstimator::add(): ";
  if (host_arrival_ns <= 0) {
    ++stats_.rejected;
    return make_error(where, "host_arrival_ns: expected a CLOCK_MONOTONIC time > 0, got ", host_arrival_ns,
                      " (device time ", device_t_ns, ")");
  }
  if (have_last_ && host_arrival_ns < last_.host_ns) {
    ++stats_.rejected;
    return make_error(where, "host_arrival_ns ", host_arrival_ns, " is earlier than the previous sample's ",
                      last_.host_ns, ": host monotonic time cannot go backwards (sample dropped)");
  }
  if (have_last_ && device_t_ns == last_.device_ns) {
    ++stats_.rejected;
    return make_error(where, "device_t_ns ", device_t_ns,
                      " repeats the previous sample's: a duplicate frame (sample dropped)");
  }

  ClockSampleResult result;
  const Sample sample{device_t_ns, host_arrival_ns};
  if (have_last_ && device_t_ns < last_.device_ns) {
    result.reset = true;  // the device clock went backwards: reset or reconnect
    restart();
  } else if (!window_.empty()) {
    const double late_ns = static_cast<double>(host_arrival_ns - device_t_ns - base_offset_ns_) -
                           relative_offset_ns(device_t_ns);
    if (late_ns < -static_cast<double>(config_.jump_threshold_ns)) {
      // Arrived before it could have been stamped: the device clock jumped forwards. A young
      // window may just have started on late samples: restart it quietly then.
      result.reset = window_.size() >= config_.min_samples;
      restart();
    } else if (late_ns > static_cast<double>(config_.jump_threshold_ns)) {
      result.outlier = true;
      ++stats_.outliers;
      late_run_.push_back(sample);
      // Late for long (host time) and for many frames: not a scheduling hiccup but a step back of
      // the device clock. A stalled host delivers its backlog in a burst, which spans no host time.
      if (late_run_.size() >= 3 &&
          late_run_.back().host_ns - late_run_.front().host_ns >= config_.reset_confirm_ns) {
        result.reset = true;
        std::vector<Sample> run = std::move(late_run_);
        restart();
        run.pop_back();  // `sample` itself is added below
        for (const Sample& s : run) window_.push_back(s);
      }
    } else {
      late_run_.clear();
    }
  }
  if (result.reset) ++stats_.resets;

  window_.push_back(sample);
  while (window_.size() > config_.max_samples ||
         (window_.size() > 1 && device_t_ns - window_.front().device_ns > config_.window_ns))
    window_.pop_front();
  refit();
  ++stats_.samples;
  last_ = sample;
  have_last_ = true;
  result.latency_ns = latency_of(sample);
  last_latency_ns_ = result.latency_ns;
  return result;
}

void ClockOffsetEstimator::restart() {
  if (drift_fitted_) prior_slope_ = slope_;  // same oscillator after a reset: keep its drift
  window_.clear();
  late_run_.clear();
  drift_fitted_ = false;
}

double ClockOffsetEstimator::relative_offset_ns(TimestampNs device_t_ns) const {
  return intercept_ns_ + slope_ * static_cast<double>(device_t_ns - anchor_device_ns_);
}

std::int64_t ClockOffsetEstimator::latency_of(const Sample& s) const {
  const double late_ns =
      static_cast<double>(s.host_ns - s.device_ns - base_offset_ns_) - relative_offset_ns(s.device_ns);
  return std::llround(late_ns);
}

void ClockOffsetEstimator::refit() {
  const Sample& first = window_.front();
  anchor_device_ns_ = first.device_ns;
  base_offset_ns_ = first.host_ns - first.device_ns;
  std::vector<Point> pts;
  pts.reserve(window_.size());
  for (const Sample& s : window_)
    pts.push_back({s.device_ns - anchor_device_ns_, s.host_ns - s.device_ns - base_offset_ns_});
  const std::int64_t span_ns = pts.back().x;
  const double max_slope = config_.max_abs_drift_ppm * 1e-6;
  drift_fitted_ = pts.size() >= 2 && span_ns >= config_.min_drift_span_ns;
  const Line line = fit_envelope(pts, drift_fitted_, prior_slope_, max_slope);
  slope_ = line.slope;
  intercept_ns_ = line.intercept;

  // Uncertainty: the smallest latency above the line in each of kSlices equal slices of the
  // window, the largest of those. A wrong slope tilts the slices' minima; a line too high sits
  // below the smallest latency of the newest slice, which is of the size of the other slices'.
  std::array<double, kSlices> slice_min;
  slice_min.fill(std::numeric_limits<double>::infinity());
  for (const Point& p : pts) {
    const int k = span_ns > 0 ? static_cast<int>(std::min<__int128>(
                                    kSlices - 1, static_cast<__int128>(p.x) * kSlices / span_ns))
                              : 0;
    slice_min[k] = std::min(slice_min[k], static_cast<double>(p.y) - line.at(static_cast<double>(p.x)));
  }
  double worst = 0;
  for (double m : slice_min)
    if (std::isfinite(m)) worst = std::max(worst, m);
  uncertainty_ns_ = static_cast<std::int64_t>(std::ceil(worst));
}

ClockEstimate ClockOffsetEstimator::estimate() const {
  ClockEstimate e;
  e.drift_ppm = slope_ * 1e6;
  if (window_.empty()) return e;
  e.t_device_ns = window_.back().device_ns;
  e.offset_ns = base_offset_ns_ + std::llround(relative_offset_ns(e.t_device_ns));
  e.t_host_ns = e.t_device_ns + e.offset_ns;
  e.uncertainty_ns = uncertainty_ns_;
  e.samples = window_.size();
  e.span_ns = window_.back().device_ns - window_.front().device_ns;
  e.drift_fitted = drift_fitted_;
  e.converged = drift_fitted_ && window_.size() >= config_.min_samples;
  return e;
}

Expected<TimestampNs> ClockOffsetEstimator::to_host(TimestampNs device_t_ns) const {
  if (window_.empty())
    return make_error("ClockOffsetEstimator::to_host(): no samples yet: add() frames before converting");
  return device_t_ns + base_offset_ns_ + std::llround(relative_offset_ns(device_t_ns));
}

ClockOffsetLog ClockOffsetEstimator::log(CameraId camera) const {
  const ClockEstimate e = estimate();
  ClockOffsetLog row;
  row.t_host_ns = e.t_host_ns;
  row.t_device_ns = e.t_device_ns;
  row.camera = camera;
  row.offset_ns = e.offset_ns;
  row.drift_ppm = e.drift_ppm;
  row.residual_ns = last_latency_ns_;
  row.uncertainty_ns = e.uncertainty_ns;
  row.samples = e.samples;
  row.resets = stats_.resets;
  return row;
}

}  // namespace augrig
