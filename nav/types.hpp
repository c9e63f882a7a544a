// nav types: the measurements the fusion consumes (IMU increments, GPS fixes), as parsed from logs
// (nav/nmea.hpp, nav/logs.hpp) or produced by the simulator (sim/sensors.hpp).
//
// Time: every sample carries its sensor time of validity `t_ns` in ClockDomain::kGps (ns since the
// GPS epoch 1980-01-06, no leap seconds) unless stated otherwise, and, where known, the host time it
// arrived at (`arrival_ns`, ClockDomain::kHostMonotonic; 0 when unknown). Per-stream offsets that map
// a stream's clock onto the nav clock are configuration (nav/ins.hpp), not baked into samples.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/conventions.hpp"
#include "nav/geodesy.hpp"

namespace augrig::nav {

// One IMU output: the integrals over (t_ns - dt_s, t_ns] of the body angular rate w.r.t. inertial
// space and of the specific force (non-gravitational acceleration), both in body FRD. The IMU sits
// at the body origin with its axes along body FRD.
struct ImuSample {
  TimestampNs t_ns = 0;
  double dt_s = 0;
  Eigen::Vector3d dtheta_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d dv_mps = Eigen::Vector3d::Zero();
  TimestampNs arrival_ns = 0;
};

// GGA fix quality codes (NMEA 0183).
enum class FixQuality : std::uint8_t {
  kInvalid = 0,
  kSingle = 1,
  kDgps = 2,
  kPps = 3,
  kRtkFixed = 4,
  kRtkFloat = 5,
  kDeadReckoning = 6,
};

// One GPS epoch, merged from the sentences that share its UTC time tag (GGA position, RMC/VTG
// ground velocity, HDT heading, GST error estimates).
struct GpsFix {
  TimestampNs t_ns = 0;  // time of validity (the sentences' UTC tag), converted to GPS time
  TimestampNs arrival_ns = 0;
  Geodetic antenna;  // antenna phase centre, ellipsoidal height (GGA: MSL + the receiver's separation)
  FixQuality quality = FixQuality::kInvalid;
  int satellites = 0;
  double hdop = 0;
  double geoid_separation_m = 0;  // GGA field 11 as received
  // 1-sigma north/east/down position error from GST, when present.
  std::optional<Eigen::Vector3d> sigma_ned_m;
  // Horizontal ground velocity from RMC/VTG (speed over ground and course), when present.
  std::optional<double> ground_speed_mps;
  std::optional<double> course_rad;  // true course over ground, from north towards east
  // True heading of the antenna baseline from HDT (dual-antenna receivers), when present.
  std::optional<double> heading_rad;
};

// What a parser saw but could not use, so nothing is dropped silently. Each entry names the
// file and line: "tanker.nmea:1234: bad checksum (got 5A, computed 4B)".
struct LogIssues {
  std::vector<std::string> messages;
  std::size_t malformed = 0;    // lines that failed to parse or failed their checksum
  std::size_t out_of_order = 0; // samples older than their predecessor (dropped)
  std::size_t duplicates = 0;   // samples with the same time as their predecessor (dropped)
  std::size_t gaps = 0;         // intervals longer than twice the nominal period
};

}  // namespace augrig::nav
