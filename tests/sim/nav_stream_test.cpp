// Tests for sim/nav_stream.hpp against the real receiving path: the four streams of a short
// simulated flight are sent over loopback UDP and received by nav::open_nav_input (udp://...?format=nmea
// and ?format=imu), as `augrig run --nav sim` receives them. Oracles: the simulator's own logs (GPS
// to the NMEA writer's precision, and exactly as the batch parser reads the writer's text; IMU bit
// for bit) and the shared SimClock for the pacing.
#include "sim/nav_stream.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "core/clock.hpp"
#include "nav/imu_stream.hpp"
#include "nav/live_input.hpp"
#include "nav/nmea.hpp"
#include "nav/udp_socket.hpp"
#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/sim_clock.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::sim {
namespace {

using namespace std::chrono_literals;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

struct SimData {
  Scenario scenario;
  SensorLogs logs;
};

// The demo flight, cut short; computed once per duration.
const SimData& sim_data(double duration_s) {
  static std::vector<std::pair<double, std::unique_ptr<SimData>>> cache;
  for (const auto& [d, data] : cache) {
    if (d == duration_s) return *data;
  }
  auto data = std::make_unique<SimData>();
  data->scenario = *builtin_scenario("demo");
  data->scenario.duration_s = duration_s;
  const Flight flight = *Flight::create(data->scenario);
  data->logs = simulate_sensors(data->scenario, flight);
  cache.emplace_back(duration_s, std::move(data));
  return *cache.back().second;
}

// Stream index in loopback_targets() order.
enum Stream { kTankerGps = 0, kTankerImu = 1, kReceiverGps = 2, kReceiverImu = 3 };
constexpr const char* kNames[] = {"tanker.gps", "tanker.imu", "receiver.gps", "receiver.imu"};

const std::vector<nav::GpsFix>& gps_log(const SensorLogs& l, int s) {
  return s == kTankerGps ? l.tanker_gps : l.receiver_gps;
}
const std::vector<nav::ImuSample>& imu_log(const SensorLogs& l, int s) {
  return s == kTankerImu ? l.tanker_imu : l.receiver_imu;
}

struct Received {
  std::vector<nav::NavEvent> events;
  nav::NavInputStats stats;
};

struct StreamRun {
  std::array<Received, 4> streams;
  NavStreamStats stats;
  bool finished = false;
};

// Opens the four receivers on free loopback ports, streams `logs` to them (targets edited by
// `edit`), reads everything until the streamer has finished and the receivers have gone quiet.
StreamRun stream_and_receive(const SensorLogs& logs, const std::shared_ptr<SimClock>& clock,
                             const std::function<void(std::vector<NavStreamTarget>&)>& edit = {}) {
  StreamRun run;
  std::array<std::unique_ptr<nav::NavInput>, 4> inputs;
  std::array<std::uint16_t, 4> ports{};
  for (int s = 0; s < 4; ++s) {
    const bool gps = s == kTankerGps || s == kReceiverGps;
    auto in = nav::open_nav_input(gps ? "udp://127.0.0.1:0?format=nmea" : "udp://127.0.0.1:0?format=imu");
    if (!in) {
      ADD_FAILURE() << in.error().message;
      return run;
    }
    inputs[s] = std::move(*in);
    ports[s] = gps ? dynamic_cast<nav::UdpNmeaInput&>(*inputs[s]).port()
                   : dynamic_cast<nav::UdpImuInput&>(*inputs[s]).port();
  }
  std::vector<NavStreamTarget> targets =
      loopback_targets(ports[kTankerGps], ports[kTankerImu], ports[kReceiverGps], ports[kReceiverImu]);
  if (edit) edit(targets);

  // One reader per input, blocked in poll(), so each datagram is stamped as it lands.
  std::atomic<bool> done{false};
  std::vector<std::thread> readers;
  for (int s = 0; s < 4; ++s) {
    readers.emplace_back([&, s] {
      nav::NavEvent e;
      for (;;) {
        auto r = inputs[s]->read(e, 20ms);
        if (!r) {
          ADD_FAILURE() << kNames[s] << ": " << r.error().message;
          return;
        }
        if (*r == nav::NavReadStatus::kEvent) {
          run.streams[s].events.push_back(e);
        } else if (done) {
          return;
        }
      }
    });
  }
  auto streamer = NavStreamer::start(logs, targets, clock);
  if (!streamer) {
    ADD_FAILURE() << streamer.error().message;
  } else {
    const TimestampNs deadline = monotonic_now_ns() + 30'000'000'000;
    while (!(*streamer)->finished() && monotonic_now_ns() < deadline) std::this_thread::sleep_for(5ms);
    run.finished = (*streamer)->finished();
    run.stats = (*streamer)->stats();
    std::this_thread::sleep_for(150ms);  // the last datagrams land; the last NMEA epochs go quiet
  }
  done = true;
  for (std::thread& t : readers) t.join();
  for (int s = 0; s < 4; ++s) run.streams[s].stats = inputs[s]->stats();
  return run;
}

std::shared_ptr<SimClock> fast_clock(const Scenario& s, double rate = 10.0) {
  return std::make_shared<SimClock>(s.start_gps_ns, rate);
}

// The fixes the batch parser reads from the NMEA writer's text of `fixes`: what a receiver must get.
std::vector<nav::GpsFix> through_nmea(const std::vector<nav::GpsFix>& fixes) {
  std::istringstream in(nav::write_nmea(fixes));
  auto log = nav::parse_nmea(in, "sim.nmea");
  EXPECT_TRUE(log) << log.error().message;
  return log ? log->fixes : std::vector<nav::GpsFix>{};
}

void expect_gps_equal(const nav::GpsFix& live, const nav::GpsFix& sim, const nav::GpsFix& batch,
                      const std::string& what) {
  EXPECT_EQ(live.t_ns, sim.t_ns) << what;
  // The writer's precision: 8 decimals of arc minutes (3e-12 rad), 4 decimals of metres for the
  // MSL altitude and the geoid separation.
  EXPECT_NEAR(live.antenna.lat_rad, sim.antenna.lat_rad, 1e-11) << what;
  EXPECT_NEAR(live.antenna.lon_rad, sim.antenna.lon_rad, 1e-11) << what;
  EXPECT_NEAR(live.antenna.h_m, sim.antenna.h_m, 1.01e-4) << what;
  EXPECT_EQ(live.quality, sim.quality) << what;
  EXPECT_EQ(live.satellites, sim.satellites) << what;
  EXPECT_EQ(live.heading_rad.has_value(), sim.heading_rad.has_value()) << what;
  // And exactly what the batch parser reads from the writer's text.
  test::expect_same_fix(live, batch, what);
}

void expect_imu_equal(const nav::ImuSample& live, const nav::ImuSample& sim, const std::string& what) {
  EXPECT_EQ(live.t_ns, sim.t_ns) << what;
  EXPECT_EQ(live.dt_s, sim.dt_s) << what;
  EXPECT_EQ(live.dtheta_rad, sim.dtheta_rad) << what;
  EXPECT_EQ(live.dv_mps, sim.dv_mps) << what;
}

std::uint64_t datagrams_of(std::size_t samples, std::size_t per) {
  return (samples + per - 1) / per;
}

// ---- Everything arrives -------------------------------------------------------------------------

TEST(NavStream, EveryFixAndSampleOfAllFourStreamsArrivesUnchanged) {
  const SimData& sim = sim_data(3.0);
  const StreamRun run = stream_and_receive(sim.logs, fast_clock(sim.scenario));
  ASSERT_TRUE(run.finished);

  for (int s : {kTankerGps, kReceiverGps}) {
    const std::vector<nav::GpsFix>& log = gps_log(sim.logs, s);
    const std::vector<nav::GpsFix> batch = through_nmea(log);
    ASSERT_EQ(log.size(), 31u);  // 3 s at 10 Hz, both ends
    ASSERT_EQ(batch.size(), log.size());
    const Received& r = run.streams[s];
    ASSERT_EQ(r.events.size(), log.size()) << kNames[s];
    for (std::size_t i = 0; i < log.size(); ++i) {
      ASSERT_TRUE(r.events[i].is_gps());
      EXPECT_EQ(r.events[i].sensor_clock, ClockDomain::kGps);
      expect_gps_equal(r.events[i].gps(), log[i], batch[i],
                       std::string(kNames[s]) + " fix " + std::to_string(i));
    }
    EXPECT_EQ(r.stats.datagrams, log.size()) << kNames[s];  // one datagram per epoch
    EXPECT_EQ(r.stats.malformed, 0u) << kNames[s];
    EXPECT_EQ(r.stats.dropped, 0u) << kNames[s];
    EXPECT_EQ(r.stats.oversized, 0u) << kNames[s];
  }
  EXPECT_TRUE(run.streams[kTankerGps].events.front().gps().heading_rad);  // the tanker's HDT came through

  for (int s : {kTankerImu, kReceiverImu}) {
    const std::vector<nav::ImuSample>& log = imu_log(sim.logs, s);
    ASSERT_EQ(log.size(), 600u);  // 3 s at 200 Hz
    const Received& r = run.streams[s];
    ASSERT_EQ(r.events.size(), log.size()) << kNames[s];
    for (std::size_t i = 0; i < log.size(); ++i) {
      ASSERT_TRUE(r.events[i].is_imu());
      EXPECT_EQ(r.events[i].sensor_clock, ClockDomain::kGps);
      expect_imu_equal(r.events[i].imu(), log[i], std::string(kNames[s]) + " sample " + std::to_string(i));
    }
    EXPECT_EQ(r.stats.datagrams, datagrams_of(log.size(), 4)) << kNames[s];
    EXPECT_EQ(r.stats.malformed, 0u) << kNames[s];
    EXPECT_EQ(r.stats.dropped, 0u) << kNames[s];
    EXPECT_EQ(r.stats.sequence_gaps, 0u) << kNames[s];
    EXPECT_EQ(r.stats.restarts, 0u) << kNames[s];
  }

  EXPECT_EQ(run.stats.gps_datagrams, sim.logs.tanker_gps.size() + sim.logs.receiver_gps.size());
  EXPECT_EQ(run.stats.imu_samples, sim.logs.tanker_imu.size() + sim.logs.receiver_imu.size());
  EXPECT_EQ(run.stats.imu_datagrams,
            datagrams_of(sim.logs.tanker_imu.size(), 4) + datagrams_of(sim.logs.receiver_imu.size(), 4));
  EXPECT_EQ(run.stats.muted, 0u);
  EXPECT_EQ(run.stats.send_errors, 0u) << run.stats.last_error;
}

// ---- Pacing -------------------------------------------------------------------------------------

// Every datagram lands at or after the host time the shared clock gives its (last) sample's arrival,
// and typically soon after it. The upper bound is loose: a loaded two-core machine may be slow.
TEST(NavStream, DatagramsArriveWhenTheSharedClockSaysTheyAreDue) {
  const SimData& sim = sim_data(3.0);
  const auto clock = fast_clock(sim.scenario);
  const StreamRun run = stream_and_receive(sim.logs, clock);
  ASSERT_TRUE(run.finished);

  std::vector<TimestampNs> lateness;
  for (int s = 0; s < 4; ++s) {
    const Received& r = run.streams[s];
    for (std::size_t i = 0; i < r.events.size(); ++i) {
      const nav::NavEvent& e = r.events[i];
      TimestampNs sim_arrival = 0;
      if (e.is_gps()) {
        ASSERT_EQ(r.events.size(), gps_log(sim.logs, s).size());
        sim_arrival = gps_log(sim.logs, s)[i].arrival_ns;
      } else {
        // The datagram of sample i is sent when its last sample (4 to a datagram) is due.
        const std::vector<nav::ImuSample>& log = imu_log(sim.logs, s);
        ASSERT_EQ(r.events.size(), log.size());
        const std::size_t last = std::min(i / 4 * 4 + 3, log.size() - 1);
        sim_arrival = log[last].arrival_ns;
        EXPECT_GE(e.arrival_ns(), clock->host_ns(log[i].arrival_ns)) << kNames[s] << " " << i;
      }
      ASSERT_GT(sim_arrival, e.t_ns() - 1) << "the sim's arrival is GPS time, not before the sample";
      const TimestampNs late = e.arrival_ns() - clock->host_ns(sim_arrival);
      EXPECT_GE(late, 0) << kNames[s] << " " << i << " arrived before it was due";
      lateness.push_back(late);
    }
  }
  ASSERT_FALSE(lateness.empty());
  std::sort(lateness.begin(), lateness.end());
  const TimestampNs p50 = lateness[lateness.size() / 2];
  EXPECT_LT(p50, 200'000'000) << "median lateness " << p50 / 1e6 << " ms";
  // The whole flight took about its duration / rate on the host.
  const TimestampNs span = run.streams[kTankerImu].events.back().arrival_ns() -
                           run.streams[kTankerImu].events.front().arrival_ns();
  EXPECT_GT(span, static_cast<TimestampNs>(0.9 * 3e9 / 10));
}

// ---- Faults -------------------------------------------------------------------------------------

TEST(NavStream, AMuteWindowSilencesOnlyItsStreamAndShowsAsAnImuSequenceGap) {
  const SimData& sim = sim_data(3.0);
  const TimestampNs t0 = sim.scenario.start_gps_ns;
  const StreamRun run =
      stream_and_receive(sim.logs, fast_clock(sim.scenario), [](std::vector<NavStreamTarget>& t) {
        t[kTankerImu].mute_s = {{1.0, 1.5}};
        t[kReceiverGps].mute_s = {{0.5, 1.25}, {2.0, 2.0}};
      });
  ASSERT_TRUE(run.finished);
  const auto in = [&](TimestampNs t, double a, double b) {
    return t >= t0 + s_to_ns(a) && t <= t0 + s_to_ns(b);
  };

  // tanker.imu: the samples outside [1, 1.5] s, unchanged; the gap counted as lost.
  std::vector<nav::ImuSample> kept;
  std::size_t muted_imu = 0;
  for (const nav::ImuSample& s : sim.logs.tanker_imu) {
    if (in(s.t_ns, 1.0, 1.5)) {
      ++muted_imu;
    } else {
      kept.push_back(s);
    }
  }
  EXPECT_EQ(muted_imu, 101u);  // 1.000 .. 1.500 s at 5 ms, both ends
  const Received& ti = run.streams[kTankerImu];
  ASSERT_EQ(ti.events.size(), kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) {
    EXPECT_FALSE(in(ti.events[i].t_ns(), 1.0, 1.5));
    expect_imu_equal(ti.events[i].imu(), kept[i], "tanker.imu kept sample " + std::to_string(i));
  }
  EXPECT_EQ(ti.stats.sequence_gaps, muted_imu);
  EXPECT_EQ(ti.stats.dropped, muted_imu);
  EXPECT_EQ(ti.stats.malformed, 0u);
  EXPECT_EQ(ti.stats.restarts, 0u);

  // receiver.gps: no fix inside either window, every other one.
  std::vector<nav::GpsFix> kept_fixes;
  for (const nav::GpsFix& f : sim.logs.receiver_gps) {
    if (!in(f.t_ns, 0.5, 1.25) && !in(f.t_ns, 2.0, 2.0)) kept_fixes.push_back(f);
  }
  const std::size_t muted_gps = sim.logs.receiver_gps.size() - kept_fixes.size();
  EXPECT_EQ(muted_gps, 8u + 1u);  // 0.5 .. 1.2 s, and 2.0 s
  const Received& rg = run.streams[kReceiverGps];
  ASSERT_EQ(rg.events.size(), kept_fixes.size());
  for (std::size_t i = 0; i < kept_fixes.size(); ++i) EXPECT_EQ(rg.events[i].t_ns(), kept_fixes[i].t_ns);
  EXPECT_EQ(rg.stats.malformed, 0u);

  // The others are unaffected.
  EXPECT_EQ(run.streams[kTankerGps].events.size(), sim.logs.tanker_gps.size());
  EXPECT_EQ(run.streams[kReceiverImu].events.size(), sim.logs.receiver_imu.size());
  EXPECT_EQ(run.streams[kReceiverImu].stats.dropped, 0u);
  EXPECT_EQ(run.streams[kTankerGps].stats.dropped, 0u);

  EXPECT_EQ(run.stats.muted, muted_imu + muted_gps);
  EXPECT_EQ(run.stats.imu_samples, sim.logs.tanker_imu.size() + sim.logs.receiver_imu.size() - muted_imu);
  EXPECT_EQ(run.stats.gps_datagrams, sim.logs.tanker_gps.size() + kept_fixes.size());
  EXPECT_EQ(run.stats.send_errors, 0u) << run.stats.last_error;
}

// With nobody listening the stream goes on (as a sensor's would), counting what it could not send.
TEST(NavStream, SendErrorsAreCountedAndTheStreamGoesOn) {
  const SimData& sim = sim_data(3.0);
  std::uint16_t closed_port = 0;
  {
    auto r = nav::UdpReceiver::bind("127.0.0.1", 0);
    ASSERT_TRUE(r) << r.error().message;
    closed_port = r->port();
  }  // closed: sends to it are refused
  std::vector<NavStreamTarget> targets = loopback_targets(closed_port, closed_port, closed_port, closed_port);
  targets.resize(1);
  auto streamer = NavStreamer::start(sim.logs, targets, std::make_shared<SimClock>(0, 0.0));  // unpaced
  ASSERT_TRUE(streamer) << streamer.error().message;
  const TimestampNs deadline = monotonic_now_ns() + 10'000'000'000;
  while (!(*streamer)->finished() && monotonic_now_ns() < deadline) std::this_thread::sleep_for(5ms);
  ASSERT_TRUE((*streamer)->finished());
  const NavStreamStats st = (*streamer)->stats();
  EXPECT_GT(st.send_errors, 0u);
  EXPECT_EQ(st.gps_datagrams + st.send_errors, sim.logs.tanker_gps.size());
  EXPECT_TRUE(contains(st.last_error, "tanker.gps -> 127.0.0.1:" + std::to_string(closed_port)))
      << st.last_error;
}

// ---- Stopping -----------------------------------------------------------------------------------

TEST(NavStream, StopMidStreamReturnsPromptlyAndDestructionJoins) {
  const SimData& sim = sim_data(28.0);  // the whole demo, in real time: far longer than the test
  std::vector<std::unique_ptr<nav::NavInput>> inputs;
  std::vector<std::uint16_t> ports;
  for (const char* format : {"nmea", "imu", "nmea", "imu"}) {
    auto in = nav::open_nav_input(std::string("udp://127.0.0.1:0?format=") + format);
    ASSERT_TRUE(in) << in.error().message;
    ports.push_back(std::string(format) == "nmea" ? dynamic_cast<nav::UdpNmeaInput&>(**in).port()
                                                  : dynamic_cast<nav::UdpImuInput&>(**in).port());
    inputs.push_back(std::move(*in));
  }
  const auto targets = loopback_targets(ports[0], ports[1], ports[2], ports[3]);

  auto streamer = NavStreamer::start(sim.logs, targets, fast_clock(sim.scenario, 1.0));
  ASSERT_TRUE(streamer) << streamer.error().message;
  std::this_thread::sleep_for(300ms);
  const NavStreamStats before = (*streamer)->stats();
  EXPECT_GT(before.imu_datagrams, 0u);  // it was streaming
  TimestampNs t = monotonic_now_ns();
  (*streamer)->stop();
  EXPECT_LT(monotonic_now_ns() - t, 1'000'000'000);
  EXPECT_FALSE((*streamer)->finished());
  const NavStreamStats after = (*streamer)->stats();
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ((*streamer)->stats().imu_datagrams, after.imu_datagrams);  // nothing more sent
  EXPECT_LT(after.imu_samples, sim.logs.tanker_imu.size());
  (*streamer)->stop();  // again: harmless
  t = monotonic_now_ns();
  streamer->reset();
  EXPECT_LT(monotonic_now_ns() - t, 1'000'000'000);

  // Destroyed while streaming, without stop(): the destructor stops and joins.
  auto again = NavStreamer::start(sim.logs, targets, fast_clock(sim.scenario, 1.0));
  ASSERT_TRUE(again) << again.error().message;
  std::this_thread::sleep_for(100ms);
  t = monotonic_now_ns();
  again->reset();
  EXPECT_LT(monotonic_now_ns() - t, 1'000'000'000);
}

// ---- Errors -------------------------------------------------------------------------------------

TEST(NavStream, BadTargetsAreErrorsNamingTheTarget) {
  const SimData& sim = sim_data(1.0);
  const auto clock = fast_clock(sim.scenario);
  struct Case {
    std::function<void(std::vector<NavStreamTarget>&)> edit;
    std::string part;
  };
  const std::vector<Case> cases = {
      {[](auto& t) { t[1].destination = "127.0.0.1"; },
       "target 'tanker.imu': destination: expected HOST:PORT"},
      {[](auto& t) { t[2].destination = "127.0.0.1:99999"; },
       "target 'receiver.gps': destination: expected HOST:PORT"},
      {[](auto& t) { t[3].destination = ""; }, "target 'receiver.imu': destination: expected HOST:PORT"},
      {[](auto& t) { t[0].destination = "127.0.0.1:0"; },
       "target 'tanker.gps': nav::UdpSender::open(): 127.0.0.1:0: expected a destination port 1..65535"},
      {[](auto& t) { t[0].destination = "[::1:5000"; },
       "target 'tanker.gps': destination: expected HOST:PORT"},
      {[](auto& t) { t[2].stream = "receiver.radar"; },
       "target 'receiver.radar': unknown stream (expected tanker.gps, tanker.imu, receiver.gps or "
       "receiver.imu)"},
      {[](auto& t) { t[0].stream = "tanker.imu"; },
       "target 'tanker.imu': kind GPS does not match the stream's kind IMU"},
      {[](auto& t) {
         t[1].mute_s = {{2.0, 1.0}};
       },
       "target 'tanker.imu': mute window [2, 1] s: expected finite scenario times t0 <= t1"},
      {[](auto& t) {
         t[3].mute_s = {{0.0, NAN}};
       },
       "target 'receiver.imu': mute window [0, nan] s"},
  };
  for (const Case& c : cases) {
    std::vector<NavStreamTarget> targets = loopback_targets(5000, 5001, 5002, 5003);
    c.edit(targets);
    auto s = NavStreamer::start(sim.logs, targets, clock);
    ASSERT_FALSE(s) << c.part;
    EXPECT_TRUE(contains(s.error().message, "NavStreamer::start(): " + c.part)) << s.error().message;
  }

  // A stream whose log is empty.
  SensorLogs empty = sim.logs;
  empty.receiver_gps.clear();
  auto s = NavStreamer::start(empty, loopback_targets(5000, 5001, 5002, 5003), clock);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message,
            "NavStreamer::start(): target 'receiver.gps': the simulated log of this stream is empty");

  // Options and arguments.
  NavStreamOptions o;
  for (int n : {0, 23}) {
    o.imu_samples_per_datagram = n;
    s = NavStreamer::start(sim.logs, loopback_targets(5000, 5001, 5002, 5003), clock, o);
    ASSERT_FALSE(s);
    EXPECT_EQ(s.error().message,
              "NavStreamer::start(): imu_samples_per_datagram must be 1..22, got " + std::to_string(n));
  }
  s = NavStreamer::start(sim.logs, {}, clock);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "NavStreamer::start(): no targets given");
  s = NavStreamer::start(sim.logs, loopback_targets(5000, 5001, 5002, 5003), nullptr);
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().message, "NavStreamer::start(): no SimClock given");
}

TEST(NavStream, LoopbackTargetsAreTheFourStreamsInOrder) {
  const std::vector<NavStreamTarget> t = loopback_targets(1, 2, 3, 4);
  ASSERT_EQ(t.size(), 4u);
  for (int s = 0; s < 4; ++s) {
    EXPECT_EQ(t[s].stream, kNames[s]);
    EXPECT_EQ(t[s].kind, s % 2 == 0 ? NavStreamKind::kGps : NavStreamKind::kImu);
    EXPECT_EQ(t[s].destination, "127.0.0.1:" + std::to_string(s + 1));
    EXPECT_TRUE(t[s].mute_s.empty());
  }
}

}  // namespace
}  // namespace augrig::sim
