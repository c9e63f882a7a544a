// Truth trajectories (sim/flight.hpp): derivatives consistent with positions and attitudes, a truly
// level tanker, the racetrack's turn radius, contact exactly at the nozzle tip, the phases.
#include "sim/flight.hpp"

#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "render/models.hpp"
#include "sim/scenario.hpp"

namespace augrig::sim {
namespace {

Scenario builtin(const std::string& name) {
  auto s = builtin_scenario(name);
  EXPECT_TRUE(s) << s.error().message;
  return *s;
}

Flight flight_of(const Scenario& s) {
  auto f = Flight::create(s);
  EXPECT_TRUE(f) << f.error().message;
  return *f;
}

// 6th-order central difference of f at t with step h.
// (Evaluated into a plain value: an Eigen expression must not outlive the temporaries it refers to.)
template <typename F>
auto derivative(const F& f, double t, double h) -> decltype(f(t)) {
  const decltype(f(t)) d = (-f(t - 3 * h) + 9.0 * f(t - 2 * h) - 45.0 * f(t - h) + 45.0 * f(t + h) -
                            9.0 * f(t + 2 * h) + f(t + 3 * h)) /
                           (60.0 * h);
  return d;
}

Eigen::Vector4d quat_vec(Eigen::Quaterniond q, const Eigen::Quaterniond& ref) {
  if (q.coeffs().dot(ref.coeffs()) < 0) q.coeffs() = -q.coeffs();
  return q.coeffs();
}

// Times in legs, turns, roll-ins/outs and receiver transitions of contact-10min (away from joints).
const std::vector<double> kTimes = {0.37,  15.2,  33.3,  60.0,  80.7,  90.9,  120.4,
                                    150.0, 207.6, 233.3, 320.5, 455.5, 512.1, 585.0};

void expect_consistent(const std::function<KinematicState(double)>& truth, double t, const char* who) {
  SCOPED_TRACE(std::string(who) + " at t = " + std::to_string(t));
  const double h = 0.01;
  const KinematicState s = truth(t);
  const Eigen::Vector3d v_num =
      derivative([&](double x) -> Eigen::Vector3d { return truth(x).p_ecef_m; }, t, h);
  const Eigen::Vector3d a_num =
      derivative([&](double x) -> Eigen::Vector3d { return truth(x).v_ecef_mps; }, t, h);
  EXPECT_LT((s.v_ecef_mps - v_num).norm(), 1e-5) << s.v_ecef_mps.transpose() << " vs " << v_num.transpose();
  EXPECT_LT((s.a_ecef_mps2 - a_num).norm(), 1e-5) << s.a_ecef_mps2.transpose() << " vs " << a_num.transpose();
  // q' = 1/2 q (0, w).
  const Eigen::Vector4d qdot_num = derivative(
      [&](double x) -> Eigen::Vector4d { return quat_vec(truth(x).q_ecef_body, s.q_ecef_body); }, t, h);
  const Eigen::Quaterniond w(0.0, s.w_eb_body_radps.x(), s.w_eb_body_radps.y(), s.w_eb_body_radps.z());
  const Eigen::Vector4d qdot = 0.5 * (s.q_ecef_body * w).coeffs();
  EXPECT_LT((qdot - qdot_num).norm(), 1e-9) << qdot.transpose() << " vs " << qdot_num.transpose();
  const Eigen::Vector3d dw_num =
      derivative([&](double x) -> Eigen::Vector3d { return truth(x).w_eb_body_radps; }, t, h);
  EXPECT_LT((s.dw_eb_body_radps2 - dw_num).norm(), 1e-8);
}

TEST(FlightTest, DerivativesMatchPositionsAndAttitudes) {
  const Flight f = flight_of(builtin("contact-10min"));
  for (double t : kTimes) {
    expect_consistent([&](double x) { return f.tanker(x); }, t, "tanker");
    expect_consistent([&](double x) { return f.receiver(x); }, t, "receiver");
  }
}

TEST(FlightTest, LevelTankerKeepsItsHeightAndSpeed) {
  for (const char* pattern : {"straight", "racetrack"}) {
    SCOPED_TRACE(pattern);
    Scenario s = builtin("contact-10min");
    s.tanker.pattern =
        std::string(pattern) == "straight" ? TankerPattern::kStraight : TankerPattern::kRacetrack;
    const Flight f = flight_of(s);
    double worst_h = 0, worst_v = 0, worst_down = 0;
    for (double t = 0; t <= 600.0; t += 0.5) {
      const KinematicState k = f.tanker(t);
      const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
      const Eigen::Vector3d v_ned = nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.v_ecef_mps;
      worst_h = std::max(worst_h, std::abs(g.h_m - s.start.h_m));
      worst_v = std::max(worst_v, std::abs(k.v_ecef_mps.norm() - s.tanker.speed_mps));
      worst_down = std::max(worst_down, std::abs(v_ned.z()));
    }
    std::printf("%s: max |h - h0| = %.3g m, max |speed - V| = %.3g m/s, max |v_down| = %.3g m/s over 600 s\n",
                pattern, worst_h, worst_v, worst_down);
    EXPECT_LT(worst_h, 1e-3);
    EXPECT_LT(worst_v, 1e-9);
    EXPECT_LT(worst_down, 1e-9);
    // The start point is the scenario's.
    const nav::Geodetic g0 = nav::geodetic_from_ecef(f.tanker(0).p_ecef_m);
    EXPECT_NEAR(g0.lat_rad, s.start.lat_rad, 1e-12);
    EXPECT_NEAR(g0.lon_rad, s.start.lon_rad, 1e-12);
  }
}

TEST(FlightTest, RacetrackTurnRadiusAndBank) {
  const Scenario s = builtin("contact-10min");
  const Flight f = flight_of(s);
  const double V = s.tanker.speed_mps;
  const double expected = V * V / (f.turn_gravity_mps2() * std::tan(s.tanker.bank_rad));
  EXPECT_NEAR(f.turn_radius_m(), expected, 1e-9 * expected);
  // First turn: leg 15000 m / 170 m/s = 88.2 s, roll-in 5 s, constant rate for ~112 s.
  for (double t : {100.0, 150.0, 200.0}) {
    const KinematicState k = f.tanker(t);
    const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
    const Eigen::Matrix3d R_ne = nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose();
    const Eigen::Vector3d a_ned = R_ne * k.a_ecef_mps2;
    const double radius = V * V / a_ned.head<2>().norm();
    std::printf("t = %.0f s: turn radius %.2f m (V^2 / (g tan bank) = %.2f m)\n", t, radius, expected);
    EXPECT_NEAR(radius, expected, 0.01 * expected);
    // Roll of the attitude: the bank (R_ned_body = Rz Rx(bank) Ry(aoa): the Euler roll differs slightly).
    const YawPitchRoll e = ypr_from_rotation(R_ne * k.R_ecef_body());
    EXPECT_NEAR(e.roll_rad, s.tanker.bank_rad, deg_to_rad(0.2));
  }
  // After the turn the track is reversed.
  auto track = [&](double t) {
    const KinematicState k = f.tanker(t);
    const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
    const Eigen::Vector3d v = nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.v_ecef_mps;
    return std::atan2(v.y(), v.x());
  };
  EXPECT_NEAR(track(50.0), s.tanker.heading_rad, 1e-9);
  EXPECT_NEAR(std::remainder(track(250.0) - s.tanker.heading_rad - kPi, 2 * kPi), 0.0, 1e-3);
  // Straight legs: wings level, yaw = track + crab, pitch = angle of attack.
  const KinematicState k = f.tanker(50.0);
  const nav::Geodetic g = nav::geodetic_from_ecef(k.p_ecef_m);
  const YawPitchRoll e =
      ypr_from_rotation(nav::R_ecef_ned(g.lat_rad, g.lon_rad).transpose() * k.R_ecef_body());
  EXPECT_NEAR(e.roll_rad, 0.0, 1e-12);
  EXPECT_NEAR(e.pitch_rad, s.tanker.angle_of_attack_rad, 1e-12);
  EXPECT_NEAR(e.yaw_rad, s.tanker.heading_rad, 1e-9);
}

TEST(FlightTest, ReceptacleAtTheNozzleTipAtContact) {
  Scenario s = builtin("demo-noise-free");
  s.receiver.turbulence = TurbulenceConfig{};
  const Flight f = flight_of(s);
  Eigen::Vector3d receptacle;
  make_builtin_receiver(&receptacle);
  EXPECT_EQ(f.receptacle_m(), receptacle);
  const BoomArticulation& c = s.receiver.contact;
  const Eigen::Vector3d tip = boom_pose(s.rig.boom.pivot_body_m, c) *
                              Eigen::Vector3d(BoomDimensions{}.nozzle_tip_m(c.extension_m), 0, 0);
  EXPECT_LT((f.contact_point_body_m() - tip).norm(), 1e-12);
  // Contact from 23 s (4 + 8 + 4 + 7) to the end, and held after it.
  for (double t : {23.0, 23.5, 25.0, 27.9, 28.0, 40.0}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    EXPECT_EQ(f.phase(t), "contact");
    const Eigen::Vector3d at = f.T_tanker_receiver(t) * f.receptacle_m();
    EXPECT_LT((at - tip).norm(), 1e-9) << (at - tip).transpose();
    const BoomArticulation b = f.boom(t);
    EXPECT_NEAR(b.elevation_rad, c.elevation_rad, 1e-12);
    EXPECT_NEAR(b.azimuth_rad, c.azimuth_rad, 1e-12);
    EXPECT_NEAR(b.extension_m, c.extension_m, 1e-12);
    // The same through the ECEF states of both aircraft (rounding of ECEF coordinates: ~1e-9 m).
    const KinematicState tk = f.tanker(t), rc = f.receiver(t);
    const Eigen::Vector3d d =
        (rc.p_ecef_m + rc.q_ecef_body * f.receptacle_m()) - (tk.p_ecef_m + tk.q_ecef_body * tip);
    EXPECT_LT(d.norm(), 1e-6);
  }
  // Observation: 30 m aft, 2 m right, 12 m below the contact point.
  EXPECT_LT(((f.T_tanker_receiver(2.0) * f.receptacle_m() - tip) - Eigen::Vector3d(-30, 2, 12)).norm(), 1e-9);
}

TEST(FlightTest, AttachedBoomFollowsTheReceptacleInTurbulence) {
  const Scenario s = builtin("contact-10min");
  const Flight f = flight_of(s);
  const BoomDimensions dims;
  double worst = 0, moved = 0;
  for (double t = 95.0; t < 510.0; t += 7.3) {
    ASSERT_EQ(f.phase(t), "contact");
    const BoomArticulation b = f.boom(t);
    const Eigen::Vector3d tip =
        boom_pose(s.rig.boom.pivot_body_m, b) * Eigen::Vector3d(dims.nozzle_tip_m(b.extension_m), 0, 0);
    worst = std::max(worst, (f.T_tanker_receiver(t) * f.receptacle_m() - tip).norm());
    moved = std::max(moved, std::abs(b.extension_m - s.receiver.contact.extension_m));
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_GT(moved, 0.01);  // turbulence moves the boom
  // Not attached: the boom stays at the contact articulation.
  EXPECT_EQ(f.boom(10.0).extension_m, s.receiver.contact.extension_m);
}

TEST(FlightTest, PhasesInOrderAndSmoothAtTheirJoints) {
  Scenario s = builtin("contact-10min-noise-free");
  s.receiver.turbulence = TurbulenceConfig{};
  const Flight f = flight_of(s);
  double start = 0;
  for (const ReceiverPhase& p : s.receiver.phases) {
    EXPECT_EQ(f.phase(start + 0.5 * p.duration_s), p.name);
    // Minimum-jerk joints: position continuous and at rest (relative velocity 0) at each joint.
    const Eigen::Vector3d a = f.T_tanker_receiver(start - 1e-4).translation_m;
    const Eigen::Vector3d b = f.T_tanker_receiver(start + 1e-4).translation_m;
    EXPECT_LT((a - b).norm(), 1e-9) << p.name;
    start += p.duration_s;
  }
  EXPECT_EQ(f.phase(-5.0), s.receiver.phases.front().name);
  EXPECT_EQ(f.phase(1e4), s.receiver.phases.back().name);
  // Halfway through a transition the receptacle is halfway (S(1/2) = 1/2).
  const Eigen::Vector3d mid = f.T_tanker_receiver(20.0 + 15.0) * f.receptacle_m() - f.contact_point_body_m();
  EXPECT_LT((mid - Eigen::Vector3d(-22.5, 1.0, 8.0)).norm(), 1e-9);
}

TEST(FlightTest, TurbulenceHasTheStatedSigmaAndIsSeeded) {
  Scenario s = builtin("demo");
  s.duration_s = 20000;
  s.receiver.phases = {{"hold", 1.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), false}};
  s.receiver.turbulence.sigma_m = {0.3, 0.2, 0.1};
  s.receiver.turbulence.sigma_rad = {deg_to_rad(0.5), deg_to_rad(0.4), deg_to_rad(0.3)};
  const Flight f = flight_of(s);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sum2 = Eigen::Vector3d::Zero();
  int n = 0;
  for (double t = 0; t < s.duration_s; t += 0.5, ++n) {
    const Eigen::Vector3d d = f.T_tanker_receiver(t) * f.receptacle_m() - f.contact_point_body_m();
    sum += d;
    sum2 += d.cwiseProduct(d);
  }
  const Eigen::Vector3d mean = sum / n;
  const Eigen::Vector3d sd = (sum2 / n - mean.cwiseProduct(mean)).cwiseSqrt();
  std::printf("turbulence sample sigma over %.0f s: %.3f %.3f %.3f m\n", s.duration_s, sd.x(), sd.y(),
              sd.z());
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(sd[i], s.receiver.turbulence.sigma_m[i], 0.1 * s.receiver.turbulence.sigma_m[i]);
  // Same seed, same truth; another seed, another realisation.
  const Flight g = flight_of(s);
  EXPECT_EQ(f.receiver(123.4).p_ecef_m, g.receiver(123.4).p_ecef_m);
  s.seed += 1;
  const Flight h = flight_of(s);
  EXPECT_GT((f.receiver(123.4).p_ecef_m - h.receiver(123.4).p_ecef_m).norm(), 1e-3);
}

TEST(FlightTest, ReceiverFliesCloseToTheTankersAttitude) {
  const Flight f = flight_of(builtin("contact-10min"));
  for (double t = 0; t < 600; t += 10) {
    const Eigen::Quaterniond d = f.tanker(t).q_ecef_body.conjugate() * f.receiver(t).q_ecef_body;
    EXPECT_LT(Eigen::AngleAxisd(d).angle(), deg_to_rad(3.0)) << t;
  }
}

TEST(FlightTest, RejectsBadScenarios) {
  Scenario s = builtin("demo");
  s.receiver.phases.clear();
  EXPECT_FALSE(Flight::create(s));
  s = builtin("contact-10min");
  s.tanker.roll_in_s = 1000;
  auto f = Flight::create(s);
  ASSERT_FALSE(f);
  EXPECT_NE(f.error().message.find("roll_in_s"), std::string::npos) << f.error().message;
}

}  // namespace
}  // namespace augrig::sim
