// moving_baseline: a simulated moving-baseline RTK pair (u-blox F9P style): the tanker's receiver
// is the moving base, the receiver aircraft's the rover, and the rover reports the vector from the
// base antenna to its own as UBX NAV-RELPOSNED (nav/ubx.hpp) at rate_hz. Its error model, per epoch:
//   carrier solution  a two-state Markov chain, fixed <-> float (rates per second), float after an
//                     outage; fixed: white noise sigma_* per NED axis (about 1 cm); float: a bias
//                     drawn on entering float (float_bias_sigma_*) plus white noise (float_sigma_*)
//   outages           [t0, t1] scenario seconds without corrections: the message still comes, with
//                     relPosValid and diffSoln clear and refObsMiss set (as a rover reports it)
//   accuracy          accN/E/D report the current state's white-noise sigmas (what the receiver
//                     knows), not the float bias
// The vector is in the local NED at the base antenna (over tens of metres the NED frames of the two
// antennas differ by microradians). iTOW is the epoch's GPS time of week; the message reaches the
// host latency_s after the epoch.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "nav/ubx.hpp"
#include "sim/sensors.hpp"

namespace augrig::sim {

struct MovingBaselineConfig {
  double rate_hz = 5.0;
  Eigen::Vector3d base_lever_arm_m = Eigen::Vector3d(0.0, 0.0, -1.5);   // tanker antenna, tanker body FRD
  Eigen::Vector3d rover_lever_arm_m = Eigen::Vector3d(0.0, 0.0, -1.5);  // receiver antenna, its body FRD
  double latency_s = 0.08;
  double sigma_horizontal_m = 0.01, sigma_vertical_m = 0.015;             // fixed
  double float_sigma_horizontal_m = 0.05, float_sigma_vertical_m = 0.08;  // float: white part
  double float_bias_sigma_horizontal_m = 0.2, float_bias_sigma_vertical_m = 0.35;
  double fixed_to_float_per_s = 0.005, float_to_fixed_per_s = 0.2;
  bool start_fixed = true;
  std::vector<GpsOutage> outages;
  int version = 1;  // NAV-RELPOSNED version (0: M8P, 1: F9P)
  int ref_station_id = 0;
  bool operator==(const MovingBaselineConfig&) const = default;
};

struct MovingBaselineEpoch {
  TimestampNs t_gps_ns = 0, arrival_ns = 0;
  nav::UbxRelPosNed message;
  Eigen::Vector3d truth_ned_m = Eigen::Vector3d::Zero();  // base antenna -> rover antenna
};

class MovingBaselineSimulator {
 public:
  MovingBaselineSimulator(const MovingBaselineConfig& config, std::uint64_t seed, TimestampNs start_gps_ns);
  // Epoch k at k / rate_hz scenario seconds.
  MovingBaselineEpoch next(const TruthFunction& base, const TruthFunction& rover);
  // All further epochs with t <= t_end_s.
  std::vector<MovingBaselineEpoch> generate(const TruthFunction& base, const TruthFunction& rover,
                                            double t_end_s);

 private:
  MovingBaselineConfig config_;
  TimestampNs start_ns_ = 0, period_ns_ = 0;
  std::int64_t k_ = 0;
  Rng rng_;
  bool fixed_ = true;
  Eigen::Vector3d float_bias_m_ = Eigen::Vector3d::Zero();
};

// The true base -> rover antenna vector in the NED frame at the base antenna.
Eigen::Vector3d true_baseline_ned_m(const KinematicState& base, const Eigen::Vector3d& base_lever_arm_m,
                                    const KinematicState& rover, const Eigen::Vector3d& rover_lever_arm_m);

// A scenario's moving baseline (Scenario::sensors.moving_baseline; none: empty) over [0, duration],
// between the two aircraft's GPS antennas, seeded from scenario.seed (stream "moving_baseline").
struct Scenario;
std::vector<MovingBaselineEpoch> simulate_moving_baseline(const Scenario& scenario, const Flight& flight);

// The epochs as a UBX log (their NAV-RELPOSNED frames in order); errors name the file.
Status write_relposned_ubx(const std::string& path, const std::vector<MovingBaselineEpoch>& epochs);

}  // namespace augrig::sim
