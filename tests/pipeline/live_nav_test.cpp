// LiveNav, the nav stage of augrig run, fed a simulated flight's GPS and IMU in arrival order (the
// UDP path is tested in tests/sim/nav_stream_test.cpp and tests/app/cmd_run_test.cpp): poses
// against the simulator's truth in each camera, the verdicts (waiting, good, stale) in plain words,
// and host time mapped to GPS time from the fixes' arrivals.
#include "pipeline/live_nav.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "sim/flight.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"

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

TEST(LiveNav, StreamNamesBelongToTheirAircraft) {
  EXPECT_EQ(aircraft_of_stream("tanker.gps"), Aircraft::kTanker);
  EXPECT_EQ(aircraft_of_stream("receiver.imu"), Aircraft::kReceiver);
  EXPECT_EQ(aircraft_of_stream("receiver"), Aircraft::kReceiver);
  EXPECT_FALSE(aircraft_of_stream("ground.gps").has_value());
  EXPECT_FALSE(aircraft_of_stream("tankers.gps").has_value());
}

}  // namespace
}  // namespace augrig::pipeline
