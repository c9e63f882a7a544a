// Scenario files and built-ins (sim/scenario.hpp): built-ins parse and equal their asset copies,
// defaults, and every bad input gives a located error naming the key.
#include "sim/scenario.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::sim {
namespace {

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Everything but `source` (and the rig compared through its canonical YAML).
void expect_same(const Scenario& a, const Scenario& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.duration_s, b.duration_s);
  EXPECT_EQ(a.start_gps_ns, b.start_gps_ns);
  EXPECT_EQ(a.start.lat_rad, b.start.lat_rad);
  EXPECT_EQ(a.start.lon_rad, b.start.lon_rad);
  EXPECT_EQ(a.start.h_m, b.start.h_m);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_TRUE(a.tanker == b.tanker);
  EXPECT_TRUE(a.receiver == b.receiver);
  EXPECT_EQ(a.rig_name, b.rig_name);
  EXPECT_EQ(rig_to_yaml(a.rig), rig_to_yaml(b.rig));
  EXPECT_TRUE(a.sensors == b.sensors);
}

TEST(ScenarioTest, BuiltinsParseAndFly) {
  for (const std::string& name : builtin_scenario_names()) {
    SCOPED_TRACE(name);
    auto s = builtin_scenario(name);
    ASSERT_TRUE(s) << s.error().message;
    EXPECT_EQ(s->name, name);
    EXPECT_EQ(s->source, "<builtin:" + name + ">");
    EXPECT_EQ(s->rig_name, "paper_default");
    EXPECT_EQ(s->rig.cameras.size(), 2u);
    auto f = Flight::create(*s);
    ASSERT_TRUE(f) << f.error().message;
    EXPECT_EQ(f->phase(s->duration_s - 1.0), name.starts_with("demo") ? "contact" : "pre-contact-2");
  }
  auto demo = builtin_scenario("demo");
  ASSERT_TRUE(demo);
  EXPECT_EQ(demo->duration_s, 28.0);
  EXPECT_EQ(demo->tanker.pattern, TankerPattern::kStraight);
  EXPECT_EQ(demo->sensors.tanker.imu.errors, *imu_preset("navigation"));
  EXPECT_EQ(demo->sensors.receiver.imu.errors, *imu_preset("tactical"));
  EXPECT_EQ(demo->sensors.tanker.gps.mode, GpsMode::kRtk);
  EXPECT_EQ(demo->receiver.phases.size(), 5u);
  EXPECT_TRUE(demo->receiver.phases.back().attached);
  EXPECT_EQ(demo->receiver.phases[2].offset_m, Eigen::Vector3d(-15, 0, 4));  // held from the previous phase
  auto ten = builtin_scenario("contact-10min");
  ASSERT_TRUE(ten);
  EXPECT_EQ(ten->duration_s, 600.0);
  EXPECT_EQ(ten->tanker.pattern, TankerPattern::kRacetrack);
  EXPECT_EQ(ten->sensors.tanker.gps.outages.size(), 1u);
  auto quiet = builtin_scenario("contact-10min-noise-free");
  ASSERT_TRUE(quiet);
  EXPECT_EQ(quiet->sensors.receiver.imu.errors, ImuErrorModel{});
  EXPECT_EQ(quiet->sensors.common_gps_error.sigma_vertical_m, 0.0);
  EXPECT_EQ(quiet->sensors.cameras.jitter_ns, 0.0);
  EXPECT_TRUE(quiet->receiver == ten->receiver);  // the truth is unchanged
  auto unknown = builtin_scenario("nope");
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("demo, demo-noise-free"), std::string::npos)
      << unknown.error().message;
}

TEST(ScenarioTest, AssetCopiesEqualTheBuiltins) {
  for (const char* name : {"demo", "contact-10min"}) {
    SCOPED_TRACE(name);
    const std::string path = test::data_path(std::string("../../assets/scenarios/") + name + ".yaml");
    auto text = builtin_scenario_text(name);
    ASSERT_TRUE(text);
    EXPECT_EQ(read_text(path), *text);
    auto file = load_scenario(path);
    ASSERT_TRUE(file) << file.error().message;
    auto builtin = builtin_scenario(name);
    ASSERT_TRUE(builtin);
    EXPECT_EQ(file->source, path);
    expect_same(*file, *builtin);
  }
}

TEST(ScenarioTest, DefaultsOfAMinimalFile) {
  auto s = load_scenario(test::data_path("scenarios/minimal.yaml"));
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->name, "minimal");
  EXPECT_EQ(s->duration_s, 30.0);
  EXPECT_EQ(s->seed, 1u);
  EXPECT_EQ(s->start_gps_ns, *gps_ns_from_utc("2024-06-01T12:00:00Z"));
  EXPECT_EQ(s->start.lat_rad, deg_to_rad(51.0));
  EXPECT_EQ(s->start.h_m, 7000.0);
  EXPECT_TRUE(s->tanker == TankerFlightConfig{});
  EXPECT_EQ(s->receiver.phases.size(), 5u);
  EXPECT_EQ(s->receiver.turbulence.sigma_m, Eigen::Vector3d::Zero());
  EXPECT_EQ(s->rig_name, "paper_default");
  EXPECT_TRUE(s->sensors == SensorsConfig{});
  EXPECT_EQ(s->sensors.tanker.imu.rate_hz, 200.0);
  EXPECT_TRUE(Flight::create(*s));
}

TEST(ScenarioTest, RigFileRelativeToTheScenarioAndOtherKeys) {
  const std::string path = test::data_path("scenarios/with_rig.yaml");
  auto s = load_scenario(path);
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->name, "with a rig file");
  EXPECT_EQ(s->rig_name, test::data_path("rigs/example.yaml"));
  EXPECT_EQ(s->rig.cameras.at(1).near_m, 1.5);
  EXPECT_EQ(s->start_gps_ns, 2315LL * 604800 * 1000000000 + 302400500000000LL);
  EXPECT_NEAR(s->start.lat_rad, deg_to_rad(-33.9), 1e-15);
  EXPECT_NEAR(s->receiver.contact.azimuth_rad, deg_to_rad(5.0), 1e-15);
  EXPECT_EQ(s->sensors.cameras.format, PixelFormat::kBayerGR8);
  EXPECT_EQ(s->sensors.cameras.clock_offset_ns, (std::vector<std::int64_t>{500, 500}));
  EXPECT_EQ(s->sensors.cameras.clock_drift_ppm, (std::vector<double>{1.5, -2.0}));
  EXPECT_EQ(s->sensors.cameras.jitter_ns, 0.0);  // noise_free: true wins over the key
  EXPECT_EQ(s->sensors.tanker.imu.errors, ImuErrorModel{});
  // The same text parsed from a string resolves the rig path against the current directory.
  auto text = parse_scenario(read_text(path), "<string>");
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().message.find("scenario::parse(): <string>:6:6: key 'rig': cannot load the rig file"),
            std::string::npos)
      << text.error().message;
}

TEST(ScenarioTest, OverridesOnTopOfAPreset) {
  auto s = parse_scenario(R"(augrig_scenario: 1
sensors:
  receiver:
    imu:
      gyro: {arw_deg_per_sqrt_h: 0.2, bias_tau_s: 100}
      preset: consumer
      accel: {turn_on_bias_mg: 3}
    gps: {mode: single, sigma_horizontal_m: 1.2, heading: true, heading_sigma_deg: 0.5, outages: [[1, 2]]}
)",
                          "inline.yaml");
  ASSERT_TRUE(s) << s.error().message;
  const ImuErrorModel consumer = *imu_preset("consumer");
  const ImuErrorModel& e = s->sensors.receiver.imu.errors;
  EXPECT_NEAR(e.gyro.arw_rad_per_sqrt_s, deg_to_rad(0.2) / 60.0, 1e-18);
  EXPECT_EQ(e.gyro.bias_tau_s, 100.0);
  EXPECT_NEAR(e.gyro.bias_instability_radps, consumer.gyro.bias_instability_radps, 1e-18);
  EXPECT_NEAR(e.accel.turn_on_bias_mps2, 3e-3 * 9.80665, 1e-15);
  EXPECT_NEAR(e.accel.vrw_mps_per_sqrt_s, consumer.accel.vrw_mps_per_sqrt_s, 1e-18);
  const GpsConfig& g = s->sensors.receiver.gps;
  EXPECT_EQ(g.mode, GpsMode::kSingle);
  EXPECT_EQ(g.sigma_horizontal_m, 1.2);
  EXPECT_TRUE(g.heading);
  EXPECT_NEAR(g.heading_sigma_rad, deg_to_rad(0.5), 1e-15);
  ASSERT_EQ(g.outages.size(), 1u);
  EXPECT_EQ(g.outages[0].t1_s, 2.0);
  EXPECT_TRUE(s->sensors.tanker == AircraftSensors{});
}

// The cameras' clocks as the rig's calibration has them (what the live nav's poses assume) apart
// from the truth: the true offsets by default, a list or one value for all otherwise.
TEST(ScenarioTest, CameraClockOffsetsAssumedApartFromTheTruth) {
  auto s = parse_scenario(R"(augrig_scenario: 1
sensors:
  cameras: {clock_offset_ns: [3700000, -2400000], clock_offset_assumed_ns: 0}
)",
                          "inline.yaml");
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->sensors.cameras.clock_offset_ns, (std::vector<std::int64_t>{3'700'000, -2'400'000}));
  EXPECT_EQ(s->sensors.cameras.assumed_clock_offsets_ns(2), (std::vector<std::int64_t>{0, 0}));
  auto calibrated = parse_scenario(R"(augrig_scenario: 1
sensors:
  cameras: {clock_offset_ns: [3700000, -2400000]}
)",
                                   "inline.yaml");
  ASSERT_TRUE(calibrated) << calibrated.error().message;
  EXPECT_EQ(calibrated->sensors.cameras.assumed_clock_offsets_ns(2),
            (std::vector<std::int64_t>{3'700'000, -2'400'000}));
  EXPECT_EQ(calibrated->sensors.cameras.assumed_clock_offsets_ns(3),
            (std::vector<std::int64_t>{3'700'000, -2'400'000, 0}));
  auto bad = parse_scenario(R"(augrig_scenario: 1
sensors:
  cameras: {clock_offset_assumed_ns: [1, 2, 3]}
)",
                            "inline.yaml");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("inline.yaml:3"), std::string::npos) << bad.error().message;
  EXPECT_NE(bad.error().message.find("sensors.cameras.clock_offset_assumed_ns"), std::string::npos)
      << bad.error().message;
  EXPECT_NE(bad.error().message.find("one per rig camera (2)"), std::string::npos) << bad.error().message;
}

// Each aircraft's IMU clock against GPS time: parsed, bounded like the other keys, 0 by default,
// and kept by noise_free (it is a clock, not noise).
TEST(ScenarioTest, ImuClockOffsetAndDrift) {
  auto s = parse_scenario(R"(augrig_scenario: 1
sensors:
  noise_free: true
  tanker:
    imu: {preset: navigation, clock_offset_ns: 7000000}
  receiver:
    imu: {clock_offset_ns: -4000000, clock_drift_ppm: 20}
)",
                          "inline.yaml");
  ASSERT_TRUE(s) << s.error().message;
  EXPECT_EQ(s->sensors.tanker.imu.clock_offset_ns, 7'000'000);
  EXPECT_EQ(s->sensors.tanker.imu.clock_drift_ppm, 0.0);
  EXPECT_EQ(s->sensors.receiver.imu.clock_offset_ns, -4'000'000);
  EXPECT_EQ(s->sensors.receiver.imu.clock_drift_ppm, 20.0);
  EXPECT_EQ(s->sensors.receiver.imu.errors, ImuErrorModel{});  // noise_free
  auto plain = parse_scenario("augrig_scenario: 1\n", "inline.yaml");
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->sensors.tanker.imu.clock_offset_ns, 0);
  EXPECT_EQ(plain->sensors.receiver.imu.clock_drift_ppm, 0.0);
  const std::pair<const char*, const char*> bad[] = {
      {"clock_offset_ns: 2000000000", "expected an integer in [-1000000000, 1000000000] ns"},
      {"clock_offset_ns: 1.5", "expected an integer in [-1000000000, 1000000000] ns"},
      {"clock_drift_ppm: 5000", "expected a number in [-1000, 1000] ppm, got 5000"},
      {"clock_drift_ppm: fast", "expected a number in [-1000, 1000] ppm"},
  };
  for (const auto& [value, says] : bad) {
    auto e = parse_scenario(
        std::string("augrig_scenario: 1\nsensors:\n  tanker:\n    imu: {") + value + "}\n", "inline.yaml");
    ASSERT_FALSE(e) << value;
    const std::string key = std::string("key 'sensors.tanker.imu.") +
                            std::string(value).substr(0, std::string(value).find(':')) + "'";
    EXPECT_NE(e.error().message.find("inline.yaml:4:"), std::string::npos) << e.error().message;
    EXPECT_NE(e.error().message.find(key), std::string::npos) << e.error().message;
    EXPECT_NE(e.error().message.find(says), std::string::npos) << e.error().message;
  }
}

TEST(ScenarioTest, UtcToGpsTime) {
  // GPS week 2295 began on 2023-12-31; GPS - UTC = 18 s since 2017.
  EXPECT_EQ(*gps_ns_from_utc("2023-12-31T00:00:00Z"), (2295LL * 604800 + 18) * 1000000000);
  EXPECT_EQ(*gps_ns_from_utc("1980-01-06T00:00:00Z"), 0);
  EXPECT_EQ(*gps_ns_from_utc("1980-01-06T00:00:01.25"), 1250000000);
  // Just before and after the 2016-12-31 leap second.
  EXPECT_EQ(*gps_ns_from_utc("2017-01-01T00:00:00Z") - *gps_ns_from_utc("2016-12-31T23:59:59Z"), 2000000000);
  for (const char* bad :
       {"2024-13-01T00:00:00Z", "2023-02-29T00:00:00Z", "1979-12-31T00:00:00Z", "2024-06-01",
        "2024-06-01T12:00:00.Z", "2024-06-01T25:00:00Z", "9999-12-31T23:59:59Z", "2100-01-01T00:00:00Z"}) {
    EXPECT_FALSE(gps_ns_from_utc(bad)) << bad;
  }
  EXPECT_TRUE(gps_ns_from_utc("2024-02-29T00:00:00Z"));
}

struct BadScenario {
  const char* file;
  int line;
  const char* key;
  const char* says;
};

class BadScenarioTest : public ::testing::TestWithParam<BadScenario> {};

TEST_P(BadScenarioTest, NamesFileLineAndKey) {
  const BadScenario& b = GetParam();
  const std::string path = test::data_path(std::string("scenarios/") + b.file);
  auto s = load_scenario(path);
  ASSERT_FALSE(s) << b.file;
  const std::string& m = s.error().message;
  EXPECT_EQ(m.rfind("scenario::load(): " + path + ":" + std::to_string(b.line) + ":", 0), 0u) << m;
  if (*b.key) {
    EXPECT_NE(m.find(std::string("key '") + b.key + "'"), std::string::npos) << m;
  }
  EXPECT_NE(m.find(b.says), std::string::npos) << m;
}

INSTANTIATE_TEST_SUITE_P(
    AllKinds, BadScenarioTest,
    ::testing::Values(
        BadScenario{"bad_unknown_key.yaml", 4, "tanker.bnak_deg", "allowed keys here: pattern"},
        BadScenario{"bad_nested_unknown_key.yaml", 6, "sensors.receiver.gps.leverarm_m", "unknown key"},
        BadScenario{"bad_wrong_type.yaml", 3, "tanker.speed_mps",
                    "expected a number in [0, 400] m/s, got 'fast'"},
        BadScenario{"bad_negative_rate.yaml", 6, "sensors.tanker.imu.rate_hz", "[100, 400] Hz, got -200"},
        BadScenario{"bad_gps_rate.yaml", 4, "sensors.tanker.gps.rate_hz", "[1, 20] Hz, got 50"},
        BadScenario{"bad_missing_rig.yaml", 3, "rig", "cannot load the rig file"},
        BadScenario{"bad_missing_version.yaml", 1, "augrig_scenario", "missing"},
        BadScenario{"bad_syntax.yaml", 3, "", "YAML syntax error"},
        BadScenario{"bad_phase_duration.yaml", 5, "receiver.phases[1].duration_s",
                    "missing; expected a number > 0 s"},
        BadScenario{"bad_contact_limits.yaml", 6, "receiver.contact.extension_m",
                    "limits [0, 5.8] metres, got 9"},
        BadScenario{"bad_outage.yaml", 5, "sensors.receiver.gps.outages[1]", "t0_s <= t1_s, got [35, 30]"},
        BadScenario{"bad_utc.yaml", 3, "start.utc", "YYYY-MM-DDTHH:MM:SS"},
        BadScenario{"bad_preset.yaml", 4, "sensors.tanker.imu.preset",
                    "one of noise_free, navigation, tactical, consumer"},
        BadScenario{"bad_bayer.yaml", 5, "sensors.cameras.bayer", "RGGB, GRBG, GBRG, BGGR, got 'RGBG'"},
        BadScenario{"bad_camera_list.yaml", 4, "sensors.cameras.clock_offset_ns", "one per rig camera (2)"},
        BadScenario{"bad_roll_in.yaml", 6, "tanker.roll_in_s", "expected at most"},
        BadScenario{"bad_two_start_times.yaml", 3, "start", "only one of utc, gps_time_ns"},
        BadScenario{"bad_drop_probability.yaml", 3, "sensors.cameras.drop_probability", "[0, 1], got 1.5"},
        // Values whose arithmetic overflows: year 9999 in int64 ns, 1e300 m in every sample.
        BadScenario{"bad_utc_year_9999.yaml", 3, "start.utc", "from 1980-01-06 through the year 2099"},
        BadScenario{"bad_gps_time_ns.yaml", 3, "start.gps_time_ns", "through the year 2099"},
        BadScenario{"bad_phase_offset.yaml", 5, "receiver.phases[1].offset_m",
                    "expected a number in [-10000, 10000] as element 0, got -1e+300"},
        BadScenario{"bad_huge_leg.yaml", 3, "tanker.leg_length_m", "expected a number in (0, 1e+09] metres"}),
    [](const auto& info) {
      std::string n = info.param.file;
      return n.substr(0, n.find('.'));
    });

TEST(ScenarioTest, DirectoryIsNotAScenarioFile) {
  const std::string dir = test::output_dir("scenario_dir") + "/s.yaml";
  std::filesystem::create_directories(dir);
  auto s = load_scenario(dir);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "scenario::load(): " + dir + ": is a directory, expected a file");
}

TEST(ScenarioTest, MissingFileAndMissingRigFileMessages) {
  auto s = load_scenario("/nonexistent/scenario.yaml");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("cannot open the scenario file"), std::string::npos);
  auto r = load_scenario(test::data_path("scenarios/bad_missing_rig.yaml"));
  ASSERT_FALSE(r);
  // The rig loader's own message, with the resolved path, is part of it.
  EXPECT_NE(r.error().message.find(test::data_path("scenarios/no_such_rig.yaml")), std::string::npos)
      << r.error().message;
  EXPECT_NE(r.error().message.find("cannot open the rig file"), std::string::npos) << r.error().message;
}

}  // namespace
}  // namespace augrig::sim
