// sim/moving_baseline: the simulated moving-baseline RTK messages against the flight's truth (the
// antennas placed from the truth poses and lever arms, the vector checked against the ECEF
// difference rotated by GeographicLib's local frame, independently of the simulator), the error
// model's statistics (fixed about 1 cm, float biased, the chain's time in each state, outages
// flagged), and the UBX log read back by nav::read_ubx_file.
#include "sim/moving_baseline.hpp"

#include <cmath>
#include <filesystem>

#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <gtest/gtest.h>

#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::sim {
namespace {

struct Fixture {
  Scenario scenario;
  std::unique_ptr<Flight> flight;
  TruthFunction tanker, receiver;
};

Fixture demo() {
  Fixture f;
  auto s = builtin_scenario("demo");
  EXPECT_TRUE(s) << s.error().message;
  f.scenario = *s;
  auto fl = Flight::create(f.scenario);
  EXPECT_TRUE(fl) << fl.error().message;
  f.flight = std::make_unique<Flight>(*fl);
  const Flight* p = f.flight.get();
  f.tanker = [p](double t) { return p->tanker(t); };
  f.receiver = [p](double t) { return p->receiver(t); };
  return f;
}

// GeographicLib's local east-north-up at the base antenna, turned into NED.
Eigen::Vector3d oracle_ned(const Eigen::Vector3d& base_ecef, const Eigen::Vector3d& rover_ecef) {
  const GeographicLib::Geocentric& earth = GeographicLib::Geocentric::WGS84();
  double lat = 0, lon = 0, h = 0;
  earth.Reverse(base_ecef.x(), base_ecef.y(), base_ecef.z(), lat, lon, h);
  const GeographicLib::LocalCartesian local(lat, lon, h, earth);
  double rlat = 0, rlon = 0, rh = 0, e = 0, n = 0, u = 0;
  earth.Reverse(rover_ecef.x(), rover_ecef.y(), rover_ecef.z(), rlat, rlon, rh);
  local.Forward(rlat, rlon, rh, e, n, u);
  return {n, e, -u};
}

TEST(MovingBaseline, TruthIsTheAntennaVectorInTheBasesNed) {
  const Fixture f = demo();
  const Eigen::Vector3d lb(1.0, 0.5, -1.2), lr(-0.3, 0.2, -1.6);
  for (double t : {0.0, 5.0, 17.3}) {
    const KinematicState b = f.tanker(t), r = f.receiver(t);
    const Eigen::Vector3d pb = b.p_ecef_m + b.R_ecef_body() * lb, pr = r.p_ecef_m + r.R_ecef_body() * lr;
    const Eigen::Vector3d got = true_baseline_ned_m(b, lb, r, lr);
    EXPECT_LT((got - oracle_ned(pb, pr)).norm(), 1e-6) << "t " << t;
    EXPECT_GT(got.norm(), 5.0) << "tens of metres between the aircraft";
  }
}

TEST(MovingBaseline, FixedIsCentimetreFloatIsBiasedOutagesAreFlagged) {
  const Fixture f = demo();
  MovingBaselineConfig c;
  c.rate_hz = 10;
  c.fixed_to_float_per_s = 0.05;
  c.float_to_fixed_per_s = 0.2;
  c.outages = {{10.0, 12.0}};
  MovingBaselineSimulator sim(c, 42, f.scenario.start_gps_ns);
  const std::vector<MovingBaselineEpoch> epochs = sim.generate(f.tanker, f.receiver, f.scenario.duration_s);
  ASSERT_EQ(epochs.size(), static_cast<std::size_t>(std::floor(f.scenario.duration_s * 10)) + 1);
  Eigen::Vector3d sq_fixed = Eigen::Vector3d::Zero();
  std::size_t fixed = 0, floating = 0, invalid = 0;
  for (std::size_t k = 0; k < epochs.size(); ++k) {
    const MovingBaselineEpoch& e = epochs[k];
    const double t = static_cast<double>(e.t_gps_ns - f.scenario.start_gps_ns) / 1e9;
    EXPECT_NEAR(t, 0.1 * static_cast<double>(k), 1e-9);
    EXPECT_EQ(e.arrival_ns - e.t_gps_ns, 80'000'000);
    EXPECT_EQ(e.message.itow_ms, static_cast<std::uint32_t>((e.t_gps_ns / 1'000'000) % 604'800'000));
    if (t >= 10.0 && t <= 12.0) {
      EXPECT_FALSE(e.message.rel_pos_valid) << t;
      EXPECT_TRUE(e.message.ref_obs_miss) << t;
      ++invalid;
      continue;
    }
    ASSERT_TRUE(e.message.rel_pos_valid);
    const Eigen::Vector3d err = e.message.rel_pos_ned_m - e.truth_ned_m;
    if (e.message.carr_soln == 2) {
      sq_fixed += err.cwiseAbs2();
      ++fixed;
      EXPECT_NEAR(e.message.acc_ned_m.x(), 0.01, 1e-12);
    } else {
      EXPECT_EQ(e.message.carr_soln, 1);
      ++floating;
    }
  }
  EXPECT_EQ(invalid, 21u);
  ASSERT_GT(fixed, 100u);
  const Eigen::Vector3d rms = (sq_fixed / static_cast<double>(fixed)).cwiseSqrt();
  EXPECT_NEAR(rms.x(), 0.01, 0.002);
  EXPECT_NEAR(rms.y(), 0.01, 0.002);
  EXPECT_NEAR(rms.z(), 0.015, 0.003);
  EXPECT_GT(floating, 0u) << "float after the outage at least";
  // Right after the outage the rover is in float.
  EXPECT_EQ(epochs[121].message.carr_soln, 1);
}

TEST(MovingBaseline, SameSeedSameMessagesAndTheUbxLogReadsBack) {
  const Fixture f = demo();
  MovingBaselineConfig c;
  MovingBaselineSimulator a(c, 7, f.scenario.start_gps_ns), b(c, 7, f.scenario.start_gps_ns);
  const auto ea = a.generate(f.tanker, f.receiver, 5.0), eb = b.generate(f.tanker, f.receiver, 5.0);
  ASSERT_EQ(ea.size(), eb.size());
  for (std::size_t k = 0; k < ea.size(); ++k)
    EXPECT_EQ(ea[k].message.rel_pos_ned_m, eb[k].message.rel_pos_ned_m);
  for (int version : {0, 1}) {
    c.version = version;
    MovingBaselineSimulator s(c, 7, f.scenario.start_gps_ns);
    const auto epochs = s.generate(f.tanker, f.receiver, 5.0);
    const std::string path =
        test::output_dir("moving_baseline") + "/rover" + std::to_string(version) + ".ubx";
    ASSERT_TRUE(write_relposned_ubx(path, epochs));
    auto log = nav::read_ubx_file(path);
    ASSERT_TRUE(log) << log.error().message;
    ASSERT_EQ(log->relposned.size(), epochs.size());
    EXPECT_EQ(log->counts.skipped_bytes, 0u);
    for (std::size_t k = 0; k < epochs.size(); ++k) {
      const nav::UbxRelPosNed& m = log->relposned[k];
      EXPECT_EQ(m.version, version);
      EXPECT_EQ(m.itow_ms, epochs[k].message.itow_ms);
      EXPECT_LT((m.rel_pos_ned_m - epochs[k].message.rel_pos_ned_m).cwiseAbs().maxCoeff(), 0.5e-4);
      EXPECT_EQ(m.carr_soln, epochs[k].message.carr_soln);
    }
  }
  EXPECT_FALSE(write_relposned_ubx("/nonexistent/dir/x.ubx", ea));
}

}  // namespace
}  // namespace augrig::sim
