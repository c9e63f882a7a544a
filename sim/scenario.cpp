// Scenario files and the built-in scenarios (sim/scenario.hpp, docs/SIMULATION.md "Scenario files").
#include "sim/scenario.hpp"

#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "core/file_check.hpp"
#include "core/yaml_reader.hpp"
#include "nav/gps_time.hpp"

namespace augrig::sim {

namespace {

namespace fs = std::filesystem;

using namespace yaml;  // located errors, key checks, numbers (core/yaml_reader.hpp)

struct Ctx : yaml::Context {
  fs::path base_dir;  // a relative rig path is resolved against it
};

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- The built-in scenarios (assets/scenarios/*.yaml hold copies; a test keeps them equal) ----

constexpr const char* kDemoYaml =
    R"yaml(# augrig scenario (docs/SIMULATION.md, "Scenario files"): the built-in "demo".
# A 28 s approach: observation, pre-contact, contact, behind a straight and level tanker.
augrig_scenario: 1
name: demo
duration_s: 28
seed: 1
start:
  utc: "2024-06-01T12:00:00Z"
  lat_deg: 51.0
  lon_deg: -1.0
  alt_m: 7000
rig: paper_default
tanker:
  pattern: straight
  heading_deg: 90
  speed_mps: 160
  angle_of_attack_deg: 3
receiver:
  contact: {elevation_deg: 30, azimuth_deg: 0, extension_m: 3.5}
  phases:
    - {name: observation, duration_s: 4, offset_m: [-30, 2, 12]}
    - {name: to-pre-contact, duration_s: 8, offset_m: [-15, 0, 4]}
    - {name: pre-contact, duration_s: 4}
    - {name: to-contact, duration_s: 7, offset_m: [0, 0, 0]}
    - {name: contact, duration_s: 5, attached: true}
  turbulence: {sigma_m: [0.15, 0.1, 0.15], sigma_deg: [0.4, 0.3, 0.3], length_scale_m: 500}
sensors:
  tanker:
    imu: {preset: navigation, rate_hz: 200}
    gps: {rate_hz: 10, lever_arm_m: [5.0, 0.0, -3.5], latency_s: 0.03, heading: true}
  receiver:
    imu: {preset: tactical, rate_hz: 200}
    gps: {rate_hz: 10, lever_arm_m: [1.0, 0.0, -1.2], latency_s: 0.03}
  common_gps_error: {sigma_horizontal_m: 0.3, sigma_vertical_m: 0.6, tau_s: 600}
  cameras:
    fps: 30
    clock_offset_ns: [1200000, 1250000]
    jitter_ns: 20000
    drop_probability: 0.001
    bayer: false
    noise: 1.5
)yaml";

constexpr const char* kContact10MinYaml =
    R"yaml(# augrig scenario (docs/SIMULATION.md, "Scenario files"): the built-in "contact-10min".
# Ten minutes behind a tanker flying a racetrack (25 deg banked turns): join, contact for 7 minutes
# through the turns, disconnect and back to pre-contact. For the accuracy tests.
augrig_scenario: 1
name: contact-10min
duration_s: 600
seed: 7
start:
  utc: "2024-06-01T12:00:00Z"
  lat_deg: 51.0
  lon_deg: -1.0
  alt_m: 7000
rig: paper_default
tanker:
  pattern: racetrack
  heading_deg: 90
  speed_mps: 170
  bank_deg: 25
  leg_length_m: 15000
  turn: right
  roll_in_s: 5
  angle_of_attack_deg: 3
receiver:
  contact: {elevation_deg: 30, azimuth_deg: 0, extension_m: 3.5}
  phases:
    - {name: observation, duration_s: 20, offset_m: [-30, 2, 12]}
    - {name: to-pre-contact, duration_s: 30, offset_m: [-15, 0, 4]}
    - {name: pre-contact, duration_s: 20}
    - {name: to-contact, duration_s: 20, offset_m: [0, 0, 0]}
    - {name: contact, duration_s: 420, attached: true}
    - {name: disconnect, duration_s: 10, offset_m: [-3, 0, 1.5]}
    - {name: to-pre-contact-2, duration_s: 40, offset_m: [-15, 0, 4]}
    - {name: pre-contact-2, duration_s: 40}
  turbulence: {sigma_m: [0.2, 0.15, 0.2], sigma_deg: [0.5, 0.4, 0.4], length_scale_m: 500}
sensors:
  tanker:
    imu: {preset: tactical, rate_hz: 200}
    gps:
      rate_hz: 10
      lever_arm_m: [5.0, 0.0, -3.5]
      latency_s: 0.03
      heading: true
      outages: [[300, 305]]
  receiver:
    imu: {preset: tactical, rate_hz: 200}
    gps: {rate_hz: 10, lever_arm_m: [1.0, 0.0, -1.2], latency_s: 0.03}
  common_gps_error: {sigma_horizontal_m: 0.3, sigma_vertical_m: 0.6, tau_s: 600}
  cameras:
    fps: 30
    clock_offset_ns: [1200000, 1250000]
    jitter_ns: 20000
    drop_probability: 0.001
    bayer: RGGB  # GigE machine-vision cameras stream the raw mosaic
    noise: 1.5
)yaml";

// ---- Reading values ---------------------------------------------------------------------------

struct Range {
  double lo = -kInf, hi = kInf;
  bool lo_open = false, hi_open = false;
};
// Even the open-ended ranges stop at 1e9 (of the key's unit): beyond that a value is a typo, and
// 1e300 metres or seconds overflow the simulation's sums and its int64 ns (docs/SIMULATION.md).
constexpr double kMaxMagnitude = 1e9;
constexpr Range kAny{-kMaxMagnitude, kMaxMagnitude, false, false};
constexpr Range kNonNegative{0.0, kMaxMagnitude, false, false};
constexpr Range kPositive{0.0, kMaxMagnitude, true, false};
// A receiver phase's offset from the contact point: within 10 km (the relative geometry is a few
// hundred metres; 1e300 made every sample non-finite).
constexpr Range kOffsetM{-1e4, 1e4, false, false};
// One phase lasts at most a day, like the whole scenario.
constexpr Range kPhaseDurationS{0.0, 86400.0, true, false};

std::string describe(const Range& r, const std::string& unit) {
  const std::string u = unit.empty() ? "" : " " + unit;
  if (r.lo == -kInf && r.hi == kInf) return "a number" + u;
  if (r.hi == kInf) return std::string("a number ") + (r.lo_open ? "> " : ">= ") + fmt(r.lo) + u;
  if (r.lo == -kInf) return std::string("a number ") + (r.hi_open ? "< " : "<= ") + fmt(r.hi) + u;
  return std::string("a number in ") + (r.lo_open ? "(" : "[") + fmt(r.lo) + ", " + fmt(r.hi) +
         (r.hi_open ? ")" : "]") + u;
}

bool in_range(const Range& r, double v) {
  return (r.lo_open ? v > r.lo : v >= r.lo) && (r.hi_open ? v < r.hi : v <= r.hi);
}

double checked(const Ctx& c, const YAML::Node& n, const std::string& key, const Range& r,
               const std::string& unit) {
  const std::string what = describe(r, unit);
  const double v = to_number(c, n, key, what);
  if (!in_range(r, v)) fail(c, n, key, "expected " + what + ", got " + fmt(v));
  return v;
}

// An optional number: `def` when the key is absent.
double number(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key,
              double def, const Range& r, const std::string& unit) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) return def;
  return checked(c, n, join_key(path, key), r, unit);
}

std::int64_t integer_of(const Ctx& c, const YAML::Node& n, const std::string& key, std::int64_t lo,
                        std::int64_t hi, const std::string& what) {
  std::int64_t v = 0;
  if (n.IsScalar()) {
    const std::string& s = n.Scalar();
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (r.ec == std::errc() && r.ptr == s.data() + s.size() && v >= lo && v <= hi) return v;
  }
  fail(c, n, key, "expected " + what + ", " + got(n));
}

std::int64_t integer(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key,
                     std::int64_t def, std::int64_t lo, std::int64_t hi, const std::string& what) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) return def;
  return integer_of(c, n, join_key(path, key), lo, hi, what);
}

bool boolean(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key, bool def) {
  const YAML::Node n = map[key];
  return n.IsDefined() ? to_bool(c, n, join_key(path, key)) : def;
}

Eigen::Vector3d vec3(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key,
                     const Eigen::Vector3d& def, const std::string& what, double scale = 1.0,
                     const Range& r = kAny) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) return def;
  const std::string k = join_key(path, key);
  const Eigen::Vector3d v = to_vec3(c, n, k, what);
  for (int i = 0; i < 3; ++i) {
    if (!in_range(r, v[i]))
      fail(c, n[i], k,
           "expected " + describe(r, "") + " as element " + std::to_string(i) + ", got " + fmt(v[i]));
  }
  return v * scale;
}

// One of `choices`.
std::string choice(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key,
                   const std::string& def, const std::vector<std::string>& choices) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) return def;
  const std::string k = join_key(path, key);
  const std::string what = "one of " + join(choices);
  if (n.IsScalar()) {
    for (const std::string& s : choices)
      if (n.Scalar() == s) return s;
  }
  fail(c, n, k, "expected " + what + ", " + got(n));
}

// An optional map: an undefined node when absent; a located error when not a map.
YAML::Node optional_map(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key,
                        const std::string& what, const std::vector<std::string>& keys) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) return n;
  const std::string k = join_key(path, key);
  expect_map(c, n, k, what);
  check_keys(c, n, k, keys);
  return n;
}

// ---- Sections ---------------------------------------------------------------------------------

// The latest start: the end of nav::kMaxYear less a day (a scenario lasts at most one), so that
// every simulated time stays inside the supported range (nav/gps_time.hpp).
constexpr std::int64_t kMaxStartGpsNs =
    nav::gps_ns_from_utc({nav::kMaxYear + 1, 1, 1}, 0, 0) - nav::kNsPerDay;

void parse_start(const Ctx& c, const YAML::Node& root, Scenario& s) {
  const YAML::Node n =
      optional_map(c, root, "", "start",
                   "a map {utc | gps_time_ns | gps_week and gps_tow_s, "
                   "lat_deg, lon_deg, alt_m}",
                   {"utc", "gps_time_ns", "gps_week", "gps_tow_s", "lat_deg", "lon_deg", "alt_m"});
  s.start_gps_ns = *gps_ns_from_utc("2024-06-01T12:00:00Z");
  s.start = {deg_to_rad(51.0), deg_to_rad(-1.0), 7000.0};
  if (!n.IsDefined()) return;
  int given = 0;
  for (const char* k : {"utc", "gps_time_ns", "gps_week"}) given += n[k].IsDefined() ? 1 : 0;
  if (given > 1) fail(c, n, "start", "give only one of utc, gps_time_ns, gps_week (with gps_tow_s)");
  if (n["gps_tow_s"].IsDefined() && !n["gps_week"].IsDefined())
    fail(c, n["gps_tow_s"], "start.gps_tow_s", "needs start.gps_week");
  if (const YAML::Node u = n["utc"]; u.IsDefined()) {
    const std::string what = std::string(
                                 "a UTC date-time \"YYYY-MM-DDTHH:MM:SS[.fraction][Z]\" from 1980-01-06 "
                                 "through the year ") +
                             std::to_string(nav::kMaxYear);
    const auto t = gps_ns_from_utc(to_string_value(c, u, "start.utc", what));
    if (!t) fail(c, u, "start.utc", "expected " + what + ", " + got(u));
    s.start_gps_ns = *t;
  } else if (const YAML::Node g = n["gps_time_ns"]; g.IsDefined()) {
    s.start_gps_ns =
        integer_of(c, g, "start.gps_time_ns", 0, kMaxStartGpsNs,
                   "an integer in [0, " + std::to_string(kMaxStartGpsNs) +
                       "] (ns since the GPS epoch, through the year " + std::to_string(nav::kMaxYear) + ")");
  } else if (const YAML::Node w = n["gps_week"]; w.IsDefined()) {
    const std::int64_t week =
        integer_of(c, w, "start.gps_week", 0, kMaxStartGpsNs / (604800 * nav::kNsPerSecond) - 1,
                   "an integer GPS week in [0, " +
                       std::to_string(kMaxStartGpsNs / (604800 * nav::kNsPerSecond) - 1) + "]");
    const double tow = number(c, n, "start", "gps_tow_s", 0.0, {0.0, 604800.0, false, true}, "s");
    s.start_gps_ns = week * 604800 * 1000000000LL + s_to_ns(tow);
  }
  s.start.lat_rad = deg_to_rad(number(c, n, "start", "lat_deg", 51.0, {-85.0, 85.0}, "degrees"));
  s.start.lon_rad = deg_to_rad(number(c, n, "start", "lon_deg", -1.0, {-180.0, 360.0}, "degrees"));
  s.start.h_m = number(c, n, "start", "alt_m", 7000.0, {-500.0, 20000.0}, "metres (ellipsoidal)");
}

void parse_rig_key(const Ctx& c, const YAML::Node& root, Scenario& s) {
  const YAML::Node n = root["rig"];
  if (!n.IsDefined() || (n.IsScalar() && n.Scalar() == "paper_default")) {
    s.rig_name = "paper_default";
    s.rig = Rig::paper_default();
    return;
  }
  const std::string p =
      to_string_value(c, n, "rig", "paper_default or a rig file path (relative to this file)");
  const fs::path path(p);
  const std::string resolved = (path.is_absolute() ? path : c.base_dir / path).lexically_normal().string();
  auto rig = load_rig(resolved);
  if (!rig) fail(c, n, "rig", "cannot load the rig file '" + resolved + "': " + rig.error().message);
  s.rig_name = resolved;
  s.rig = std::move(*rig);
}

void parse_tanker(const Ctx& c, const YAML::Node& root, Scenario& s) {
  const YAML::Node n = optional_map(c, root, "", "tanker", "a map {pattern, heading_deg, speed_mps, ...}",
                                    {"pattern", "heading_deg", "speed_mps", "bank_deg", "leg_length_m",
                                     "turn", "roll_in_s", "angle_of_attack_deg", "crab_deg"});
  TankerFlightConfig& t = s.tanker;
  t = TankerFlightConfig{};
  if (!n.IsDefined()) return;
  t.pattern = choice(c, n, "tanker", "pattern", "straight", {"straight", "racetrack"}) == "racetrack"
                  ? TankerPattern::kRacetrack
                  : TankerPattern::kStraight;
  t.heading_rad = deg_to_rad(number(c, n, "tanker", "heading_deg", 90.0, {-360.0, 360.0}, "degrees"));
  t.speed_mps = number(c, n, "tanker", "speed_mps", 160.0, {0.0, 400.0}, "m/s");
  t.bank_rad = deg_to_rad(number(c, n, "tanker", "bank_deg", 25.0, {0.0, 60.0, true, false}, "degrees"));
  t.leg_length_m = number(c, n, "tanker", "leg_length_m", 15000.0, kPositive, "metres");
  t.turn_right = choice(c, n, "tanker", "turn", "right", {"right", "left"}) == "right";
  t.roll_in_s = number(c, n, "tanker", "roll_in_s", 5.0, kPositive, "s");
  t.angle_of_attack_rad =
      deg_to_rad(number(c, n, "tanker", "angle_of_attack_deg", 3.0, {-10.0, 20.0}, "degrees"));
  t.crab_rad = deg_to_rad(number(c, n, "tanker", "crab_deg", 0.0, {-30.0, 30.0}, "degrees"));
  if (t.pattern == TankerPattern::kRacetrack) {
    if (!(t.speed_mps > 0)) {
      const YAML::Node v = n["speed_mps"];
      fail(c, v.IsDefined() ? v : n, "tanker.speed_mps", "expected a number > 0 m/s for a racetrack");
    }
    // The roll-in and roll-out must fit into the 180 deg turn.
    const double g = nav::gravity_ecef(nav::ecef_from_geodetic(s.start)).norm();
    const double max_s = kPi * t.speed_mps / (g * std::tan(t.bank_rad));
    if (t.roll_in_s > max_s) {
      const YAML::Node r = n["roll_in_s"];
      fail(c, r.IsDefined() ? r : n, "tanker.roll_in_s",
           "expected at most " + fmt(std::floor(max_s * 1000) / 1000) +
               " s (a 180 deg turn at this bank and speed), got " + fmt(t.roll_in_s));
    }
  }
}

// A boom angle or extension (default `def`), within the rig's limits in the file's own unit.
double limited(const Ctx& c, const YAML::Node& map, const std::string& path, const std::string& key,
               double def, double lo, double hi, const std::string& unit) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) return def;
  const std::string k = join_key(path, key);
  const auto g9 = [](double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return std::string(buf);
  };
  const std::string what = "a number within the rig's limits [" + g9(lo) + ", " + g9(hi) + "] " + unit;
  const double v = to_number(c, n, k, what);
  // A hair of slack: limits went through deg -> rad -> deg.
  const double eps = 1e-9 * std::max(1.0, std::max(std::abs(lo), std::abs(hi)));
  if (v < lo - eps || v > hi + eps) fail(c, n, k, "expected " + what + ", got " + fmt(v));
  return v;
}

std::vector<ReceiverPhase> default_phases() {
  return {
      {"observation", 4.0, {-30.0, 2.0, 12.0}, Eigen::Vector3d::Zero(), false},
      {"to-pre-contact", 8.0, {-15.0, 0.0, 4.0}, Eigen::Vector3d::Zero(), false},
      {"pre-contact", 4.0, {-15.0, 0.0, 4.0}, Eigen::Vector3d::Zero(), false},
      {"to-contact", 7.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), false},
      {"contact", 5.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), true},
  };
}

void parse_receiver(const Ctx& c, const YAML::Node& root, Scenario& s) {
  const YAML::Node n = optional_map(c, root, "", "receiver", "a map {contact, phases, turbulence}",
                                    {"contact", "phases", "turbulence"});
  ReceiverFlightConfig& r = s.receiver;
  r = ReceiverFlightConfig{};
  r.phases = default_phases();
  if (!n.IsDefined()) return;

  // Contact articulation, within the rig's limits.
  if (const YAML::Node a =
          optional_map(c, n, "receiver", "contact", "a map {elevation_deg, azimuth_deg, extension_m}",
                       {"elevation_deg", "azimuth_deg", "extension_m"});
      a.IsDefined()) {
    const BoomLimits& l = s.rig.boom.limits;
    const std::string ap = "receiver.contact";
    r.contact.elevation_rad =
        deg_to_rad(limited(c, a, ap, "elevation_deg", 30.0, rad_to_deg(l.elevation_min_rad),
                           rad_to_deg(l.elevation_max_rad), "degrees"));
    r.contact.azimuth_rad = deg_to_rad(limited(c, a, ap, "azimuth_deg", 0.0, rad_to_deg(l.azimuth_min_rad),
                                               rad_to_deg(l.azimuth_max_rad), "degrees"));
    r.contact.extension_m =
        limited(c, a, ap, "extension_m", 3.5, l.extension_min_m, l.extension_max_m, "metres");
  }

  if (const YAML::Node ps = n["phases"]; ps.IsDefined()) {
    const std::string what = "a non-empty list of phases {name, duration_s, offset_m, ypr_deg, attached}";
    if (!ps.IsSequence() || ps.size() == 0)
      fail(c, ps, "receiver.phases", "expected " + what + ", " + got(ps));
    r.phases.clear();
    Eigen::Vector3d offset(-30.0, 2.0, 12.0), ypr = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < ps.size(); ++i) {
      const std::string path = "receiver.phases[" + std::to_string(i) + "]";
      const YAML::Node p = ps[i];
      expect_map(c, p, path, "a map {name, duration_s, offset_m, ypr_deg, attached}");
      check_keys(c, p, path, {"name", "duration_s", "offset_m", "ypr_deg", "attached"});
      ReceiverPhase ph;
      ph.name = "phase " + std::to_string(i + 1);
      if (const YAML::Node nm = p["name"]; nm.IsDefined())
        ph.name = to_string_value(c, nm, path + ".name", "a name");
      ph.duration_s = checked(c, require(c, p, path, "duration_s", "a number > 0 s"), path + ".duration_s",
                              kPhaseDurationS, "s");
      offset = vec3(c, p, path, "offset_m", offset,
                    "[x, y, z] in metres (tanker body, from the contact point)", 1.0, kOffsetM);
      ypr = vec3(c, p, path, "ypr_deg", ypr, "[yaw, pitch, roll] in degrees", deg_to_rad(1.0), {-30.0, 30.0});
      ph.offset_m = offset;
      ph.ypr_rad = ypr;
      ph.attached = boolean(c, p, path, "attached", false);
      r.phases.push_back(ph);
    }
  }

  if (const YAML::Node t = optional_map(c, n, "receiver", "turbulence",
                                        "a map {sigma_m, sigma_deg, length_scale_m, components}",
                                        {"sigma_m", "sigma_deg", "length_scale_m", "components"});
      t.IsDefined()) {
    TurbulenceConfig& tb = r.turbulence;
    tb.sigma_m =
        vec3(c, t, "receiver.turbulence", "sigma_m", tb.sigma_m, "[x, y, z] in metres", 1.0, kNonNegative);
    tb.sigma_rad = vec3(c, t, "receiver.turbulence", "sigma_deg", tb.sigma_rad,
                        "[yaw, pitch, roll] in degrees", deg_to_rad(1.0), {0.0, 10.0});
    tb.length_scale_m =
        number(c, t, "receiver.turbulence", "length_scale_m", tb.length_scale_m, kPositive, "metres");
    tb.components = static_cast<int>(integer(c, t, "receiver.turbulence", "components", tb.components, 1,
                                             1000, "an integer in [1, 1000]"));
  }
}

void parse_imu(const Ctx& c, const YAML::Node& parent, const std::string& parent_path, ImuConfig& imu) {
  const std::string path = join_key(parent_path, "imu");
  const YAML::Node n =
      optional_map(c, parent, parent_path, "imu",
                   "a map {preset, rate_hz, latency_s, clock_offset_ns, clock_drift_ppm, gyro, accel}",
                   {"preset", "rate_hz", "latency_s", "clock_offset_ns", "clock_drift_ppm", "gyro", "accel"});
  imu = ImuConfig{};
  if (!n.IsDefined()) return;
  if (const YAML::Node p = n["preset"]; p.IsDefined()) {
    const std::string name =
        choice(c, n, path, "preset", "tactical", {"noise_free", "navigation", "tactical", "consumer"});
    imu.errors = *imu_preset(name);
  }
  imu.rate_hz = number(c, n, path, "rate_hz", imu.rate_hz, {100.0, 400.0}, "Hz");
  imu.latency_s = number(c, n, path, "latency_s", imu.latency_s, {0.0, 1.0}, "s");
  // The IMU clock against GPS time: within 1 s and 1000 ppm (a sample's stamp must stay increasing).
  imu.clock_offset_ns = integer(c, n, path, "clock_offset_ns", imu.clock_offset_ns, -1'000'000'000,
                                1'000'000'000, "an integer in [-1000000000, 1000000000] ns");
  imu.clock_drift_ppm = number(c, n, path, "clock_drift_ppm", imu.clock_drift_ppm, {-1000.0, 1000.0}, "ppm");
  constexpr double kMg = 9.80665e-3;
  const double deg_per_sqrt_h = deg_to_rad(1.0) / 60.0, deg_per_h = deg_to_rad(1.0) / 3600.0;
  if (const YAML::Node g = optional_map(c, n, path, "gyro", "a map of gyro errors",
                                        {"arw_deg_per_sqrt_h", "bias_instability_deg_per_h", "bias_tau_s",
                                         "rate_random_walk_deg_per_h_per_sqrt_h", "turn_on_bias_deg_per_h"});
      g.IsDefined()) {
    const std::string gp = path + ".gyro";
    GyroErrors& e = imu.errors.gyro;
    e.arw_rad_per_sqrt_s =
        deg_per_sqrt_h * number(c, g, gp, "arw_deg_per_sqrt_h", e.arw_rad_per_sqrt_s / deg_per_sqrt_h,
                                kNonNegative, "deg/sqrt(h)");
    e.bias_instability_radps =
        deg_per_h * number(c, g, gp, "bias_instability_deg_per_h", e.bias_instability_radps / deg_per_h,
                           kNonNegative, "deg/h");
    e.bias_tau_s = number(c, g, gp, "bias_tau_s", e.bias_tau_s, kPositive, "s");
    e.rate_random_walk_radps_per_sqrt_s =
        deg_per_h / 60.0 *
        number(c, g, gp, "rate_random_walk_deg_per_h_per_sqrt_h",
               e.rate_random_walk_radps_per_sqrt_s / (deg_per_h / 60.0), kNonNegative, "deg/h/sqrt(h)");
    e.turn_on_bias_radps = deg_per_h * number(c, g, gp, "turn_on_bias_deg_per_h",
                                              e.turn_on_bias_radps / deg_per_h, kNonNegative, "deg/h");
  }
  if (const YAML::Node a = optional_map(c, n, path, "accel", "a map of accelerometer errors",
                                        {"vrw_mps_per_sqrt_h", "bias_instability_mg", "bias_tau_s",
                                         "random_walk_mg_per_sqrt_h", "turn_on_bias_mg"});
      a.IsDefined()) {
    const std::string ap = path + ".accel";
    AccelErrors& e = imu.errors.accel;
    e.vrw_mps_per_sqrt_s =
        number(c, a, ap, "vrw_mps_per_sqrt_h", e.vrw_mps_per_sqrt_s * 60.0, kNonNegative, "m/s/sqrt(h)") /
        60.0;
    e.bias_instability_mps2 =
        kMg * number(c, a, ap, "bias_instability_mg", e.bias_instability_mps2 / kMg, kNonNegative, "mg");
    e.bias_tau_s = number(c, a, ap, "bias_tau_s", e.bias_tau_s, kPositive, "s");
    e.random_walk_mps2_per_sqrt_s =
        kMg / 60.0 *
        number(c, a, ap, "random_walk_mg_per_sqrt_h", e.random_walk_mps2_per_sqrt_s / (kMg / 60.0),
               kNonNegative, "mg/sqrt(h)");
    e.turn_on_bias_mps2 =
        kMg * number(c, a, ap, "turn_on_bias_mg", e.turn_on_bias_mps2 / kMg, kNonNegative, "mg");
  }
}

// KEY.outages: a list of [t0_s, t1_s] scenario-time intervals.
std::vector<GpsOutage> outages(const Ctx& c, const YAML::Node& n, const std::string& path) {
  std::vector<GpsOutage> out;
  const YAML::Node o = n["outages"];
  if (!o.IsDefined()) return out;
  const std::string key = path + ".outages";
  if (!o.IsSequence()) fail(c, o, key, "expected a list of [t0_s, t1_s] intervals, " + got(o));
  for (std::size_t i = 0; i < o.size(); ++i) {
    const auto v =
        to_numbers(c, o[i], key + "[" + std::to_string(i) + "]", 2, "[t0_s, t1_s] with t0_s <= t1_s");
    if (!(v[0] <= v[1]))
      fail(c, o[i], key + "[" + std::to_string(i) + "]",
           "expected [t0_s, t1_s] with t0_s <= t1_s, got [" + fmt(v[0]) + ", " + fmt(v[1]) + "]");
    out.push_back({v[0], v[1]});
  }
  return out;
}

// A slowly wandering GPS error {sigma_horizontal_m, sigma_vertical_m, tau_s} under PARENT.KEY.
void gps_error(const Ctx& c, const YAML::Node& parent, const std::string& parent_path, const char* key,
               CommonGpsErrorConfig& e) {
  const YAML::Node g =
      optional_map(c, parent, parent_path, key, "a map {sigma_horizontal_m, sigma_vertical_m, tau_s}",
                   {"sigma_horizontal_m", "sigma_vertical_m", "tau_s"});
  if (!g.IsDefined()) return;
  const std::string p = join_key(parent_path, key);
  e.sigma_horizontal_m = number(c, g, p, "sigma_horizontal_m", e.sigma_horizontal_m, kNonNegative, "metres");
  e.sigma_vertical_m = number(c, g, p, "sigma_vertical_m", e.sigma_vertical_m, kNonNegative, "metres");
  e.tau_s = number(c, g, p, "tau_s", e.tau_s, kPositive, "s");
}

void parse_gps(const Ctx& c, const YAML::Node& parent, const std::string& parent_path, GpsConfig& gps) {
  const std::string path = join_key(parent_path, "gps");
  const YAML::Node n =
      optional_map(c, parent, parent_path, "gps", "a map {rate_hz, lever_arm_m, latency_s, mode, ...}",
                   {"rate_hz", "lever_arm_m", "latency_s", "mode", "sigma_horizontal_m", "sigma_vertical_m",
                    "float_sigma_horizontal_m", "float_sigma_vertical_m", "fixed_to_float_per_s",
                    "float_to_fixed_per_s", "start_fixed", "outages", "velocity_sigma_mps", "heading",
                    "heading_sigma_deg", "satellites", "hdop", "own_error"});
  gps = GpsConfig{};
  if (!n.IsDefined()) return;
  gps.rate_hz = number(c, n, path, "rate_hz", gps.rate_hz, {1.0, 20.0}, "Hz");
  gps.lever_arm_m = vec3(c, n, path, "lever_arm_m", gps.lever_arm_m, "[x, y, z] in metres (body FRD)", 1.0,
                         {-100.0, 100.0});
  gps.latency_s = number(c, n, path, "latency_s", gps.latency_s, {0.0, 2.0}, "s");
  gps.mode = choice(c, n, path, "mode", "rtk", {"rtk", "single"}) == "rtk" ? GpsMode::kRtk : GpsMode::kSingle;
  gps.sigma_horizontal_m =
      number(c, n, path, "sigma_horizontal_m", gps.sigma_horizontal_m, kNonNegative, "metres");
  gps.sigma_vertical_m = number(c, n, path, "sigma_vertical_m", gps.sigma_vertical_m, kNonNegative, "metres");
  gps.float_sigma_horizontal_m =
      number(c, n, path, "float_sigma_horizontal_m", gps.float_sigma_horizontal_m, kNonNegative, "metres");
  gps.float_sigma_vertical_m =
      number(c, n, path, "float_sigma_vertical_m", gps.float_sigma_vertical_m, kNonNegative, "metres");
  gps.fixed_to_float_per_s =
      number(c, n, path, "fixed_to_float_per_s", gps.fixed_to_float_per_s, kNonNegative, "1/s");
  gps.float_to_fixed_per_s =
      number(c, n, path, "float_to_fixed_per_s", gps.float_to_fixed_per_s, kNonNegative, "1/s");
  gps.start_fixed = boolean(c, n, path, "start_fixed", gps.start_fixed);
  gps.outages = outages(c, n, path);
  gps.velocity_sigma_mps =
      number(c, n, path, "velocity_sigma_mps", gps.velocity_sigma_mps, kNonNegative, "m/s");
  gps.heading = boolean(c, n, path, "heading", gps.heading);
  gps.heading_sigma_rad = deg_to_rad(
      number(c, n, path, "heading_sigma_deg", rad_to_deg(gps.heading_sigma_rad), kNonNegative, "degrees"));
  gps.satellites =
      static_cast<int>(integer(c, n, path, "satellites", gps.satellites, 0, 99, "an integer in [0, 99]"));
  gps.hdop = number(c, n, path, "hdop", gps.hdop, kNonNegative, "");
  gps_error(c, n, path, "own_error", gps.own_error);
}

// sensors.moving_baseline: the receiver's rover reports the baseline from the tanker's antenna (the
// moving base) to its own; the antennas are the two aircraft's GPS antennas.
std::optional<MovingBaselineConfig> parse_moving_baseline(const Ctx& c, const YAML::Node& sensors) {
  const std::string path = "sensors.moving_baseline";
  const YAML::Node n = optional_map(
      c, sensors, "sensors", "moving_baseline", "a map {rate_hz, latency_s, sigma_horizontal_m, ...}",
      {"rate_hz", "latency_s", "sigma_horizontal_m", "sigma_vertical_m", "float_sigma_horizontal_m",
       "float_sigma_vertical_m", "float_bias_sigma_horizontal_m", "float_bias_sigma_vertical_m",
       "fixed_to_float_per_s", "float_to_fixed_per_s", "start_fixed", "outages", "version"});
  if (!n.IsDefined()) return std::nullopt;
  MovingBaselineConfig m;
  m.rate_hz = number(c, n, path, "rate_hz", m.rate_hz, {0.1, 20.0}, "Hz");
  m.latency_s = number(c, n, path, "latency_s", m.latency_s, {0.0, 2.0}, "s");
  for (auto [key, v] : {std::pair<const char*, double*>{"sigma_horizontal_m", &m.sigma_horizontal_m},
                        {"sigma_vertical_m", &m.sigma_vertical_m},
                        {"float_sigma_horizontal_m", &m.float_sigma_horizontal_m},
                        {"float_sigma_vertical_m", &m.float_sigma_vertical_m},
                        {"float_bias_sigma_horizontal_m", &m.float_bias_sigma_horizontal_m},
                        {"float_bias_sigma_vertical_m", &m.float_bias_sigma_vertical_m}})
    *v = number(c, n, path, key, *v, kNonNegative, "metres");
  m.fixed_to_float_per_s =
      number(c, n, path, "fixed_to_float_per_s", m.fixed_to_float_per_s, kNonNegative, "1/s");
  m.float_to_fixed_per_s =
      number(c, n, path, "float_to_fixed_per_s", m.float_to_fixed_per_s, kNonNegative, "1/s");
  m.start_fixed = boolean(c, n, path, "start_fixed", m.start_fixed);
  m.outages = outages(c, n, path);
  m.version = static_cast<int>(integer(c, n, path, "version", m.version, 0, 1, "0 (M8P) or 1 (F9P)"));
  return m;
}

// A number for every camera: one value for all, or a list with one per camera.
template <typename T>
std::vector<T> per_camera(const Ctx& c, const YAML::Node& map, const std::string& path,
                          const std::string& key, std::size_t cameras, bool integral,
                          const std::string& unit) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) return {};
  const std::string k = join_key(path, key);
  const std::string what = std::string(integral ? "an integer" : "a number") + " (" + unit +
                           ") or a list with one per rig camera (" + std::to_string(cameras) + ")";
  const auto one = [&](const YAML::Node& e) -> T {
    if (integral) {
      return static_cast<T>(integer_of(c, e, k, -1000000000000LL, 1000000000000LL, what));
    }
    const double v = to_number(c, e, k, what);
    if (!in_range(kAny, v)) fail(c, e, k, "expected " + describe(kAny, unit) + ", got " + fmt(v));
    return static_cast<T>(v);
  };
  if (n.IsScalar()) return std::vector<T>(cameras, one(n));
  if (!n.IsSequence() || n.size() != cameras) fail(c, n, k, "expected " + what + ", " + got(n));
  std::vector<T> v;
  for (std::size_t i = 0; i < n.size(); ++i) v.push_back(one(n[i]));
  return v;
}

void parse_cameras(const Ctx& c, const YAML::Node& parent, Scenario& s) {
  const std::string path = "sensors.cameras";
  const YAML::Node n =
      optional_map(c, parent, "sensors", "cameras",
                   "a map {fps, clock_offset_ns, jitter_ns, drop_probability, bayer, noise, ...}",
                   {"fps", "clock_offset_ns", "clock_drift_ppm", "clock_offset_assumed_ns",
                    "exposure_offset_ns", "jitter_ns", "drop_probability", "bayer", "noise", "noise_a",
                    "psf_sigma_px", "gain", "gamma", "exposure_ms"});
  CameraTimingConfig& cam = s.sensors.cameras;
  cam = CameraTimingConfig{};
  if (!n.IsDefined()) return;
  const std::size_t count = s.rig.cameras.size();
  cam.fps = number(c, n, path, "fps", cam.fps, {0.0, 1000.0, true, false}, "frames/s");
  cam.clock_offset_ns = per_camera<std::int64_t>(c, n, path, "clock_offset_ns", count, true, "ns");
  cam.clock_drift_ppm = per_camera<double>(c, n, path, "clock_drift_ppm", count, false, "ppm");
  cam.exposure_offset_ns = per_camera<std::int64_t>(c, n, path, "exposure_offset_ns", count, true, "ns");
  cam.clock_offset_assumed_ns =
      per_camera<std::int64_t>(c, n, path, "clock_offset_assumed_ns", count, true, "ns");
  cam.jitter_ns = number(c, n, path, "jitter_ns", cam.jitter_ns, kNonNegative, "ns");
  cam.drop_probability = number(c, n, path, "drop_probability", cam.drop_probability, {0.0, 1.0}, "");
  if (const YAML::Node b = n["bayer"]; b.IsDefined()) {
    const std::string what = "false, true (RGGB) or one of RGGB, GRBG, GBRG, BGGR";
    bool flag = false;
    if (b.IsScalar() && YAML::convert<bool>::decode(b, flag)) {
      cam.format = flag ? PixelFormat::kBayerRG8 : PixelFormat::kRGB8;
    } else if (b.IsScalar() && b.Scalar() == "RGGB") {
      cam.format = PixelFormat::kBayerRG8;
    } else if (b.IsScalar() && b.Scalar() == "GRBG") {
      cam.format = PixelFormat::kBayerGR8;
    } else if (b.IsScalar() && b.Scalar() == "GBRG") {
      cam.format = PixelFormat::kBayerGB8;
    } else if (b.IsScalar() && b.Scalar() == "BGGR") {
      cam.format = PixelFormat::kBayerBG8;
    } else {
      fail(c, b, path + ".bayer", "expected " + what + ", " + got(b));
    }
  }
  cam.noise_sigma = number(c, n, path, "noise", cam.noise_sigma, kNonNegative, "digital numbers");
  cam.noise_a = number(c, n, path, "noise_a", cam.noise_a, {0.0, 100.0}, "DN of variance per DN of signal");
  cam.psf_sigma_px = number(c, n, path, "psf_sigma_px", cam.psf_sigma_px, {0.0, 8.0}, "pixels");
  cam.gain = number(c, n, path, "gain", cam.gain, {0.0, 100.0, true, false}, "raw DN per DN of radiance");
  cam.gamma = number(c, n, path, "gamma", cam.gamma, {0.2, 5.0}, "");
  cam.exposure_ms = number(c, n, path, "exposure_ms", cam.exposure_ms, {0.0, kMaxExposureMs}, "milliseconds");
}

void parse_sensors(const Ctx& c, const YAML::Node& root, Scenario& s) {
  const YAML::Node n =
      optional_map(c, root, "", "sensors",
                   "a map {tanker, receiver, common_gps_error, moving_baseline, cameras, noise_free}",
                   {"tanker", "receiver", "common_gps_error", "moving_baseline", "cameras", "noise_free"});
  s.sensors = SensorsConfig{};
  if (!n.IsDefined()) return;
  for (const char* who : {"tanker", "receiver"}) {
    const std::string path = std::string("sensors.") + who;
    AircraftSensors& a = std::string(who) == "tanker" ? s.sensors.tanker : s.sensors.receiver;
    const YAML::Node m = optional_map(c, n, "sensors", who, "a map {imu, gps}", {"imu", "gps"});
    if (!m.IsDefined()) continue;
    parse_imu(c, m, path, a.imu);
    parse_gps(c, m, path, a.gps);
  }
  gps_error(c, n, "sensors", "common_gps_error", s.sensors.common_gps_error);
  s.sensors.moving_baseline = parse_moving_baseline(c, n);
  parse_cameras(c, n, s);
  if (boolean(c, n, "sensors", "noise_free", false)) make_noise_free(s);
}

Scenario parse_root(const Ctx& c, const YAML::Node& root) {
  if (!root.IsMap())
    fail(c, root, "", "expected a scenario file (a map starting with 'augrig_scenario: 1'), " + got(root));
  check_keys(
      c, root, "",
      {"augrig_scenario", "name", "duration_s", "seed", "start", "rig", "tanker", "receiver", "sensors"});
  const YAML::Node version =
      require(c, root, "", "augrig_scenario", "the format version, augrig_scenario: 1");
  if (!version.IsScalar() || version.Scalar() != "1")
    fail(c, version, "augrig_scenario", "expected format version 1, " + got(version));
  Scenario s;
  s.source = c.name;
  s.name = "scenario";
  if (!c.name.empty() && c.name[0] != '<') s.name = fs::path(c.name).stem().string();
  if (const YAML::Node n = root["name"]; n.IsDefined()) s.name = to_string_value(c, n, "name", "a name");
  s.duration_s = number(c, root, "", "duration_s", 30.0, {0.0, 86400.0, true, false}, "s");
  s.seed = static_cast<std::uint64_t>(
      integer(c, root, "", "seed", 1, 0, std::numeric_limits<std::int64_t>::max(), "an integer >= 0"));
  parse_start(c, root, s);
  parse_rig_key(c, root, s);  // before the receiver: the contact articulation is checked against its limits
  parse_tanker(c, root, s);
  parse_receiver(c, root, s);
  parse_sensors(c, root, s);
  return s;
}

Expected<Scenario> parse_with(const std::string& text, const Ctx& c) {
  return guarded(c, [&] { return parse_root(c, YAML::Load(text)); });
}

fs::path absolute_dir_of(const std::string& path) {
  std::error_code ec;
  const fs::path abs = fs::absolute(fs::path(path), ec);
  return ec ? fs::path(path).parent_path() : abs.parent_path();
}

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const auto yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

}  // namespace

Expected<TimestampNs> gps_ns_from_utc(std::string_view utc) {
  const auto bad = [&] {
    return make_error(
        "gps_ns_from_utc(): expected \"YYYY-MM-DDTHH:MM:SS[.fraction][Z]\" from 1980-01-06 through the year ",
        nav::kMaxYear, ", got '", std::string(utc), "'");
  };
  std::string_view s = utc;
  if (!s.empty() && (s.back() == 'Z' || s.back() == 'z')) s.remove_suffix(1);
  if (s.size() < 19 || s[4] != '-' || s[7] != '-' || (s[10] != 'T' && s[10] != 't' && s[10] != ' ') ||
      s[13] != ':' || s[16] != ':')
    return bad();
  const auto field = [&](std::size_t pos, std::size_t len, int* out) {
    const auto r = std::from_chars(s.data() + pos, s.data() + pos + len, *out);
    return r.ec == std::errc() && r.ptr == s.data() + pos + len;
  };
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, se = 0;
  if (!field(0, 4, &y) || !field(5, 2, &mo) || !field(8, 2, &d) || !field(11, 2, &h) || !field(14, 2, &mi) ||
      !field(17, 2, &se))
    return bad();
  std::int64_t frac_ns = 0;
  if (s.size() > 19) {
    if (s[19] != '.' || s.size() == 20 || s.size() > 29) return bad();
    std::int64_t scale = 100000000;
    for (std::size_t i = 20; i < s.size(); ++i, scale /= 10) {
      if (s[i] < '0' || s[i] > '9') return bad();
      frac_ns += (s[i] - '0') * scale;
    }
  }
  constexpr std::array<int, 12> kDays = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap_year = (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
  if (mo < 1 || mo > 12 || d < 1 || d > kDays[static_cast<std::size_t>(mo - 1)] ||
      (mo == 2 && d == 29 && !leap_year) || h > 23 || mi > 59 || se > 59)
    return bad();
  // Years past nav::kMaxYear would overflow the int64 ns (9999 did; nav/gps_time.hpp).
  if (y > nav::kMaxYear) return bad();
  const std::int64_t days = days_from_civil(y, static_cast<unsigned>(mo), static_cast<unsigned>(d));
  const std::int64_t gps_epoch = days_from_civil(1980, 1, 6);
  if (days < gps_epoch) return bad();
  // GPS - UTC on that day: the table of leap seconds (nav/gps_time.hpp), 18 s since 2017-01-01.
  const int leap_s = nav::leap_seconds_on_day(days);
  const std::int64_t seconds = (days - gps_epoch) * 86400 + h * 3600 + mi * 60 + se + leap_s;
  return seconds * 1000000000LL + frac_ns;
}

Expected<Scenario> load_scenario(const std::string& path) {
  Ctx c;
  c.prefix = "scenario::load(): ";
  c.name = path;
  c.base_dir = absolute_dir_of(path);
  auto text = read_text_file(c.prefix, path, "scenario file");
  if (!text) return text.error();
  return parse_with(*text, c);
}

Expected<Scenario> parse_scenario(const std::string& yaml_text, const std::string& name) {
  Ctx c;
  c.prefix = "scenario::parse(): ";
  c.name = name;
  std::error_code ec;
  c.base_dir = !name.empty() && name[0] != '<' ? absolute_dir_of(name) : fs::current_path(ec);
  return parse_with(yaml_text, c);
}

std::vector<std::string> builtin_scenario_names() {
  return {"demo", "demo-noise-free", "contact-10min", "contact-10min-noise-free"};
}

Expected<std::string> builtin_scenario_text(const std::string& name) {
  if (name == "demo") return std::string(kDemoYaml);
  if (name == "contact-10min") return std::string(kContact10MinYaml);
  return make_error("builtin_scenario_text(): unknown built-in scenario '", name,
                    "'; expected demo or contact-10min");
}

Expected<Scenario> builtin_scenario(const std::string& name) {
  const std::string suffix = "-noise-free";
  const bool noise_free = name.size() > suffix.size() && name.ends_with(suffix);
  const std::string base = noise_free ? name.substr(0, name.size() - suffix.size()) : name;
  auto text = builtin_scenario_text(base);
  if (!text)
    return make_error("builtin_scenario(): unknown built-in scenario '", name,
                      "'; expected one of: ", join(builtin_scenario_names()));
  auto s = parse_scenario(*text, "<builtin:" + base + ">");
  if (!s) return make_error("builtin_scenario(): ", s.error().message);
  if (noise_free) {
    make_noise_free(*s);
    s->name = name;
  }
  s->source = "<builtin:" + name + ">";
  return s;
}

void make_noise_free(Scenario& s) {
  for (AircraftSensors* a : {&s.sensors.tanker, &s.sensors.receiver}) {
    a->imu.errors = ImuErrorModel{};
    GpsConfig& g = a->gps;
    g.sigma_horizontal_m = g.sigma_vertical_m = 0;
    g.float_sigma_horizontal_m = g.float_sigma_vertical_m = 0;
    g.fixed_to_float_per_s = 0;
    g.start_fixed = true;
    g.velocity_sigma_mps = 0;
    g.heading_sigma_rad = 0;
    g.own_error.sigma_horizontal_m = g.own_error.sigma_vertical_m = 0;
  }
  if (MovingBaselineConfig* m = s.sensors.moving_baseline ? &*s.sensors.moving_baseline : nullptr) {
    m->sigma_horizontal_m = m->sigma_vertical_m = 0;
    m->float_sigma_horizontal_m = m->float_sigma_vertical_m = 0;
    m->float_bias_sigma_horizontal_m = m->float_bias_sigma_vertical_m = 0;
    m->fixed_to_float_per_s = 0;
    m->start_fixed = true;
  }
  s.sensors.common_gps_error.sigma_horizontal_m = 0;
  s.sensors.common_gps_error.sigma_vertical_m = 0;
  s.sensors.cameras.jitter_ns = 0;
  s.sensors.cameras.drop_probability = 0;
  s.sensors.cameras.noise_sigma = 0;
  s.sensors.cameras.noise_a = 0;
}

}  // namespace augrig::sim
