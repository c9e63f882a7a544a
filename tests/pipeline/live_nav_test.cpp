// LiveNav, the nav stage of augrig run, fed a simulated flight's GPS and IMU in arrival order (the
// UDP path is tested in tests/sim/nav_stream_test.cpp and tests/app/cmd_run_test.cpp): poses
// against the simulator's truth in each camera, the verdicts (waiting, good, stale) in plain words,
// and host time mapped to GPS time from the fixes' arrivals.
#include "pipeline/live_nav.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "pipeline/camera_clock_online.hpp"
#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::pipeline {
namespace {

struct Flight {
  sim::Scenario scenario;
  std::unique_ptr<sim::Flight> flight;
  sim::SensorLogs logs;
};

Flight simulate(double duration_s) {
  Flight f;
  f.scenario = *sim::builtin_scenario("demo");
  f.scenario.duration_s = duration_s;
  f.flight = std::make_unique<sim::Flight>(*sim::Flight::create(f.scenario));
  f.logs = sim::simulate_sensors(f.scenario, *f.flight);
  return f;
}

LiveNav make_nav(const Flight& f, double stale_after_s = 0.5) {
  LiveNavOptions o;
  o.stale_after_s = stale_after_s;
  return LiveNav(f.scenario.rig, f.scenario.boom, f.flight->receptacle_m(),
                 ins_config_for(f.scenario.sensors.tanker), ins_config_for(f.scenario.sensors.receiver), o);
}

// Every sample of both aircraft in arrival order, calling before(arrival) first; `keep` filters.
template <typename Before, typename Keep>
void feed(LiveNav& nav, const sim::SensorLogs& logs, Before&& before, Keep&& keep) {
  struct Item {
    TimestampNs arrival;
    Aircraft who;
    nav::NavEvent e;
  };
  std::vector<Item> items;
  for (int a = 0; a < 2; ++a) {
    const Aircraft who = a ? Aircraft::kReceiver : Aircraft::kTanker;
    for (const nav::ImuSample& s : a ? logs.receiver_imu : logs.tanker_imu)
      items.push_back({s.arrival_ns, who, {s, ClockDomain::kGps, std::nullopt}});
    for (const nav::GpsFix& g : a ? logs.receiver_gps : logs.tanker_gps)
      items.push_back({g.arrival_ns, who, {g, ClockDomain::kGps, std::nullopt}});
  }
  std::stable_sort(items.begin(), items.end(),
                   [](const Item& x, const Item& y) { return x.arrival < y.arrival; });
  for (const Item& it : items) {
    before(it.arrival);
    if (keep(it.who, it.e)) nav.add(it.who, it.e);
  }
}

TEST(LiveNav, ReceiverInEachCameraFollowsTheTruthAsFramesArrive) {
  const Flight f = simulate(20.0);
  LiveNav nav = make_nav(f);
  const std::vector<sim::FrameTruth> frames = sim::frame_truths(f.scenario, *f.flight, f.logs.cameras);
  std::size_t next = 0, n = 0, stale = 0, waiting = 0;
  double max_err = 0, max_att = 0, early_max_err = 0;
  std::size_t early_att_over_3sigma = 0;
  std::size_t converging = 0;
  double last_converging_s = 0;
  // A frame is asked for 40 ms after its mid-exposure, as the pipeline would.
  feed(
      nav, f.logs,
      [&](TimestampNs now) {
        for (; next < frames.size() && frames[next].t_gps_ns + 40'000'000 <= now; ++next) {
          const sim::FrameTruth& t = frames[next];
          const FrameNav fn = nav.at(t.camera, t.t_gps_ns);
          if (!fn.pose) {
            ++waiting;
            ASSERT_FALSE(fn.problems.empty());
            EXPECT_NE(fn.hud.status.find("no pose"), std::string::npos) << fn.hud.status;
            continue;
          }
          if (fn.stale) ++stale;
          if (t.t_true_s < 3.0) continue;  // the filters settle
          const Pose& est = fn.pose->camera.T_a_receiver;
          const double e = (est.translation_m - t.T_cam_receiver.translation_m).norm();
          const Eigen::AngleAxisd d(est.rotation * t.T_cam_receiver.rotation.conjugate());
          // The receiver's yaw (no dual-antenna heading) converges over the first seconds; its 1-sigma
          // says so meanwhile.
          if (t.t_true_s < 10.0) {
            early_max_err = std::max(early_max_err, e);
            early_att_over_3sigma += rad_to_deg(d.angle()) > 3 * fn.hud.sigma_att_deg ? 1 : 0;
          } else {
            max_err = std::max(max_err, e);
            max_att = std::max(max_att, rad_to_deg(d.angle()));
          }
          // Until both filters have converged their sigma is optimistic, and the status says so.
          if (fn.converging) {
            ++converging;
            last_converging_s = t.t_true_s;
            EXPECT_EQ(fn.hud.status, "CONVERGING: " + fn.converging_text);
          } else {
            EXPECT_EQ(fn.hud.status, "fused GPS/INS, both aircraft");
          }
          EXPECT_EQ(fn.hud.fix, nav::FixQuality::kRtkFixed);
          EXPECT_LT(fn.hud.age_s, 0.5);
          EXPECT_GT(fn.hud.sigma_pos_m, 0.0);
          ++n;
        }
      },
      [](Aircraft, const nav::NavEvent&) { return true; });
  std::printf(
      "  %zu frames checked: receiver in the camera max error 3-10 s %.1f mm, 10-20 s %.1f mm and %.3f deg; "
      "%zu frames waited for the filters, %zu stale\n",
      n, 1e3 * early_max_err, 1e3 * max_err, max_att, waiting, stale);
  std::printf("  %zu frames flagged converging, the last at %.1f s\n", converging, last_converging_s);
  EXPECT_GT(n, 900u);
  EXPECT_GT(converging, 0u);
  EXPECT_LT(last_converging_s, 15.0);  // both filters converge within the flight (about 9 s in)
  EXPECT_LT(early_max_err, 0.1);
  EXPECT_LT(early_att_over_3sigma, n / 100);
  EXPECT_LT(max_err, 0.05);
  EXPECT_LT(max_att, 0.5);
  EXPECT_GT(waiting, 0u);  // the first second: nothing to fuse yet
  EXPECT_LT(waiting, 150u);
  EXPECT_EQ(stale, 0u);
}

// Single-point GPS on both aircraft (metres off, each wandering on its own) and a moving-baseline
// rover's vectors on the receiver's stream, arriving 80 ms after their time: the relative position
// is corrected live to centimetres where the solutions alone are metres off, the HUD says so, and
// a frame more than a second past the newest vector (the rover's outage, its silence) is named.
TEST(LiveNav, MovingBaselineCorrectsTheRelativePositionLive) {
  Flight f;
  auto sc = sim::load_scenario(test::data_path("scenarios/moving_baseline.yaml"));
  ASSERT_TRUE(sc) << sc.error().message;
  f.scenario = *sc;
  // Live, the receiver's yaw needs a heading source: its single-point fixes cannot show it on a
  // straight course, and a yaw error moves its antenna's lever arm (a moving baseline between the
  // aircraft says nothing of either's yaw). Its receiver has dual-antenna heading here.
  f.scenario.sensors.receiver.gps.heading = true;
  f.flight = std::make_unique<sim::Flight>(*sim::Flight::create(f.scenario));
  f.logs = sim::simulate_sensors(f.scenario, *f.flight);
  const std::vector<sim::MovingBaselineEpoch> vectors = sim::simulate_moving_baseline(f.scenario, *f.flight);
  ASSERT_FALSE(vectors.empty());
  const std::vector<sim::FrameTruth> frames = sim::frame_truths(f.scenario, *f.flight, f.logs.cameras);
  // Two runs: with the vectors and without; relative position error in the tanker body frame.
  double rms[2] = {0, 0};
  std::size_t corrected_frames = 0, named = 0;
  for (int with = 0; with < 2; ++with) {
    // The receivers' Doppler ground velocity is used: the vectors are carried to each frame's time
    // by the relative velocity, which single-point positions alone give only to decimetres per second.
    nav::InsConfig tk_cfg = ins_config_for(f.scenario.sensors.tanker), rx_cfg = ins_config_for(f.scenario.sensors.receiver);
    for (nav::InsConfig* c : {&tk_cfg, &rx_cfg}) {
      c->use_ground_velocity = true;
      c->ground_velocity_sigma_mps = 0.03;
    }
    LiveNav nav(f.scenario.rig, f.scenario.boom, f.flight->receptacle_m(), tk_cfg, rx_cfg);
    std::size_t next_frame = 0, next_vector = 0, n = 0;
    double sq = 0;
    feed(
        nav, f.logs,
        [&](TimestampNs now) {
          for (; with && next_vector < vectors.size() && vectors[next_vector].arrival_ns <= now; ++next_vector) {
            const sim::MovingBaselineEpoch& v = vectors[next_vector];
            if (v.t_gps_ns >= f.scenario.start_gps_ns + 22 * nav::kNsPerSecond) continue;  // the rover falls silent
            nav::BaselineMeasurement m;
            m.t_ns = v.t_gps_ns;
            m.arrival_ns = v.arrival_ns;
            m.ned_m = v.message.rel_pos_ned_m;
            m.sigma_ned_m = v.message.acc_ned_m;
            m.carr_soln = v.message.carr_soln;
            m.valid = v.message.rel_pos_valid;
            nav.add(Aircraft::kReceiver, {m, ClockDomain::kGps, std::nullopt});
          }
          for (; next_frame < frames.size() && frames[next_frame].t_gps_ns + 40'000'000 <= now; ++next_frame) {
            const sim::FrameTruth& t = frames[next_frame];
            if (t.t_true_s < 10.0 || t.camera != 0) continue;  // the filters settle
            const FrameNav fn = nav.at(t.camera, t.t_gps_ns);
            ASSERT_TRUE(fn.pose) << fn.hud.status;
            // In the rover's 2 s outage (from 18 s), and more than a second after its last vector
            // (22 s): the solutions alone, and said.
            if (with && ((t.t_true_s > 19.1 && t.t_true_s < 20.0) || t.t_true_s > 23.1)) {
              EXPECT_FALSE(fn.pose->baseline_corrected) << t.t_true_s;
              std::string problems;
              for (const std::string& p : fn.problems) problems += p + "; ";
              EXPECT_NE(problems.find("moving baseline: no usable vector in the last second"), std::string::npos)
                  << problems;
              ++named;
            }
            // The error where vectors flow: not in the outage and the float solutions after it.
            if ((t.t_true_s > 18.3 && t.t_true_s < 21.0) || t.t_true_s > 22.2) continue;
            sq += (fn.pose->body.T_a_receiver.translation_m - t.T_body_receiver.translation_m).squaredNorm();
            ++n;
            if (with && fn.pose->baseline_corrected) {
              ++corrected_frames;
              if (!fn.stale && !fn.converging) {
                EXPECT_EQ(fn.hud.status, "fused GPS/INS, both aircraft, and the moving baseline");
              }
            }
          }
        },
        [](Aircraft, const nav::NavEvent&) { return true; });
    rms[with] = std::sqrt(sq / static_cast<double>(n));
    if (with) {
      const LiveBaselineReport r = nav.baseline_report();
      EXPECT_EQ(r.received, 110u) << "up to 22 s: " << r.summary();
      EXPECT_EQ(r.invalid, 11u) << "the 2 s outage at 5 Hz: " << r.summary();
    }
  }
  std::printf("  live relative position RMS (10 s on, vectors flowing): %.1f mm with the moving baseline, %.0f mm without; %zu frames "
              "corrected\n",
              1e3 * rms[1], 1e3 * rms[0], corrected_frames);
  EXPECT_GT(rms[0], 0.5);
  EXPECT_LT(rms[1], 0.04);
  EXPECT_GT(corrected_frames, 250u);
  EXPECT_GT(named, 40u);
}

TEST(LiveNav, GpsSilenceMakesFramesStaleInPlainWordsThenGoodAgain) {
  const Flight f = simulate(12.0);
  LiveNav nav = make_nav(f);
  const TimestampNs t0 = f.scenario.start_gps_ns, cut0 = t0 + s_to_ns(5.0), cut1 = t0 + s_to_ns(7.0);
  std::vector<std::pair<double, FrameNav>> seen;  // (scenario s, verdict)
  TimestampNs next = t0 + s_to_ns(2.0);
  feed(
      nav, f.logs,
      [&](TimestampNs now) {
        for (; next + 40'000'000 <= now; next += s_to_ns(0.1))
          seen.emplace_back(ns_to_s(next - t0), nav.at(0, next));
      },
      [&](Aircraft who, const nav::NavEvent& e) {
        return !(who == Aircraft::kReceiver && e.is_gps() && e.gps().t_ns >= cut0 && e.gps().t_ns <= cut1);
      });
  bool stale_seen = false;
  for (const auto& [t, fn] : seen) {
    ASSERT_TRUE(fn.pose) << "t " << t << ": the IMU carries the pose through a GPS silence";
    const bool expect_stale = t > 5.0 + 0.5 + 0.15 && t < 7.0;  // the last fix before the cut, + 0.5 s
    const bool expect_good = t < 5.45 || t > 7.2;
    if (expect_stale) {
      EXPECT_TRUE(fn.stale) << "t " << t;
      ASSERT_FALSE(fn.problems.empty());
      EXPECT_NE(fn.problems.front().find("receiver GPS: no data for"), std::string::npos)
          << fn.problems.front();
      EXPECT_NE(fn.hud.status.find("STALE"), std::string::npos) << fn.hud.status;
      stale_seen = true;
    }
    if (expect_good) {
      EXPECT_FALSE(fn.stale) << "t " << t << ": " << (fn.problems.empty() ? "" : fn.problems[0]);
    }
  }
  EXPECT_TRUE(stale_seen);
}

TEST(LiveNav, NoFixQualityAndMissingImuAreNamed) {
  const Flight f = simulate(8.0);
  LiveNav nav = make_nav(f);
  const TimestampNs t0 = f.scenario.start_gps_ns;
  // The tanker's receiver reports "no fix" from 4 s; the receiver's IMU stops at 6 s.
  feed(
      nav, f.logs, [](TimestampNs) {},
      [&](Aircraft who, const nav::NavEvent& e) {
        if (who == Aircraft::kTanker && e.is_gps() && e.gps().t_ns >= t0 + s_to_ns(4.0)) {
          nav::NavEvent bad = e;
          std::get<nav::GpsFix>(bad.sample).quality = nav::FixQuality::kInvalid;
          nav.add(who, bad);
          return false;
        }
        return !(who == Aircraft::kReceiver && e.is_imu() && e.imu().t_ns >= t0 + s_to_ns(6.0));
      });
  const FrameNav fn = nav.at(1, t0 + s_to_ns(6.7));
  ASSERT_TRUE(fn.pose);
  EXPECT_TRUE(fn.stale);
  std::string all;
  for (const std::string& p : fn.problems) all += p + "; ";
  EXPECT_NE(all.find("tanker GPS: no fix for"), std::string::npos) << all;
  EXPECT_NE(all.find("receiver IMU: no data for"), std::string::npos) << all;
  EXPECT_EQ(fn.hud.fix, nav::FixQuality::kInvalid);
  // Too far past the receiver's last IMU sample: no pose at all.
  const FrameNav gone = nav.at(1, t0 + s_to_ns(7.2));
  EXPECT_FALSE(gone.pose);
  EXPECT_NE(gone.hud.status.find("no pose: receiver nav"), std::string::npos) << gone.hud.status;
}

// A busy augmenter handles frames late: by then the silence may be over. A frame taken inside it is
// still stale, named by the data it was taken with; frames before and after it are good.
TEST(LiveNav, FramesAskedAboutAfterASilenceEndedAreStillStale) {
  const Flight f = simulate(9.0);
  LiveNav nav = make_nav(f);
  const TimestampNs t0 = f.scenario.start_gps_ns;
  // The receiver's GPS silent 3-4.5 s, its IMU 6-7 s; everything fed before any frame is asked.
  feed(
      nav, f.logs, [](TimestampNs) {},
      [&](Aircraft who, const nav::NavEvent& e) {
        if (who != Aircraft::kReceiver) return true;
        const TimestampNs t = e.is_gps() ? e.gps().t_ns : e.imu().t_ns;
        if (e.is_gps()) return t < t0 + s_to_ns(3.0) || t > t0 + s_to_ns(4.5);
        return t < t0 + s_to_ns(6.0) || t > t0 + s_to_ns(7.0);
      });
  auto problems = [](const FrameNav& fn) {
    std::string all;
    for (const std::string& p : fn.problems) all += p + "; ";
    return all;
  };
  const FrameNav gps = nav.at(1, t0 + s_to_ns(4.2));
  ASSERT_TRUE(gps.pose);
  EXPECT_TRUE(gps.stale);
  EXPECT_NE(problems(gps).find("receiver GPS: no data for 1."), std::string::npos) << problems(gps);
  const FrameNav imu = nav.at(1, t0 + s_to_ns(6.8));
  ASSERT_TRUE(imu.pose);
  EXPECT_TRUE(imu.stale);
  EXPECT_NE(problems(imu).find("receiver IMU: no data for 0.8 s"), std::string::npos) << problems(imu);
  for (double t_s : {2.5, 5.0, 7.5}) {
    const FrameNav good = nav.at(1, t0 + s_to_ns(t_s));
    ASSERT_TRUE(good.pose) << t_s;
    EXPECT_FALSE(good.stale) << t_s << ": " << problems(good);
  }
}

TEST(LiveNav, WaitsInPlainWordsAndMapsHostTimeByTheFixesArrivals) {
  const Flight f = simulate(4.0);
  LiveNav nav = make_nav(f);
  FrameNav fn = nav.at(0, f.scenario.start_gps_ns);
  EXPECT_FALSE(fn.pose);
  ASSERT_EQ(fn.problems.size(), 2u);
  EXPECT_EQ(fn.problems[0], "tanker nav: waiting for IMU data");
  EXPECT_EQ(fn.hud.status, "no pose: tanker nav: waiting for IMU data");
  EXPECT_FALSE(nav.host_to_nav(123).has_value());

  // Fixes arriving on a host clock 1000 s ahead of GPS time, 30 ms (the sim's latency) to 45 ms late.
  const TimestampNs host_minus_gps = -s_to_ns(1000.0);
  for (int i = 0; i < 40; ++i) {
    nav::NavEvent e{f.logs.tanker_gps[static_cast<std::size_t>(i)], ClockDomain::kGps, std::nullopt};
    auto& g = std::get<nav::GpsFix>(e.sample);
    g.arrival_ns = g.t_ns + host_minus_gps + 30'000'000 + (i % 4) * 5'000'000;
    nav.add(Aircraft::kTanker, e);
  }
  const TimestampNs t_gps = f.logs.tanker_gps[20].t_ns;
  const auto mapped = nav.host_to_nav(t_gps + host_minus_gps);
  ASSERT_TRUE(mapped) << mapped.error().message;
  // The lower envelope keeps the constant 30 ms latency in the offset (documented); no more.
  EXPECT_NEAR(static_cast<double>(*mapped - t_gps), -30e6, 1e6);
}

// For the online camera clocks (camera_clock_online.hpp): the tanker's gyro rates on GPS time, each
// at its increment's middle, and its attitude, ground velocity and height from its live fusion.
TEST(LiveNav, GivesTheTankersRatesAndGroundMotionForTheCameraClocks) {
  const Flight f = simulate(6.0);
  LiveNav nav = make_nav(f);
  auto rates = std::make_shared<TankerRates>();
  nav.feed_tanker_rates(rates);
  feed(
      nav, f.logs, [](TimestampNs) {}, [](Aircraft, const nav::NavEvent&) { return true; });
  const TimestampNs t_ns = f.scenario.start_gps_ns + 4'000'000'000;
  const double t = 4.0;
  ASSERT_TRUE(rates->at(t_ns));
  // The gyro's rate (w.r.t. inertial space: the Earth's rate and the gyro's errors are in it).
  EXPECT_LT((*rates->at(t_ns) - f.flight->tanker(t).w_eb_body_radps).norm(), 2e-3);
  const nav::GroundMotionFunction ground = nav.tanker_ground_motion(0);
  const auto g = ground(t_ns);
  ASSERT_TRUE(g);
  const sim::KinematicState k = f.flight->tanker(t);
  const nav::Geodetic geo = nav::geodetic_from_ecef(k.p_ecef_m);
  EXPECT_NEAR(g->height_m, geo.h_m, 1.0);
  EXPECT_LT((g->v_ned_mps - nav::R_ecef_ned(geo.lat_rad, geo.lon_rad).transpose() * k.v_ecef_mps).norm(),
            0.2);
  EXPECT_FALSE(ground(f.scenario.start_gps_ns - 60'000'000'000));  // outside the fusion's history
}

TEST(LiveNav, StreamNamesBelongToTheirAircraft) {
  EXPECT_EQ(aircraft_of_stream("tanker.gps"), Aircraft::kTanker);
  EXPECT_EQ(aircraft_of_stream("receiver.imu"), Aircraft::kReceiver);
  EXPECT_EQ(aircraft_of_stream("receiver"), Aircraft::kReceiver);
  EXPECT_FALSE(aircraft_of_stream("ground.gps").has_value());
  EXPECT_FALSE(aircraft_of_stream("tankers.gps").has_value());
}

}  // namespace
}  // namespace augrig::pipeline
