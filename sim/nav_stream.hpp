// nav_stream: a simulated flight's GPS and IMU logs played as live nav inputs over real UDP, so that
// a simulated run (`augrig run --source sim://demo --nav sim`) receives them through exactly the
// path of a flight (nav/live_input.hpp: udp://ADDR:PORT?format=nmea and ?format=imu).
//
//   GPS: one datagram per epoch holding all its NMEA sentences (nav::nmea_sentences), each ended
//        by the writer's line ending, sent when the fix's arrival time is due.
//   IMU: binary datagrams of nav/imu_stream.hpp, up to imu_samples_per_datagram consecutive samples
//        each, ClockDomain::kGps, sequence numbers counting the log's samples from 0; a datagram is
//        sent when its last sample's arrival time is due.
//
// Time: the samples' arrival_ns is GPS time (t_ns + the sensor's latency, sim/sensors.hpp); one
// sending thread merges all targets in arrival order and sends each datagram when the run's SimClock
// (sim/sim_clock.hpp, shared with the rendered cameras) says that arrival has come on the host.
//
// Faults: a target's mute windows (scenario time, inclusive) drop the samples whose t_ns falls in
// them, as a pulled cable would. Sequence numbers keep counting through them, so an IMU receiver
// sees the loss as a sequence gap; a GPS receiver simply gets no fixes.
//
// A failed send (nobody listening yet: ECONNREFUSED) does not stop the stream, as it would not stop
// a real sensor: it is counted in NavStreamStats and the stream goes on.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/nmea.hpp"
#include "sim/sensors.hpp"
#include "sim/sim_clock.hpp"

namespace augrig::sim {

enum class NavStreamKind { kGps, kImu };

struct NavStreamTarget {
  std::string stream;       // "tanker.gps", "tanker.imu", "receiver.gps", "receiver.imu"
  NavStreamKind kind;       // must match the stream's
  std::string destination;  // "127.0.0.1:PORT"
  // Scenario-time windows [t0_s, t1_s] during which nothing is sent (a fault injected: a cable
  // pulled, a receiver muted): samples with t0 <= t <= t1 are dropped.
  std::vector<std::pair<double, double>> mute_s;
};

struct NavStreamOptions {
  // 1..nav::kImuMaxSamplesPerDatagram; an IMU datagram is sent when its last sample's arrival time is due.
  int imu_samples_per_datagram = 4;
  nav::NmeaWriterOptions nmea;  // one datagram per GPS epoch holding all its sentences
  // GPS time of scenario time 0 (Scenario::start_gps_ns), for the mute windows. When unset it is
  // taken from the logs: the start of the first IMU sample's interval (sample 1 covers (0, t_1]).
  std::optional<TimestampNs> scenario_start_gps_ns;
};

struct NavStreamStats {
  std::uint64_t gps_datagrams = 0, imu_datagrams = 0, imu_samples = 0;  // sent
  std::uint64_t muted = 0;        // samples and fixes not sent for a mute window
  std::uint64_t send_errors = 0;  // datagrams that could not be sent (or encoded)
  std::string last_error;         // the last of those, naming the target
};

class NavStreamer {
 public:
  // Starts one sending thread that merges all targets' samples in arrival order and sends each when
  // clock->host_ns(arrival_ns) is due (sample arrival_ns is in GPS time here: t_ns + latency).
  // Errors (bad destination, unknown stream name, empty logs, a kind that does not match the stream,
  // bad mute windows, bad options) name the target.
  static Expected<std::unique_ptr<NavStreamer>> start(const SensorLogs& logs,
                                                      std::vector<NavStreamTarget> targets,
                                                      std::shared_ptr<SimClock> clock,
                                                      NavStreamOptions options = {});
  ~NavStreamer();  // stops and joins
  NavStreamer(const NavStreamer&) = delete;
  NavStreamer& operator=(const NavStreamer&) = delete;

  // Stops sending (within the clock's 50 ms wait slice) and joins the thread; idempotent.
  void stop();
  bool finished() const { return finished_; }  // every sample sent (or muted, or failed)
  NavStreamStats stats() const;

 private:
  struct Lane;
  NavStreamer();
  void run();
  void plan(Lane& lane) const;
  void step(Lane& lane);

  std::vector<Lane> lanes_;
  std::shared_ptr<SimClock> clock_;
  NavStreamOptions options_;
  std::atomic<bool> stop_{false}, finished_{false};
  mutable std::mutex stats_mutex_;
  NavStreamStats stats_;
  std::mutex join_mutex_;
  std::thread thread_;
};

// The four standard targets on loopback with the given ports, in the order tanker.gps, tanker.imu,
// receiver.gps, receiver.imu.
std::vector<NavStreamTarget> loopback_targets(std::uint16_t tanker_gps, std::uint16_t tanker_imu,
                                              std::uint16_t receiver_gps, std::uint16_t receiver_imu);

}  // namespace augrig::sim
