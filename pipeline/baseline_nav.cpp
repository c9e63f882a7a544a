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

BaselineNav::InsBaseline BaselineNav::ins_baseline(const nav::NavState& tanker,
                                                   const nav::NavState& receiver) const {
  const Eigen::Vector3d a = tanker.p_ecef_m + tanker.q_ecef_body * tanker_antenna_m_;
  const Eigen::Vector3d b = receiver.p_ecef_m + receiver.q_ecef_body * receiver_antenna_m_;
  const nav::Geodetic g = nav::geodetic_from_ecef(a);
  InsBaseline out;
  out.R_ecef_ned = nav::R_ecef_ned(g.lat_rad, g.lon_rad);
  out.ned_m = out.R_ecef_ned.transpose() * (b - a);
  const Eigen::Matrix3d P = tanker.P.block<3, 3>(nav::kErrPos, nav::kErrPos) +
                            receiver.P.block<3, 3>(nav::kErrPos, nav::kErrPos);
  out.cov_ned_m2 = out.R_ecef_ned.transpose() * P * out.R_ecef_ned;
  return out;
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
        return n.ins_baseline(s->tk, s->rx);
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
  const InsBaseline ib = ins_baseline(tanker, receiver);
  const Eigen::Vector3d e = c->e_ned_m;
  const Eigen::Matrix3d cov = c->cov_ned_m2;
  receiver.p_ecef_m += ib.R_ecef_ned * e;
  // The relative position's covariance now: all of it on the receiver, none on the tanker, and no
  // position cross terms (the correction's error is not the solutions').
  for (nav::NavState* s : {&tanker, &receiver}) {
    s->P.middleRows(nav::kErrPos, 3).setZero();
    s->P.middleCols(nav::kErrPos, 3).setZero();
  }
  receiver.P.block<3, 3>(nav::kErrPos, nav::kErrPos) = ib.R_ecef_ned * cov * ib.R_ecef_ned.transpose();
  return true;
}

}  // namespace augrig::pipeline
