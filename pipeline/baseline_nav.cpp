#include "pipeline/baseline_nav.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Dense>

#include "nav/geodesy.hpp"

namespace augrig::pipeline {

namespace {

constexpr TimestampNs kWeekNs = 604800LL * 1'000'000'000LL;

// GPS time of a time of week: the week that puts it nearest `near_ns`.
TimestampNs resolve_tow(std::uint32_t itow_ms, TimestampNs near_ns) {
  const TimestampNs tow_ns = static_cast<TimestampNs>(itow_ms) * 1'000'000;
  const double weeks = std::round(static_cast<double>(near_ns - tow_ns) / static_cast<double>(kWeekNs));
  return static_cast<TimestampNs>(weeks) * kWeekNs + tow_ns;
}

}  // namespace

std::string RoverLog::summary() const {
  std::ostringstream o;
  o << path << ": " << counts.frames << " UBX frames (" << measurements.size() << " NAV-RELPOSNED, " << pvt
    << " NAV-PVT, " << other_frames << " other), " << counts.bad_checksums << " bad checksums, "
    << counts.skipped_bytes << " bytes skipped, " << truncated_bytes << " bytes cut off at the end";
  return o.str();
}

Expected<RoverLog> load_rover_log(const std::string& path, TimestampNs reference_gps_ns) {
  auto log = nav::read_ubx_file(path);
  if (!log) return make_error("pipeline::load_rover_log(): ", log.error().message);
  if (log->relposned.empty())
    return make_error("pipeline::load_rover_log(): ", path,
                      ": no NAV-RELPOSNED message (class 0x01 id 0x3C): not a moving-baseline rover's log (",
                      log->counts.frames, " UBX frames read)");
  RoverLog r;
  r.path = path;
  r.counts = log->counts;
  r.pvt = log->pvt.size();
  for (const auto& [id, n] : log->other_frames) r.other_frames += n;
  r.truncated_bytes = log->truncated_bytes;
  r.issues = log->issues;
  TimestampNs near_ns = reference_gps_ns;
  for (const nav::UbxRelPosNed& m : log->relposned) {
    nav::BaselineMeasurement b;
    b.t_ns = resolve_tow(m.itow_ms, near_ns);
    near_ns = b.t_ns;  // a log that crosses the week's end goes on into the next week
    b.ned_m = m.rel_pos_ned_m;
    b.sigma_ned_m = m.acc_ned_m;
    b.carr_soln = m.carr_soln;
    b.valid = m.rel_pos_valid && m.gnss_fix_ok;
    r.measurements.push_back(b);
  }
  return r;
}

InsBaseline ins_baseline(const nav::NavState& tanker, const nav::NavState& receiver,
                         const Eigen::Vector3d& tanker_antenna_body_m,
                         const Eigen::Vector3d& receiver_antenna_body_m) {
  const Eigen::Vector3d a = tanker.p_ecef_m + tanker.q_ecef_body * tanker_antenna_body_m;
  const Eigen::Vector3d b = receiver.p_ecef_m + receiver.q_ecef_body * receiver_antenna_body_m;
  const nav::Geodetic g = nav::geodetic_from_ecef(a);
  InsBaseline out;
  out.R_ecef_ned = nav::R_ecef_ned(g.lat_rad, g.lon_rad);
  out.ned_m = out.R_ecef_ned.transpose() * (b - a);
  const Eigen::Matrix3d P =
      tanker.P.block<3, 3>(nav::kErrPos, nav::kErrPos) + receiver.P.block<3, 3>(nav::kErrPos, nav::kErrPos);
  out.cov_ned_m2 = out.R_ecef_ned.transpose() * P * out.R_ecef_ned;
  return out;
}

void apply_baseline_correction(const nav::BaselineCorrection& c, const InsBaseline& ib, nav::NavState& tanker,
                               nav::NavState& receiver) {
  const Eigen::Matrix3d cov = 0.5 * (c.cov_ned_m2 + c.cov_ned_m2.transpose());
  receiver.p_ecef_m += ib.R_ecef_ned * c.e_ned_m;
  // The relative position's covariance now: all of it on the receiver, none on the tanker, and no
  // position cross terms (the correction's error is not the solutions').
  for (nav::NavState* s : {&tanker, &receiver}) {
    s->P.middleRows(nav::kErrPos, 3).setZero();
    s->P.middleCols(nav::kErrPos, 3).setZero();
  }
  receiver.P.block<3, 3>(nav::kErrPos, nav::kErrPos) = ib.R_ecef_ned * cov * ib.R_ecef_ned.transpose();
}

Expected<BaselineNav> BaselineNav::fuse(const std::vector<nav::BaselineMeasurement>& measurements,
                                        const nav::NavTrajectory& tanker, const nav::NavTrajectory& receiver,
                                        const Eigen::Vector3d& tanker_antenna_body_m,
                                        const Eigen::Vector3d& receiver_antenna_body_m,
                                        const nav::BaselineFusionOptions& options) {
  BaselineNav n;
  n.tanker_antenna_m_ = tanker_antenna_body_m;
  n.receiver_antenna_m_ = receiver_antenna_body_m;
  struct Both {
    nav::NavState tk, rx;
  };
  auto states = [&](TimestampNs t) -> std::optional<Both> {
    auto tk = tanker.at(t);
    auto rx = receiver.at(t);
    if (!tk || !rx) return std::nullopt;
    return Both{*tk, *rx};
  };
  auto fusion = nav::BaselineFusion::fuse(
      measurements,
      [&](TimestampNs t) -> std::optional<nav::InsBaselineSample> {
        const auto s = states(t);
        if (!s) return std::nullopt;
        return ins_baseline(s->tk, s->rx, n.tanker_antenna_m_, n.receiver_antenna_m_);
      },
      options);
  if (!fusion) return make_error("pipeline::BaselineNav::fuse(): ", fusion.error().message);
  n.fusion_ = std::move(*fusion);
  return n;
}

bool BaselineNav::correct(TimestampNs t_nav_ns, nav::NavState& tanker, nav::NavState& receiver) const {
  if (!fusion_) return false;
  const auto c = fusion_->at(t_nav_ns);
  if (!c) return false;
  apply_baseline_correction(*c, ins_baseline(tanker, receiver, tanker_antenna_m_, receiver_antenna_m_),
                            tanker, receiver);
  return true;
}

// ---- Live ---------------------------------------------------------------------------------------

std::string LiveBaselineReport::summary() const {
  std::ostringstream o;
  o << "moving baseline: " << received
    << " vectors received: " << received - invalid - float_skipped - out_of_order << " usable, " << invalid
    << " without a valid vector, " << float_skipped << " float skipped, " << out_of_order << " out of order";
  return o.str();
}

LiveBaseline::LiveBaseline(const nav::BaselineFusionOptions& options, double window_s,
                           double min_relative_sigma_mps)
    : options_(options),
      window_ns_(static_cast<TimestampNs>(window_s * 1e9)),
      min_relative_sigma_mps_(min_relative_sigma_mps) {}

void LiveBaseline::add(const nav::BaselineMeasurement& m) {
  std::lock_guard lock(mutex_);
  ++report_.received;
  if (const nav::BaselineUse use = nav::baseline_use(m, options_); use != nav::BaselineUse::kUse) {
    ++(use == nav::BaselineUse::kInvalid ? report_.invalid : report_.float_skipped);
    return;
  }
  if (m.t_ns <= last_ns_) {
    ++report_.out_of_order;
    return;
  }
  last_ns_ = m.t_ns;
  recent_.push_back(m);
  while (!recent_.empty() && recent_.front().t_ns < m.t_ns - 2 * window_ns_) recent_.pop_front();
}

LiveBaselineReport LiveBaseline::report() const {
  std::lock_guard lock(mutex_);
  return report_;
}

std::optional<nav::BaselineCorrection> LiveBaseline::at(
    TimestampNs t_ns, const nav::NavState& tanker, const nav::NavState& receiver, const StatesAt& states_at,
    const Eigen::Vector3d& tanker_antenna_body_m, const Eigen::Vector3d& receiver_antenna_body_m) const {
  std::vector<nav::BaselineMeasurement> ms;
  {
    std::lock_guard lock(mutex_);
    for (const nav::BaselineMeasurement& m : recent_)
      if (m.t_ns <= t_ns && m.t_ns >= t_ns - window_ns_) ms.push_back(m);
  }
  if (ms.empty()) return std::nullopt;
  const InsBaseline now = ins_baseline(tanker, receiver, tanker_antenna_body_m, receiver_antenna_body_m);
  const Eigen::Matrix3d R_ned_ecef = now.R_ecef_ned.transpose();
  // The relative velocity's uncertainty (NED variances), for the weight of an older vector.
  // A forward filter's velocity sigma is optimistic between its jumps: at least min_relative_sigma_mps.
  const Eigen::Vector3d var_v = (R_ned_ecef *
                                 (tanker.P.block<3, 3>(nav::kErrVel, nav::kErrVel) +
                                  receiver.P.block<3, 3>(nav::kErrVel, nav::kErrVel)) *
                                 now.R_ecef_ned)
                                    .diagonal()
                                    .cwiseMax(min_relative_sigma_mps_ * min_relative_sigma_mps_);
  struct Carried {
    Eigen::Vector3d b, var;
  };
  std::vector<Carried> carried;
  for (const nav::BaselineMeasurement& m : ms) {
    nav::NavState tk, rx;
    if (!states_at(m.t_ns, tk, rx)) continue;
    const double dt = static_cast<double>(t_ns - m.t_ns) / 1e9;
    // The antennas' relative motion from t_k to t: velocities (trapezoid) and attitudes (lever arms).
    const Eigen::Vector3d motion_ecef =
        0.5 * dt * ((receiver.v_ecef_mps + rx.v_ecef_mps) - (tanker.v_ecef_mps + tk.v_ecef_mps)) +
        (receiver.q_ecef_body * receiver_antenna_body_m - rx.q_ecef_body * receiver_antenna_body_m) -
        (tanker.q_ecef_body * tanker_antenna_body_m - tk.q_ecef_body * tanker_antenna_body_m);
    Carried c;
    c.b = m.ned_m + R_ned_ecef * motion_ecef;
    const Eigen::Matrix3d R = nav::baseline_noise(m, options_);
    c.var = R.diagonal() + dt * dt * var_v;
    carried.push_back(c);
  }
  if (carried.empty()) return std::nullopt;
  // Weighted mean per axis; once more without those beyond 5 sigma of it.
  auto mean = [&](const std::vector<bool>& keep, Eigen::Vector3d& b, Eigen::Vector3d& var) {
    Eigen::Vector3d sw = Eigen::Vector3d::Zero(), swb = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < carried.size(); ++i) {
      if (!keep[i]) continue;
      const Eigen::Vector3d w = carried[i].var.cwiseInverse();
      sw += w;
      swb += w.cwiseProduct(carried[i].b);
    }
    b = swb.cwiseQuotient(sw);
    var = sw.cwiseInverse();
  };
  std::vector<bool> keep(carried.size(), true);
  Eigen::Vector3d b, var;
  mean(keep, b, var);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < carried.size(); ++i) {
    const Eigen::Vector3d d = carried[i].b - b;
    keep[i] = (d.cwiseAbs2().array() <= 25.0 * (carried[i].var + var).array()).all();
    kept += keep[i] ? 1 : 0;
  }
  if (kept == 0) return std::nullopt;
  if (kept < carried.size()) mean(keep, b, var);
  nav::BaselineCorrection c;
  c.e_ned_m = b - now.ned_m;
  c.cov_ned_m2 = var.asDiagonal();
  return c;
}

}  // namespace augrig::pipeline
