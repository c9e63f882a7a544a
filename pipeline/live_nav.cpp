#include "pipeline/live_nav.hpp"

#include <cmath>
#include <cstdio>

#include "nav/geodesy.hpp"
#include "pipeline/camera_clock_online.hpp"

namespace augrig::pipeline {

std::string_view to_string(Aircraft a) {
  return a == Aircraft::kTanker ? "tanker" : "receiver";
}

std::optional<Aircraft> aircraft_of_stream(std::string_view stream) {
  const std::string_view head = stream.substr(0, stream.find('.'));
  if (head == "tanker") return Aircraft::kTanker;
  if (head == "receiver") return Aircraft::kReceiver;
  return std::nullopt;
}

LiveNav::LiveNav(const Rig& rig, const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
                 const nav::InsConfig& tanker, const nav::InsConfig& receiver, const LiveNavOptions& options)
    : rig_(rig), boom_(boom), receptacle_m_(receptacle_m), options_(options), baseline_(options.baseline) {
  fusion_[0] = std::make_unique<nav::LiveFusion>(tanker, options.fusion);
  fusion_[1] = std::make_unique<nav::LiveFusion>(receiver, options.fusion);
  // GPS time against host arrival: receivers output fixes some tens of ms late, steadily; a
  // minute's window follows the host clock's drift.
  ClockOffsetConfig c;
  c.window_ns = 60'000'000'000;
  c.jump_threshold_ns = 200'000'000;
  gps_to_host_ = *ClockOffsetEstimator::create(c);
}

void LiveNav::add(Aircraft aircraft, const nav::NavEvent& event) {
  if (event.is_baseline()) {
    baseline_.add(event.baseline());
    return;
  }
  nav::LiveFusion& f = *fusion_[static_cast<int>(aircraft)];
  if (event.is_imu()) {
    f.add_imu(event.imu());
    if (aircraft == Aircraft::kTanker && tanker_rates_) {
      // On GPS time as the filter puts it: its time offset, less its IMU clock estimate.
      const nav::ImuSample& m = event.imu();
      const nav::LiveFusionStatus st = f.status();
      const TimestampNs clock_ns = st.imu_clock_estimated ? s_to_ns(st.imu_clock_offset_s) : 0;
      tanker_rates_->add_increment(m.t_ns + f.config().imu_time_offset_ns - clock_ns, m.dt_s, m.dtheta_rad);
    }
    return;
  }
  const nav::GpsFix& fix = event.gps();
  f.add_fix(fix);
  if (fix.arrival_ns > 0) {
    std::lock_guard lock(clock_mutex_);
    (void)gps_to_host_.add(fix.t_ns, fix.arrival_ns);  // a refused sample leaves the estimate as it was
  }
}

Expected<TimestampNs> LiveNav::host_to_nav(TimestampNs host_ns) const {
  std::lock_guard lock(clock_mutex_);
  if (!gps_to_host_.has_estimate())
    return make_error("LiveNav: no GPS fix yet to relate host time to GPS time");
  return host_ns - gps_to_host_.estimate().offset_ns;
}

nav::GroundMotionFunction LiveNav::tanker_ground_motion(double terrain_height_m) const {
  return [this, terrain_height_m](TimestampNs t_gps_ns) -> std::optional<nav::GroundMotion> {
    const auto x = fusion_[0]->at(t_gps_ns);
    if (!x) return std::nullopt;
    const nav::Geodetic g = nav::geodetic_from_ecef(x->p_ecef_m);
    const Eigen::Matrix3d R_ecef_ned_m = nav::R_ecef_ned(g.lat_rad, g.lon_rad);
    nav::GroundMotion gm;
    gm.R_ned_body = R_ecef_ned_m.transpose() * x->q_ecef_body.toRotationMatrix();
    gm.v_ned_mps = R_ecef_ned_m.transpose() * x->v_ecef_mps;
    gm.height_m = g.h_m - terrain_height_m;
    return gm;
  };
}

nav::LiveFusionStatus LiveNav::status(Aircraft aircraft) const {
  return fusion_[static_cast<int>(aircraft)]->status();
}

namespace {

std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f s", s);
  return buf;
}

}  // namespace

FrameNav LiveNav::at(int camera, TimestampNs t_nav_ns) const {
  FrameNav out;
  std::array<nav::LiveFusionStatus, 2> st;
  std::array<std::optional<nav::NavState>, 2> state;
  double age_s = 0;            // of the oldest newest-fix of the two aircraft at the frame's time
  std::string no_pose_reason;  // the first aircraft without a state
  for (int a = 0; a < 2; ++a) {
    const std::string who(to_string(static_cast<Aircraft>(a)));
    st[a] = fusion_[a]->status();
    if (!st[a].initialised) {
      out.problems.push_back(who + " nav: waiting for " +
                             (st[a].t_imu_ns == 0 ? std::string("IMU data")
                              : st[a].t_valid_fix_ns == 0 && st[a].fixes
                                  ? std::string("a GPS fix (no fix yet)")
                                  : std::string("GPS and IMU to initialise")));
      if (no_pose_reason.empty()) no_pose_reason = out.problems.back();
      continue;
    }
    auto s = fusion_[a]->at(t_nav_ns);
    if (!s) {
      out.problems.push_back(who + " nav: " + s.error().message);
      if (no_pose_reason.empty()) no_pose_reason = out.problems.back();
      continue;
    }
    state[a] = *s;
    // The ages of the data the pose at t rests on, not of the newest: a frame handled late, after a
    // silence ended, was still taken in it.
    const nav::LiveFusionDataAt d = fusion_[a]->data_before(t_nav_ns);
    const double fix_age = ns_to_s(t_nav_ns - (d.t_valid_fix_ns ? d.t_valid_fix_ns : st[a].t_valid_fix_ns));
    const double imu_age = ns_to_s(t_nav_ns - (d.t_imu_ns ? d.t_imu_ns : st[a].t_imu_ns));
    age_s = std::max(age_s, fix_age);
    if (st[a].fix_quality == nav::FixQuality::kInvalid ||
        st[a].fix_quality == nav::FixQuality::kDeadReckoning) {
      if (fix_age > options_.stale_after_s)
        out.problems.push_back(who + " GPS: no fix for " + seconds(fix_age) + " (dead reckoning)");
    } else if (fix_age > options_.stale_after_s) {
      out.problems.push_back(who + " GPS: no data for " + seconds(fix_age) + " (dead reckoning)");
    }
    if (imu_age > options_.stale_after_s)
      out.problems.push_back(who + " IMU: no data for " + seconds(imu_age) + " (pose extrapolated)");
    if (!st[a].converged || t_nav_ns < st[a].t_converged_ns) {
      out.converging = true;
      out.converging_text += (out.converging_text.empty() ? "" : "; ") + who +
                             " nav converging (attitude sigma still falling): sigma optimistic";
    }
  }
  out.hud.fix = std::min(st[0].fix_quality, st[1].fix_quality, [](nav::FixQuality x, nav::FixQuality y) {
    // The worse of the two: RTK fixed (4) best, then float (5), DGPS/PPS, single, none.
    auto rank = [](nav::FixQuality q) {
      switch (q) {
        case nav::FixQuality::kRtkFixed:
          return 6;
        case nav::FixQuality::kRtkFloat:
          return 5;
        case nav::FixQuality::kDgps:
        case nav::FixQuality::kPps:
          return 4;
        case nav::FixQuality::kSingle:
          return 3;
        default:
          return 0;
      }
    };
    return rank(x) < rank(y);
  });
  bool corrected = false;
  if (state[0] && state[1]) {
    const Eigen::Vector3d l_tk = fusion_[0]->config().baseline_antenna();
    const Eigen::Vector3d l_rx = fusion_[1]->config().baseline_antenna();
    const auto states_at = [this](TimestampNs t, nav::NavState& tk, nav::NavState& rx) {
      auto a = fusion_[0]->at(t);
      auto b = fusion_[1]->at(t);
      if (!a || !b) return false;
      tk = std::move(*a), rx = std::move(*b);
      return true;
    };
    if (const auto c = baseline_.at(t_nav_ns, *state[0], *state[1], states_at, l_tk, l_rx)) {
      apply_baseline_correction(*c, ins_baseline(*state[0], *state[1], l_tk, l_rx), *state[0], *state[1]);
      corrected = true;
    } else if (const LiveBaselineReport r = baseline_.report(); r.received > r.invalid) {
      out.problems.push_back("moving baseline: no usable vector in the last second (the solutions alone)");
    }
  }
  if (state[0] && state[1]) {
    out.pose = frame_pose(*state[0], *state[1], t_nav_ns, rig_, camera, boom_, receptacle_m_);
    out.pose->baseline_corrected = corrected;
    out.stale = !out.problems.empty();
    out.hud.age_s = age_s;
    out.hud.sigma_pos_m = out.pose->body.sigma_position_m();
    out.hud.sigma_att_deg = rad_to_deg(out.pose->body.sigma_attitude_rad());
    out.hud.status = out.stale        ? "STALE: " + out.problems.front()
                     : out.converging ? "CONVERGING: " + out.converging_text
                     : corrected      ? "fused GPS/INS, both aircraft, and the moving baseline"
                                      : "fused GPS/INS, both aircraft";
  } else {
    out.converging = false;
    out.converging_text.clear();
    out.hud.status = "no pose: " + no_pose_reason;
  }
  return out;
}

}  // namespace augrig::pipeline
