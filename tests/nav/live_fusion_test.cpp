// LiveFusion against two oracles: the batch forward filter (nav::fuse without smoothing) fed the
// same data must give the very same states at its epochs, and the flight simulator's truth at
// arbitrary frame times as they arrive in real time (at most 0.3 s behind the newest IMU sample).
#include "nav/live_fusion.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"

namespace augrig::nav {
namespace {

struct SimData {
  sim::Scenario scenario;
  std::unique_ptr<sim::Flight> flight;
  sim::SensorLogs logs;
};

SimData simulate(const std::string& name, double duration_s, std::int64_t receiver_imu_clock_offset_ns = 0) {
  SimData d;
  auto sc = sim::builtin_scenario(name);
  EXPECT_TRUE(sc) << sc.error().message;
  d.scenario = *sc;
  d.scenario.duration_s = duration_s;
  d.scenario.sensors.receiver.imu.clock_offset_ns = receiver_imu_clock_offset_ns;
  auto f = sim::Flight::create(d.scenario);
  EXPECT_TRUE(f) << f.error().message;
  d.flight = std::make_unique<sim::Flight>(std::move(*f));
  d.logs = sim::simulate_sensors(d.scenario, *d.flight);
  return d;
}

InsConfig config_for(const sim::AircraftSensors& s) {
  InsConfig c;
  c.lever_arm_body_m = s.gps.lever_arm_m;
  c.use_heading = s.gps.heading;
  return c;
}

// Feeds IMU samples and fixes in arrival order, calling on_time(arrival) before each.
template <typename F>
void feed(LiveFusion& live, const std::vector<ImuSample>& imu, const std::vector<GpsFix>& gps, F&& on_time) {
  std::size_t i = 0, g = 0;
  while (i < imu.size() || g < gps.size()) {
    const bool take_imu = g >= gps.size() || (i < imu.size() && imu[i].arrival_ns <= gps[g].arrival_ns);
    on_time(take_imu ? imu[i].arrival_ns : gps[g].arrival_ns);
    if (take_imu)
      live.add_imu(imu[i++]);
    else
      live.add_fix(gps[g++]);
  }
}

TEST(LiveFusion, SameStatesAsTheBatchForwardFilter) {
  const SimData d = simulate("demo", 20.0);
  const InsConfig cfg = config_for(d.scenario.sensors.receiver);
  const auto batch = fuse(d.logs.receiver_imu, d.logs.receiver_gps, cfg, /*smooth=*/false);
  ASSERT_TRUE(batch) << batch.error().message;
  const std::vector<NavState> epochs = batch->epochs();

  LiveFusion live(cfg);
  // Each batch epoch is compared once the live filter has passed it (it keeps 5 s of history).
  std::size_t next = 0, compared = 0;
  double max_dp = 0, max_dP = 0;
  auto compare_up_to = [&](TimestampNs t_filter) {
    for (; next < epochs.size() && epochs[next].t_ns <= t_filter; ++next) {
      const auto s = live.at(epochs[next].t_ns);
      ASSERT_TRUE(s) << s.error().message;
      max_dp = std::max(max_dp, (s->p_ecef_m - epochs[next].p_ecef_m).norm());
      max_dP = std::max(max_dP,
                        (s->P - epochs[next].P).cwiseAbs().maxCoeff() / epochs[next].P.cwiseAbs().maxCoeff());
      ++compared;
    }
  };
  feed(live, d.logs.receiver_imu, d.logs.receiver_gps,
       [&](TimestampNs) { compare_up_to(live.status().t_filter_ns); });
  compare_up_to(live.status().t_filter_ns);
  const LiveFusionStatus st = live.status();
  std::printf("  %zu of %zu batch epochs compared: position max diff %.3g m, P max relative diff %.3g\n",
              compared, epochs.size(), max_dp, max_dP);
  EXPECT_TRUE(st.initialised);
  EXPECT_GT(compared, epochs.size() * 9 / 10);  // all but the last 0.3 s or so
  EXPECT_LT(max_dp, 1e-9);
  EXPECT_LT(max_dP, 1e-9);
  // Every fix the batch used, but those in the last fraction of a second that live has not reached.
  EXPECT_LE(st.fixes_used, batch->report().fixes_used);
  EXPECT_GE(st.fixes_used + 5, batch->report().fixes_used);
  EXPECT_EQ(st.fixes_late, 0u);
  EXPECT_EQ(st.imu_refused, 0u);
}

// With the IMU clock estimated (the receiver's IMU 7 ms ahead of GPS time), the live filter estimates
// it online exactly as the batch forward filter does: the same states, clock and covariance at every
// epoch (GPS time), and the status says the estimate.
TEST(LiveFusion, EstimatesTheImuClockAsTheBatchForwardFilter) {
  const SimData d = simulate("demo", 20.0, 7'000'000);
  InsConfig cfg = config_for(d.scenario.sensors.receiver);
  cfg.imu_clock.estimate = true;
  const auto batch = fuse(d.logs.receiver_imu, d.logs.receiver_gps, cfg, /*smooth=*/false);
  ASSERT_TRUE(batch) << batch.error().message;
  const std::vector<NavState> epochs = batch->epochs();
  LiveFusion live(cfg);
  std::size_t next = 0, compared = 0;
  double max_dp = 0, max_dc = 0, max_dP = 0;
  auto compare_up_to = [&](TimestampNs t_filter) {
    for (; next < epochs.size() && epochs[next].t_ns + s_to_ns(0.05) <= t_filter; ++next) {
      const auto s = live.at(epochs[next].t_ns);
      ASSERT_TRUE(s) << s.error().message;
      max_dp = std::max(max_dp, (s->p_ecef_m - epochs[next].p_ecef_m).norm());
      max_dc = std::max(max_dc, std::abs(s->imu_clock_offset_s - epochs[next].imu_clock_offset_s));
      max_dP = std::max(max_dP, (s->clock.P_xc - epochs[next].clock.P_xc).cwiseAbs().maxCoeff() /
                                    epochs[next].clock.P_xc.cwiseAbs().maxCoeff());
      ++compared;
    }
  };
  feed(live, d.logs.receiver_imu, d.logs.receiver_gps,
       [&](TimestampNs) { compare_up_to(live.status().t_filter_ns); });
  compare_up_to(live.status().t_filter_ns);
  const LiveFusionStatus st = live.status();
  std::printf(
      "  %zu of %zu batch epochs compared: position max diff %.3g m, clock %.3g s, P_xc max relative %.3g; "
      "live clock %+.3f ms (1-sigma %.3f ms), batch at its end %+.3f ms\n",
      compared, epochs.size(), max_dp, max_dc, max_dP, 1e3 * st.imu_clock_offset_s,
      1e3 * st.imu_clock_offset_sigma_s, 1e3 * batch->report().imu_clock_offset_s);
  EXPECT_GT(compared, epochs.size() * 9 / 10);
  EXPECT_LT(max_dp, 1e-9);
  EXPECT_LT(max_dc, 1e-12);
  EXPECT_LT(max_dP, 1e-9);
  EXPECT_TRUE(st.imu_clock_estimated);
  EXPECT_GT(st.imu_clock_offset_sigma_s, 0.0);
  EXPECT_LT(std::abs(st.imu_clock_offset_s - 0.007), 4.0 * st.imu_clock_offset_sigma_s);
  EXPECT_EQ(st.fixes_late, 0u);
}

TEST(LiveFusion, FollowsTheTruthInRealTimeWithBoundedMemory) {
  // 60 s of the noisy demo flight, both aircraft fed in arrival order. At each camera frame's
  // arrival (frame time + 40 ms), the receiver relative to the tanker at the frame's mid-exposure
  // time, as the live pipeline asks for it. (Absolute positions carry the GPS error common to both
  // aircraft, decimetres; the relative pose does not.)
  const SimData d = simulate("demo", 60.0);
  LiveFusion tanker(config_for(d.scenario.sensors.tanker)), receiver(config_for(d.scenario.sensors.receiver));
  struct Stream {
    LiveFusion* live;
    const std::vector<ImuSample>* imu;
    const std::vector<GpsFix>* gps;
    std::size_t i = 0, g = 0;
  };
  Stream streams[2] = {{&tanker, &d.logs.tanker_imu, &d.logs.tanker_gps},
                       {&receiver, &d.logs.receiver_imu, &d.logs.receiver_gps}};
  const TimestampNs t0 = d.scenario.start_gps_ns;
  TimestampNs next_frame = t0 + s_to_ns(10.0);  // after both filters settle
  const TimestampNs frame_period = s_to_ns(1.0 / 30.0), frame_latency = s_to_ns(0.040);
  double sum_p2 = 0, max_p = 0, max_att = 0;
  std::size_t n = 0, within_3sigma = 0, max_buffered = 0;
  for (;;) {
    // The next sample of the four streams by arrival time.
    Stream* next = nullptr;
    bool imu_next = false;
    TimestampNs t_next = 0;
    for (Stream& s : streams) {
      if (s.i < s.imu->size() && (!next || (*s.imu)[s.i].arrival_ns < t_next)) {
        next = &s, imu_next = true, t_next = (*s.imu)[s.i].arrival_ns;
      }
      if (s.g < s.gps->size() && (!next || (*s.gps)[s.g].arrival_ns < t_next)) {
        next = &s, imu_next = false, t_next = (*s.gps)[s.g].arrival_ns;
      }
    }
    if (!next) break;
    while (next_frame + frame_latency <= t_next) {
      const auto tk = tanker.at(next_frame);
      const auto rx = receiver.at(next_frame);
      ASSERT_TRUE(tk && rx);
      const double t_s = ns_to_s(next_frame - t0);
      const sim::KinematicState ktk = d.flight->tanker(t_s), krx = d.flight->receiver(t_s);
      // Receiver relative to the tanker, in the tanker body frame.
      const Eigen::Vector3d rel = tk->q_ecef_body.conjugate() * (rx->p_ecef_m - tk->p_ecef_m);
      const Eigen::Vector3d rel_true = ktk.q_ecef_body.conjugate() * (krx.p_ecef_m - ktk.p_ecef_m);
      const double e = (rel - rel_true).norm();
      const double sigma = std::sqrt(tk->P.block<3, 3>(kErrPos, kErrPos).trace() +
                                     rx->P.block<3, 3>(kErrPos, kErrPos).trace());
      within_3sigma += e <= 3 * sigma ? 1 : 0;
      sum_p2 += e * e;
      max_p = std::max(max_p, e);
      const Eigen::AngleAxisd r((tk->q_ecef_body.conjugate() * rx->q_ecef_body) *
                                (ktk.q_ecef_body.conjugate() * krx.q_ecef_body).conjugate());
      max_att = std::max(max_att, rad_to_deg(r.angle()));
      ++n;
      next_frame += frame_period;
    }
    if (imu_next)
      next->live->add_imu((*next->imu)[next->i++]);
    else
      next->live->add_fix((*next->gps)[next->g++]);
    max_buffered = std::max(max_buffered, next->live->status().buffered_imu);
  }
  const double rms = std::sqrt(sum_p2 / static_cast<double>(n));
  std::printf(
      "  %zu frames (10-60 s): relative position RMS %.1f mm, max %.1f mm; relative attitude max %.3f deg; "
      "within 3 sigma %.1f %%; most IMU increments buffered %zu\n",
      n, 1e3 * rms, 1e3 * max_p, max_att, 100.0 * static_cast<double>(within_3sigma) / static_cast<double>(n),
      max_buffered);
  EXPECT_GT(n, 1400u);
  EXPECT_LT(rms, 0.05);  // RTK: centimetres
  EXPECT_LT(max_att, 0.5);
  EXPECT_GT(within_3sigma, n * 95 / 100);
  EXPECT_LE(max_buffered, 4096u);  // history trimmed: memory bounded, not growing with the flight
}

TEST(LiveFusion, NotInitialisedThenQueriesOutsideTheWindowAreErrors) {
  const SimData d = simulate("demo-noise-free", 8.0);
  LiveFusion live(config_for(d.scenario.sensors.tanker));
  EXPECT_FALSE(live.at(d.scenario.start_gps_ns).has_value());
  feed(live, d.logs.tanker_imu, d.logs.tanker_gps, [](TimestampNs) {});
  const LiveFusionStatus st = live.status();
  ASSERT_TRUE(st.initialised);
  EXPECT_FALSE(st.init_summary.empty());
  EXPECT_TRUE(live.at(st.t_imu_ns + s_to_ns(0.9)).has_value());  // held rates, within 1 s
  const auto far = live.at(st.t_imu_ns + s_to_ns(1.1));
  ASSERT_FALSE(far.has_value());
  EXPECT_NE(far.error().message.find("past the last IMU sample"), std::string::npos) << far.error().message;
  EXPECT_FALSE(live.at(d.scenario.start_gps_ns - s_to_ns(1.0)).has_value());
}

TEST(LiveFusion, OutOfOrderAndLateSamplesAreRefusedAndCounted) {
  const SimData d = simulate("demo-noise-free", 6.0);
  LiveFusion live(config_for(d.scenario.sensors.tanker));
  feed(live, d.logs.tanker_imu, d.logs.tanker_gps, [](TimestampNs) {});
  live.add_imu(d.logs.tanker_imu[10]);  // old
  ImuSample bad = d.logs.tanker_imu.back();
  bad.t_ns += s_to_ns(0.005);
  bad.dv_mps.x() = std::nan("");
  live.add_imu(bad);
  live.add_fix(d.logs.tanker_gps.front());  // far behind the filter
  const LiveFusionStatus st = live.status();
  EXPECT_EQ(st.imu_refused, 2u);
  EXPECT_EQ(st.fixes_late, 1u);
  EXPECT_FALSE(st.last_error.empty());
  // Still answering.
  EXPECT_TRUE(live.at(st.t_filter_ns).has_value());
}

TEST(LiveFusion, WithoutAnyFixTheImuBufferStaysBounded) {
  // A receiver that never gets a fix: the filter cannot start, and must not keep every IMU sample.
  const SimData d = simulate("demo-noise-free", 40.0);
  LiveFusion live(config_for(d.scenario.sensors.tanker));
  std::size_t most = 0;
  for (const ImuSample& s : d.logs.tanker_imu) {
    live.add_imu(s);
    most = std::max(most, live.status().buffered_imu);
  }
  const LiveFusionStatus st = live.status();
  EXPECT_FALSE(st.initialised);
  EXPECT_EQ(st.imu_samples, d.logs.tanker_imu.size());
  EXPECT_LE(most, 4097u);
  // A fix now still starts the filter from the recent IMU data.
  for (const GpsFix& f : d.logs.tanker_gps)
    if (f.t_ns > st.t_imu_ns - s_to_ns(3.0)) live.add_fix(f);
  EXPECT_TRUE(live.status().initialised);
}

TEST(LiveFusion, NoFixQualityIsReportedAndCoastsOnTheImu) {
  const SimData d = simulate("demo-noise-free", 10.0);
  LiveFusion live(config_for(d.scenario.sensors.tanker));
  std::vector<GpsFix> gps = d.logs.tanker_gps;
  const TimestampNs t_cut = d.scenario.start_gps_ns + s_to_ns(6.0);
  for (GpsFix& f : gps)
    if (f.t_ns >= t_cut) f.quality = FixQuality::kInvalid;
  feed(live, d.logs.tanker_imu, gps, [](TimestampNs) {});
  const LiveFusionStatus st = live.status();
  EXPECT_EQ(st.fix_quality, FixQuality::kInvalid);
  EXPECT_LT(st.t_valid_fix_ns, t_cut);
  EXPECT_GT(st.t_fix_ns, t_cut);
  EXPECT_GT(st.fixes_invalid, 30u);
  // 4 s of dead reckoning on a noise-free IMU stays close to the truth.
  const TimestampNs t = st.t_filter_ns;
  const auto s = live.at(t);
  ASSERT_TRUE(s);
  const sim::KinematicState k = d.flight->tanker(ns_to_s(t - d.scenario.start_gps_ns));
  EXPECT_LT((s->p_ecef_m - k.p_ecef_m).norm(), 0.5);
}

// data_before(): what a state at t rests on, asked after everything has arrived: inside the IMU's
// silence the sample that opened it, inside the fixes' the fix before it (an invalid fix is none),
// for history_s (5 s) behind the newest data.
TEST(LiveFusion, DataBeforeATimeAreTheSamplesItRestsOnHoweverLateItIsAsked) {
  const SimData d = simulate("demo-noise-free", 10.0);
  const TimestampNs t0 = d.scenario.start_gps_ns;
  std::vector<ImuSample> imu;
  for (const ImuSample& s : d.logs.tanker_imu)
    if (s.t_ns < t0 + s_to_ns(6.0) || s.t_ns > t0 + s_to_ns(7.0)) imu.push_back(s);
  std::vector<GpsFix> gps;
  for (GpsFix f : d.logs.tanker_gps) {
    if (f.t_ns > t0 + s_to_ns(5.5) && f.t_ns < t0 + s_to_ns(6.2)) continue;
    if (f.t_ns > t0 + s_to_ns(8.5)) f.quality = FixQuality::kInvalid;
    gps.push_back(f);
  }
  LiveFusion live(config_for(d.scenario.sensors.tanker));
  feed(live, imu, gps, [](TimestampNs) {});
  auto last_before = [](const auto& v, TimestampNs t, auto valid) {
    TimestampNs best = 0;
    for (const auto& x : v)
      if (x.t_ns <= t && valid(x)) best = std::max(best, x.t_ns);
    return best;
  };
  const auto any = [](const auto&) { return true; };
  const auto valid_fix = [](const GpsFix& f) { return f.quality != FixQuality::kInvalid; };
  for (double t_s : {5.2, 5.8, 6.5, 7.5, 9.0}) {
    const TimestampNs t = t0 + s_to_ns(t_s);
    const LiveFusionDataAt at = live.data_before(t);
    // The IMU: in the silence, the last sample before it; elsewhere t itself (samples 10 ms apart).
    if (t_s == 6.5)
      EXPECT_EQ(at.t_imu_ns, last_before(imu, t, any)) << t_s;
    else
      EXPECT_EQ(at.t_imu_ns, t) << t_s;
    EXPECT_EQ(at.t_valid_fix_ns, last_before(gps, t, valid_fix)) << t_s;
  }
  EXPECT_LT(live.data_before(t0 + s_to_ns(5.8)).t_valid_fix_ns, t0 + s_to_ns(5.5) + 1);
  EXPECT_LT(live.data_before(t0 + s_to_ns(9.0)).t_valid_fix_ns, t0 + s_to_ns(8.5) + 1);
  // Older than history_s (5 s) behind the newest: forgotten.
  EXPECT_EQ(live.data_before(t0 + s_to_ns(2.0)).t_valid_fix_ns, 0);
  // Past the newest sample: the newest.
  EXPECT_EQ(live.data_before(t0 + s_to_ns(20.0)).t_imu_ns, imu.back().t_ns);
}

}  // namespace
}  // namespace augrig::nav
