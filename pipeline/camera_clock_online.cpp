#include "pipeline/camera_clock_online.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

namespace augrig::pipeline {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr TimestampNs kMaxRateGapNs = 50'000'000;

using SteadyClock = std::chrono::steady_clock;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// Linear between the two samples about t in a time-ordered sequence; nullopt outside or across a gap.
template <class Seq>
std::optional<Eigen::Vector3d> interpolate(const Seq& s, TimestampNs t_ns) {
  if (s.empty() || t_ns < s.front().first || t_ns > s.back().first) return std::nullopt;
  const auto hi =
      std::lower_bound(s.begin(), s.end(), t_ns, [](const auto& e, TimestampNs t) { return e.first < t; });
  if (hi->first == t_ns) return hi->second;
  const auto lo = std::prev(hi);
  if (hi->first - lo->first > kMaxRateGapNs) return std::nullopt;
  const double a = static_cast<double>(t_ns - lo->first) / static_cast<double>(hi->first - lo->first);
  return Eigen::Vector3d((1 - a) * lo->second + a * hi->second);
}

}  // namespace

// ---- TankerRates -------------------------------------------------------------------------------

void TankerRates::add_increment(TimestampNs t_gps_end_ns, double dt_s, const Eigen::Vector3d& dtheta_rad) {
  if (!(dt_s > 0) || !dtheta_rad.allFinite()) return;
  // The increment's mean rate belongs to its middle: at its end it would add half an IMU period.
  add(t_gps_end_ns - s_to_ns(0.5 * dt_s), dtheta_rad / dt_s);
}

void TankerRates::add(TimestampNs t_gps_ns, const Eigen::Vector3d& omega_body_radps) {
  std::lock_guard lock(mutex_);
  if (!samples_.empty() && t_gps_ns <= samples_.back().first) return;  // out of order: refused
  samples_.emplace_back(t_gps_ns, omega_body_radps);
  while (samples_.size() > 2 && samples_.front().first < t_gps_ns - keep_ns_) samples_.pop_front();
}

std::optional<Eigen::Vector3d> TankerRates::at(TimestampNs t_gps_ns) const {
  std::lock_guard lock(mutex_);
  return interpolate(samples_, t_gps_ns);
}

TimestampNs TankerRates::newest_ns() const {
  std::lock_guard lock(mutex_);
  return samples_.empty() ? 0 : samples_.back().first;
}

nav::AngularRateFunction TankerRates::snapshot(TimestampNs t0_ns, TimestampNs t1_ns) const {
  auto copy = std::make_shared<std::vector<std::pair<TimestampNs, Eigen::Vector3d>>>();
  {
    std::lock_guard lock(mutex_);
    auto a = std::lower_bound(samples_.begin(), samples_.end(), t0_ns,
                              [](const auto& e, TimestampNs t) { return e.first < t; });
    if (a != samples_.begin()) --a;
    for (auto it = a; it != samples_.end(); ++it) {
      copy->push_back(*it);
      if (it->first > t1_ns) break;
    }
  }
  return [copy](TimestampNs t_ns) { return interpolate(*copy, t_ns); };
}

// ---- status ------------------------------------------------------------------------------------

std::string_view to_string(CameraClockState s) {
  switch (s) {
    case CameraClockState::kCollecting:
      return "collecting";
    case CameraClockState::kNotObservable:
      return "not observable";
    case CameraClockState::kEstimated:
      return "estimated";
    case CameraClockState::kApplied:
      return "applied";
  }
  return "?";
}

namespace {
const nav::CameraClockEstimate* shown(const CameraClockOnlineStatus& s) {
  return s.applied ? &*s.applied : s.latest ? &*s.latest : nullptr;
}
}  // namespace

double CameraClockOnlineStatus::offset_ms() const {
  const nav::CameraClockEstimate* e = shown(*this);
  return e ? e->offset_s * 1e3 : kNaN;
}
double CameraClockOnlineStatus::sigma_ms() const {
  const nav::CameraClockEstimate* e = shown(*this);
  return e ? e->offset_sigma_s * 1e3 : kNaN;
}
double CameraClockOnlineStatus::drift_ppm() const {
  const nav::CameraClockEstimate* e = shown(*this);
  return e && e->drift_observable ? e->drift_ppm : kNaN;
}
double CameraClockOnlineStatus::drift_sigma_ppm() const {
  const nav::CameraClockEstimate* e = shown(*this);
  return e && e->drift_observable ? e->drift_sigma_ppm : kNaN;
}

std::string CameraClockOnlineStatus::text() const {
  std::string t = name + ": ";
  if (shown(*this)) {
    t += fmt("%+.3f", offset_ms()) + " +- " + fmt("%.3f", sigma_ms()) + " ms";
    t += std::isnan(drift_ppm())
             ? std::string(", drift not observable")
             : ", drift " + fmt("%+.1f", drift_ppm()) + " +- " + fmt("%.1f", drift_sigma_ppm()) + " ppm";
    t += ", " + std::string(to_string(state));
    if (state == CameraClockState::kApplied && !reason.empty()) t += " (latest fit: " + reason + ")";
    return t;
  }
  t += std::string(to_string(state));
  if (!reason.empty()) t += " (" + reason + ")";
  t += "; prior " + fmt("%+.3f", prior_offset_s * 1e3) + " ms in use";
  return t;
}

std::string CameraClockOnlineStatus::hud_text() const {
  std::string t = name + "  " + std::string(to_string(state));
  if (shown(*this)) {
    t += "  " + fmt("%+.3f", offset_ms()) + " +- " + fmt("%.3f", sigma_ms()) + " ms";
    if (!std::isnan(drift_ppm()))
      t += ", drift " + fmt("%+.1f", drift_ppm()) + " +- " + fmt("%.1f", drift_sigma_ppm()) + " ppm";
    if (state != CameraClockState::kApplied) t += "; prior " + fmt("%+.3f", prior_offset_s * 1e3) + " ms";
    return t;
  }
  // The reasons read "what: why"; the why is what fits.
  const std::size_t colon = reason.rfind(": ");
  if (!reason.empty()) t += ": " + (colon == std::string::npos ? reason : reason.substr(colon + 2));
  return t + "; prior " + fmt("%+.3f", prior_offset_s * 1e3) + " ms";
}

// ---- CameraClockOnline -------------------------------------------------------------------------

struct CameraClockOnline::Impl {
  struct Pending {
    TimestampNs t_camera_ns = 0;
    Image image;
    SteadyClock::time_point queued;
  };

  // Set at construction.
  int camera = 0;
  std::string name;
  Eigen::Matrix3d R_cam_body;
  TimestampNs prior_ns = 0;
  std::shared_ptr<const TankerRates> rates;
  CameraClockOnlineOptions opt;
  std::unique_ptr<nav::CameraRotationTracker> tracker;
  // The queue and the worker.
  std::mutex mutex;
  std::condition_variable cv, idle_cv;
  std::deque<Pending> queue;
  bool busy = false, stop = false;
  TimestampNs last_taken_ns = std::numeric_limits<TimestampNs>::min();
  std::thread worker;
  // The worker's own.
  std::deque<nav::FrameRotation> window;
  TimestampNs next_fit_ns = std::numeric_limits<TimestampNs>::min();
  // What others read.
  mutable std::mutex status_mutex;
  CameraClockOnlineStatus status;
  std::vector<std::string> changes;

  void run();
  void process(Pending& p);
  void fit();
  void update(Expected<nav::CameraClockEstimate> est, double ms);
  bool rates_cover(const Pending& p) const {
    const TimestampNs need = p.t_camera_ns - prior_ns + s_to_ns(opt.clock.search_s) + 20'000'000;
    return rates->newest_ns() >= need;
  }
};

CameraClockOnline::CameraClockOnline(int camera, std::string name, const CameraModel& model,
                                     const Eigen::Matrix3d& R_cam_body, TimestampNs prior_offset_ns,
                                     std::shared_ptr<const TankerRates> rates,
                                     nav::GroundMotionFunction ground,
                                     const CameraClockOnlineOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.camera = camera;
  s.name = std::move(name);
  s.R_cam_body = R_cam_body;
  s.prior_ns = prior_offset_ns;
  s.rates = std::move(rates);
  s.opt = options;
  s.opt.clock.prior_offset_s = ns_to_s(prior_offset_ns);
  const std::shared_ptr<const TankerRates> r = s.rates;
  s.tracker = std::make_unique<nav::CameraRotationTracker>(model, R_cam_body, s.opt.clock, std::move(ground),
                                                           [r](TimestampNs t) { return r->at(t); });
  s.status.camera = camera;
  s.status.name = s.name;
  s.status.prior_offset_s = s.opt.clock.prior_offset_s;
  s.status.reason = "no frames yet";
  if (!s.opt.synchronous) s.worker = std::thread([&s] { s.run(); });
}

CameraClockOnline::~CameraClockOnline() {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->stop = true;
  }
  impl_->cv.notify_all();
  if (impl_->worker.joinable()) impl_->worker.join();
}

bool CameraClockOnline::offer(TimestampNs t_camera_ns, ConstImageView image) {
  Impl& s = *impl_;
  {
    std::lock_guard lock(s.status_mutex);
    ++s.status.frames_offered;
  }
  {
    // The pipeline is the only caller: what is checked here still holds when the copy is queued.
    std::lock_guard lock(s.mutex);
    if (t_camera_ns < s.last_taken_ns + s_to_ns(s.opt.min_interval_s)) return false;  // decimated
    if (!s.opt.synchronous && static_cast<int>(s.queue.size()) >= s.opt.queue_frames) {
      std::lock_guard st(s.status_mutex);
      ++s.status.frames_skipped_busy;
      return false;
    }
    s.last_taken_ns = t_camera_ns;
  }
  Impl::Pending p{t_camera_ns, Image::copy_of(image), SteadyClock::now()};
  {
    std::lock_guard st(s.status_mutex);
    ++s.status.frames_taken;
  }
  if (s.opt.synchronous) {
    s.process(p);
    return true;
  }
  {
    std::lock_guard lock(s.mutex);
    s.queue.push_back(std::move(p));
  }
  s.cv.notify_all();
  return true;
}

// The worker: the oldest frame once the nav rates cover it (the tracker's nav gate looks
// search_s beyond it), or once it has waited rate_wait_s.
void CameraClockOnline::Impl::run() {
  std::unique_lock lock(mutex);
  for (;;) {
    cv.wait(lock, [&] { return stop || !queue.empty(); });
    if (stop) break;
    const bool waited =
        std::chrono::duration<double>(SteadyClock::now() - queue.front().queued).count() >= opt.rate_wait_s;
    if (!rates_cover(queue.front()) && !waited) {
      cv.wait_for(lock, std::chrono::milliseconds(10));
      continue;
    }
    Pending p = std::move(queue.front());
    queue.pop_front();
    busy = true;
    lock.unlock();
    process(p);
    lock.lock();
    busy = false;
    idle_cv.notify_all();
  }
  busy = false;
  idle_cv.notify_all();
}

void CameraClockOnline::Impl::process(Pending& p) {
  const Status st = tracker->add_frame(p.t_camera_ns, p.image.cview());
  std::vector<nav::FrameRotation> got = tracker->take_rotations();
  {
    std::lock_guard lock(status_mutex);
    if (st) ++status.frames_tracked;
    status.rotations += got.size();
    if (status.fits == 0)
      status.reason = "until the first fit, after " + fmt("%g", opt.refit_every_s) + " s of frames";
  }
  for (nav::FrameRotation& r : got) window.push_back(r);
  if (next_fit_ns == std::numeric_limits<TimestampNs>::min())
    next_fit_ns = p.t_camera_ns + s_to_ns(opt.refit_every_s);
  if (p.t_camera_ns >= next_fit_ns) {
    next_fit_ns = p.t_camera_ns + s_to_ns(opt.refit_every_s);
    fit();
  }
}

// A fit over the window's rotations, on a copy of the rates they need.
void CameraClockOnline::Impl::fit() {
  if (!window.empty()) {
    const TimestampNs oldest = window.back().t1_camera_ns - s_to_ns(opt.window_s);
    while (!window.empty() && window.front().t0_camera_ns < oldest) window.pop_front();
  }
  const auto min_intervals = static_cast<std::size_t>(std::max(opt.clock.min_intervals, 8));
  if (window.size() < min_intervals) {
    std::lock_guard lock(status_mutex);
    status.reason = std::to_string(window.size()) + " of " + std::to_string(min_intervals) +
                    " frame intervals with a rotation";
    return;
  }
  const std::vector<nav::FrameRotation> rot(window.begin(), window.end());
  const TimestampNs reach = s_to_ns(opt.clock.search_s + opt.clock.derivative_step_s) + 100'000'000;
  const nav::AngularRateFunction omega = rates->snapshot(rot.front().t0_camera_ns - prior_ns - reach,
                                                         rot.back().t1_camera_ns - prior_ns + reach);
  const auto t0 = SteadyClock::now();
  Expected<nav::CameraClockEstimate> est = nav::fit_camera_clock(rot, R_cam_body, omega, opt.clock);
  update(std::move(est), std::chrono::duration<double, std::milli>(SteadyClock::now() - t0).count());
}

// The fit's outcome into the state: applied once confident (and replaced by later confident fits;
// held through unconfident ones).
void CameraClockOnline::Impl::update(Expected<nav::CameraClockEstimate> est, double ms) {
  std::lock_guard lock(status_mutex);
  ++status.fits;
  status.last_fit_ms = ms;
  const CameraClockState before = status.state;
  const bool had_applied = status.applied.has_value();
  if (!est) {
    status.reason = est.error().message;
    if (!had_applied) status.state = CameraClockState::kCollecting;
  } else if (!est->observable) {
    status.reason = est->reason;
    status.latest.reset();
    if (!had_applied) status.state = CameraClockState::kNotObservable;
  } else {
    status.latest = *est;
    status.reason.clear();
    if (est->offset_sigma_s <= opt.apply_sigma_s) {
      status.applied = *est;
      status.t_applied_camera_ns = window.back().t1_camera_ns;
      status.state = CameraClockState::kApplied;
    } else if (had_applied) {
      status.reason = "estimated " + fmt("%+.3f", est->offset_s * 1e3) + " +- " +
                      fmt("%.3f", est->offset_sigma_s * 1e3) + " ms, above the " +
                      fmt("%.3f", opt.apply_sigma_s * 1e3) + " ms to apply";
    } else {
      status.state = CameraClockState::kEstimated;
    }
  }
  if (status.state != before || (status.applied && !had_applied))
    changes.push_back("camera clock " + status.text() +
                      (status.applied && est && est->observable
                           ? " (1-sigma " + nav::describe_sigma(*est) + ")"
                           : std::string()));
}

TimestampNs CameraClockOnline::offset_ns(TimestampNs t_camera_ns) const {
  std::lock_guard lock(impl_->status_mutex);
  return impl_->status.applied ? impl_->status.applied->offset_at_ns(t_camera_ns) : impl_->prior_ns;
}

bool CameraClockOnline::applied() const {
  std::lock_guard lock(impl_->status_mutex);
  return impl_->status.applied.has_value();
}

CameraClockOnlineStatus CameraClockOnline::status() const {
  std::lock_guard lock(impl_->status_mutex);
  return impl_->status;
}

std::vector<std::string> CameraClockOnline::take_changes() {
  std::lock_guard lock(impl_->status_mutex);
  std::vector<std::string> out;
  out.swap(impl_->changes);
  return out;
}

void CameraClockOnline::wait_idle() {
  Impl& s = *impl_;
  std::unique_lock lock(s.mutex);
  s.cv.notify_all();
  s.idle_cv.wait_for(lock, std::chrono::seconds(60), [&] { return s.stop || (s.queue.empty() && !s.busy); });
}

// ---- CameraClocks ------------------------------------------------------------------------------

CameraClocks::CameraClocks(const Rig& rig, std::vector<TimestampNs> prior_offset_ns,
                           std::function<std::optional<TimestampNs>(TimestampNs)> host_to_nav,
                           nav::GroundMotionFunction ground, const CameraClockOnlineOptions& options)
    : rig_(rig),
      prior_offset_ns_(std::move(prior_offset_ns)),
      host_timed_(prior_offset_ns_.empty()),
      host_to_nav_(std::move(host_to_nav)),
      ground_(std::move(ground)),
      options_(options),
      rates_(std::make_shared<TankerRates>(options.window_s + 60)) {
  if (!host_timed_) prior_offset_ns_.resize(2, 0);
}

CameraClocks::~CameraClocks() = default;

// Camera c's estimator, made at its first frame whose prior is known.
CameraClockOnline* CameraClocks::camera(int c, TimestampNs mid_host_ns) {
  std::lock_guard lock(mutex_);
  auto& cam = cameras_[static_cast<std::size_t>(c)];
  if (cam) return cam.get();
  TimestampNs prior = 0;
  if (host_timed_) {
    const std::optional<TimestampNs> t_nav = host_to_nav_ ? host_to_nav_(mid_host_ns) : std::nullopt;
    if (!t_nav) return nullptr;  // no GPS fix yet to relate host time to GPS time
    prior = mid_host_ns - *t_nav;
  } else {
    prior = prior_offset_ns_[static_cast<std::size_t>(c)];
  }
  const RigCamera& rc = rig_.cameras[static_cast<std::size_t>(c)];
  cam = std::make_unique<CameraClockOnline>(c, c == 0 ? "left" : "right", rc.model,
                                            rc.T_body_cam.R().transpose(), prior, rates_, ground_, options_);
  return cam.get();
}

void CameraClocks::offer(const StereoFrame& frame, TimestampNs mid_host_left_ns,
                         TimestampNs mid_host_right_ns) {
  for (int c = 0; c < 2; ++c) {
    const Frame& f = c == 0 ? frame.left : frame.right;
    const TimestampNs mid_host = c == 0 ? mid_host_left_ns : mid_host_right_ns;
    const TimestampNs t = host_timed_ ? mid_host : f.t_ns;
    if (t == 0 || f.image.empty()) continue;
    if (CameraClockOnline* cam = camera(c, mid_host)) cam->offer(t, f.image.cview());
  }
}

std::optional<TimestampNs> CameraClocks::to_gps(int camera, TimestampNs t_camera_ns) const {
  if (t_camera_ns == 0) return std::nullopt;
  std::lock_guard lock(mutex_);
  const auto& cam = cameras_[static_cast<std::size_t>(camera)];
  if (!cam || !cam->applied()) return std::nullopt;
  return t_camera_ns - cam->offset_ns(t_camera_ns);
}

std::vector<CameraClockOnlineStatus> CameraClocks::status() const {
  std::lock_guard lock(mutex_);
  std::vector<CameraClockOnlineStatus> out;
  for (int c = 0; c < 2; ++c) {
    const auto& cam = cameras_[static_cast<std::size_t>(c)];
    if (cam) {
      out.push_back(cam->status());
      continue;
    }
    CameraClockOnlineStatus s;
    s.camera = c;
    s.name = c == 0 ? "left" : "right";
    s.reason = host_timed_ ? "no frame with a nav clock yet" : "no frames yet";
    if (!host_timed_) s.prior_offset_s = ns_to_s(prior_offset_ns_[static_cast<std::size_t>(c)]);
    out.push_back(s);
  }
  return out;
}

std::vector<std::string> CameraClocks::take_changes() {
  std::lock_guard lock(mutex_);
  std::vector<std::string> out;
  for (const auto& cam : cameras_)
    if (cam)
      for (std::string& s : cam->take_changes()) out.push_back(std::move(s));
  return out;
}

std::vector<std::pair<std::string, std::string>> CameraClocks::diagnostics() const {
  std::vector<std::pair<std::string, std::string>> kv;
  for (const CameraClockOnlineStatus& s : status()) {
    const std::string k = "camera" + std::to_string(s.camera) + "_clock_";
    auto num = [](double v, const char* f) { return std::isnan(v) ? std::string("nan") : fmt(f, v); };
    kv.emplace_back(k + "offset_ms", num(s.offset_ms(), "%.4f"));
    kv.emplace_back(k + "sigma_ms", num(s.sigma_ms(), "%.4f"));
    kv.emplace_back(k + "drift_ppm", num(s.drift_ppm(), "%.2f"));
    kv.emplace_back(k + "drift_sigma_ppm", num(s.drift_sigma_ppm(), "%.2f"));
    kv.emplace_back(k + "state", std::string(to_string(s.state)));
    kv.emplace_back(k + "applied", s.applied ? "1" : "0");
    kv.emplace_back(k + "prior_offset_ms", fmt("%.4f", s.prior_offset_s * 1e3));
    kv.emplace_back(k + "frames_skipped", std::to_string(s.frames_skipped_busy));
  }
  return kv;
}

std::vector<std::string> CameraClocks::take_record_lines() {
  std::vector<std::string> lines;
  for (const CameraClockOnlineStatus& s : status()) {
    std::uint64_t& seen = recorded_fits_[static_cast<std::size_t>(s.camera)];
    if (s.fits == seen) continue;
    seen = s.fits;
    const nav::CameraClockEstimate* e = s.latest ? &*s.latest : nullptr;
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "camera_clock camera=%s state=%s applied=%d offset_ms=%.4f sigma_ms=%.4f drift_ppm=%.3f "
                  "drift_sigma_ppm=%.3f latest_offset_ms=%.4f latest_sigma_ms=%.4f reference_camera_ns=%lld "
                  "prior_offset_ms=%.4f intervals=%d frames_tracked=%llu frames_skipped=%llu",
                  s.name.c_str(), std::string(to_string(s.state)).c_str(), s.applied ? 1 : 0, s.offset_ms(),
                  s.sigma_ms(), s.drift_ppm(), s.drift_sigma_ppm(), e ? e->offset_s * 1e3 : kNaN,
                  e ? e->offset_sigma_s * 1e3 : kNaN,
                  static_cast<long long>(s.applied ? s.applied->reference_camera_ns
                                         : e       ? e->reference_camera_ns
                                                   : 0),
                  s.prior_offset_s * 1e3, e ? e->intervals_used : 0,
                  static_cast<unsigned long long>(s.frames_tracked),
                  static_cast<unsigned long long>(s.frames_skipped_busy));
    lines.emplace_back(buf);
    if (!s.reason.empty()) lines.back() += " reason=\"" + s.reason + "\"";
  }
  return lines;
}

void CameraClocks::wait_idle() {
  std::array<CameraClockOnline*, 2> cams{};
  {
    std::lock_guard lock(mutex_);
    for (std::size_t c = 0; c < 2; ++c) cams[c] = cameras_[c].get();
  }
  for (CameraClockOnline* cam : cams)
    if (cam) cam->wait_idle();
}

}  // namespace augrig::pipeline
