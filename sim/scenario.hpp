// Scenario: everything that defines a simulated flight — start time and place, the tanker's pattern,
// the receiver's phases and turbulence, the rig, and the sensors — read from a scenario file (YAML,
// format in docs/SIMULATION.md, "Scenario files") or taken from the built-ins ("demo",
// "contact-10min" and their "-noise-free" variants), which need no file on disk. Loading never
// prints: it returns the Scenario or an Error naming the file, line, column and key, and what was
// expected. Flight (sim/flight.hpp) and simulate_sensors (sim/sensors.hpp) turn it into truth and logs.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/geodesy.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "sim/flight.hpp"
#include "sim/moving_baseline.hpp"
#include "sim/sensors.hpp"

namespace augrig::sim {

struct AircraftSensors {
  ImuConfig imu;
  GpsConfig gps;
  bool operator==(const AircraftSensors&) const = default;
};

struct SensorsConfig {
  AircraftSensors tanker, receiver;
  CommonGpsErrorConfig common_gps_error;
  // A moving-baseline RTK pair (the tanker's receiver the base, the receiver's the rover), between
  // the two aircraft's GPS antennas (their gps.lever_arm_m): `augrig sim` writes the rover's UBX log.
  std::optional<MovingBaselineConfig> moving_baseline;
  CameraTimingConfig cameras;
  bool operator==(const SensorsConfig&) const = default;
};

struct Scenario {
  std::string name;
  std::string source;  // the file it came from, or "<builtin:NAME>"
  double duration_s = 30.0;
  TimestampNs start_gps_ns = 0;  // scenario time 0, ClockDomain::kGps
  nav::Geodetic start;           // tanker body origin at t = 0 (ellipsoidal height)
  std::uint64_t seed = 1;
  TankerFlightConfig tanker;
  ReceiverFlightConfig receiver;
  std::string rig_name;  // "paper_default" or the rig file's path (resolved)
  Rig rig;
  BoomDimensions boom;  // the built-in boom's dimensions (nozzle tip)
  SensorsConfig sensors;
};

Expected<Scenario> load_scenario(const std::string& path);
// Parses scenario YAML text; `name` is used in messages and, when it is a path, to resolve a relative
// rig path (otherwise the current directory is used).
Expected<Scenario> parse_scenario(const std::string& yaml_text, const std::string& name);

// Built-in scenarios: "demo", "demo-noise-free", "contact-10min", "contact-10min-noise-free".
Expected<Scenario> builtin_scenario(const std::string& name);
std::vector<std::string> builtin_scenario_names();
// The YAML text of a built-in base scenario ("demo", "contact-10min"); assets/scenarios/NAME.yaml
// holds a copy.
Expected<std::string> builtin_scenario_text(const std::string& name);

// Makes every sensor noise-free: IMU errors zero, GPS white noise (fixed and float) and common error
// zero, RTK fixed from the start and never lost (after an outage the receiver is in float until it
// regains the fix, with zero noise), no velocity/heading noise, no camera jitter, drops or image
// noise. Keeps the truth (turbulence included), rates, lever arms, latencies, outages and camera
// clock offsets.
void make_noise_free(Scenario& scenario);

// GPS time (ns since 1980-01-06T00:00:00, no leap seconds) of a UTC date-time
// "YYYY-MM-DDTHH:MM:SS[.fraction][Z]" (leap seconds from 1981 to 2017 applied; GPS - UTC = 18 s since
// 2017-01-01).
Expected<TimestampNs> gps_ns_from_utc(std::string_view utc);

}  // namespace augrig::sim
