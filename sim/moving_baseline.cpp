#include "sim/moving_baseline.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>

#include "core/conventions.hpp"
#include "nav/geodesy.hpp"
#include "sim/scenario.hpp"

namespace augrig::sim {

namespace {

constexpr std::int64_t kWeekMs = 7LL * 86400 * 1000;

Eigen::Vector3d antenna_ecef(const KinematicState& s, const Eigen::Vector3d& lever_m) {
  return s.p_ecef_m + s.R_ecef_body() * lever_m;
}

}  // namespace

Eigen::Vector3d true_baseline_ned_m(const KinematicState& base, const Eigen::Vector3d& base_lever_arm_m,
                                    const KinematicState& rover, const Eigen::Vector3d& rover_lever_arm_m) {
  const Eigen::Vector3d b = antenna_ecef(base, base_lever_arm_m);
  const nav::Geodetic g = nav::geodetic_from_ecef(b);
  return nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * (antenna_ecef(rover, rover_lever_arm_m) - b);
}

MovingBaselineSimulator::MovingBaselineSimulator(const MovingBaselineConfig& config, std::uint64_t seed,
                                                 TimestampNs start_gps_ns)
    : config_(config),
      start_ns_(start_gps_ns),
      period_ns_(static_cast<TimestampNs>(std::llround(1e9 / config.rate_hz))),
      rng_(seed),
      fixed_(config.start_fixed) {}

MovingBaselineEpoch MovingBaselineSimulator::next(const TruthFunction& base, const TruthFunction& rover) {
  const TimestampNs t_rel_ns = k_ * period_ns_;
  const double t = static_cast<double>(t_rel_ns) / 1e9;
  const double dt = static_cast<double>(period_ns_) / 1e9;
  const bool first = k_ == 0;
  ++k_;
  // The same draws every epoch, whatever the state: chain, white noise, a possible new float bias.
  const double u = rng_.uniform();
  const Eigen::Vector3d n = rng_.normal3();
  const Eigen::Vector3d nb = rng_.normal3();
  const bool outage = std::any_of(config_.outages.begin(), config_.outages.end(),
                                  [t](const GpsOutage& o) { return t >= o.t0_s && t <= o.t1_s; });
  const bool was_fixed = fixed_;
  if (outage) {
    fixed_ = false;  // back from an outage in float
  } else if (!first) {
    const double rate = fixed_ ? config_.fixed_to_float_per_s : config_.float_to_fixed_per_s;
    if (u < 1.0 - std::exp(-rate * dt)) fixed_ = !fixed_;
  }
  if ((was_fixed || first) && !fixed_)
    float_bias_m_ = {config_.float_bias_sigma_horizontal_m * nb.x(),
                     config_.float_bias_sigma_horizontal_m * nb.y(),
                     config_.float_bias_sigma_vertical_m * nb.z()};

  MovingBaselineEpoch e;
  e.t_gps_ns = start_ns_ + t_rel_ns;
  e.arrival_ns = e.t_gps_ns + static_cast<TimestampNs>(std::llround(config_.latency_s * 1e9));
  e.truth_ned_m = true_baseline_ned_m(base(t), config_.base_lever_arm_m, rover(t), config_.rover_lever_arm_m);
  nav::UbxRelPosNed& m = e.message;
  m.version = config_.version;
  m.ref_station_id = config_.ref_station_id;
  m.itow_ms = static_cast<std::uint32_t>(((e.t_gps_ns / 1'000'000) % kWeekMs + kWeekMs) % kWeekMs);
  m.gnss_fix_ok = true;
  m.is_moving = true;
  if (outage) {
    // No corrections from the base: the rover says so and reports no vector.
    m.ref_obs_miss = true;
    m.rel_pos_ned_m.setZero();
    m.acc_ned_m.setConstant(nav::UbxRelPosNed::kNaN);
    return e;
  }
  const double sh = fixed_ ? config_.sigma_horizontal_m : config_.float_sigma_horizontal_m;
  const double sv = fixed_ ? config_.sigma_vertical_m : config_.float_sigma_vertical_m;
  Eigen::Vector3d err(sh * n.x(), sh * n.y(), sv * n.z());
  if (!fixed_) err += float_bias_m_;
  m.rel_pos_ned_m = e.truth_ned_m + err;
  m.acc_ned_m = {sh, sh, sv};
  m.diff_soln = m.rel_pos_valid = true;
  m.carr_soln = fixed_ ? 2 : 1;
  if (m.version == 1) {
    m.length_m = m.rel_pos_ned_m.norm();
    m.acc_length_m = sh;
    m.heading_deg =
        std::fmod(rad_to_deg(std::atan2(m.rel_pos_ned_m.y(), m.rel_pos_ned_m.x())) + 360.0, 360.0);
    const double horizontal = m.rel_pos_ned_m.head<2>().norm();
    m.acc_heading_deg = horizontal > 0 ? rad_to_deg(sh / horizontal) : 180.0;
    m.heading_valid = horizontal > 0;
  }
  return e;
}

std::vector<MovingBaselineEpoch> MovingBaselineSimulator::generate(const TruthFunction& base,
                                                                   const TruthFunction& rover,
                                                                   double t_end_s) {
  std::vector<MovingBaselineEpoch> out;
  while (static_cast<double>(k_ * period_ns_) / 1e9 <= t_end_s + 1e-9) out.push_back(next(base, rover));
  return out;
}

std::vector<MovingBaselineEpoch> simulate_moving_baseline(const Scenario& sc, const Flight& flight) {
  if (!sc.sensors.moving_baseline) return {};
  MovingBaselineConfig config = *sc.sensors.moving_baseline;
  config.base_lever_arm_m = sc.sensors.tanker.gps.lever_arm_m;
  config.rover_lever_arm_m = sc.sensors.receiver.gps.lever_arm_m;
  MovingBaselineSimulator sim(config, derive_seed(sc.seed, "moving_baseline"), sc.start_gps_ns);
  return sim.generate([&flight](double t) { return flight.tanker(t); },
                      [&flight](double t) { return flight.receiver(t); }, sc.duration_s);
}

Status write_relposned_ubx(const std::string& path, const std::vector<MovingBaselineEpoch>& epochs) {
  std::ofstream f(path, std::ios::binary);
  if (!f) return make_error("sim::write_relposned_ubx(): ", path, ": cannot create the file");
  for (const MovingBaselineEpoch& e : epochs) {
    const std::vector<std::uint8_t> bytes = nav::encode_nav_relposned(e.message);
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  f.close();
  if (!f) return make_error("sim::write_relposned_ubx(): ", path, ": cannot write the file");
  return {};
}

}  // namespace augrig::sim
