#include "sim/nav_stream.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <span>

#include "core/thread_name.hpp"
#include "nav/imu_stream.hpp"
#include "nav/udp_socket.hpp"

namespace augrig::sim {

// One target as the sending thread sees it: its log (shared with other targets of the same stream,
// never rebuilt), its socket, and the next step planned, which is either one datagram's samples
// [begin, end) or one muted sample.
struct NavStreamer::Lane {
  std::string name;
  NavStreamKind kind = NavStreamKind::kGps;
  std::shared_ptr<const std::vector<nav::ImuSample>> imu;
  std::shared_ptr<const std::vector<nav::GpsFix>> gps;
  std::vector<std::pair<TimestampNs, TimestampNs>> mute_ns;  // GPS time, inclusive
  nav::UdpSender sender;

  std::size_t next = 0;  // the first sample not yet handled
  std::size_t begin = 0, end = 0;
  bool muted = false;
  TimestampNs due_ns = 0;  // GPS time at which the step happens
  bool done = false;

  explicit Lane(nav::UdpSender s) : sender(std::move(s)) {}
  std::size_t size() const { return imu ? imu->size() : gps->size(); }
  TimestampNs t_ns(std::size_t i) const { return imu ? (*imu)[i].t_ns : (*gps)[i].t_ns; }
  TimestampNs arrival_ns(std::size_t i) const {
    const TimestampNs a = imu ? (*imu)[i].arrival_ns : (*gps)[i].arrival_ns;
    return a != 0 ? a : t_ns(i);  // 0: unknown, sent at its time of validity
  }
  bool is_muted(std::size_t i) const {
    const TimestampNs t = t_ns(i);
    return std::any_of(mute_ns.begin(), mute_ns.end(),
                       [t](const auto& w) { return w.first <= t && t <= w.second; });
  }
};

namespace {

constexpr const char* kFunction = "NavStreamer::start(): ";

struct StreamInfo {
  const char* name;
  NavStreamKind kind;
};
constexpr StreamInfo kStreams[] = {{"tanker.gps", NavStreamKind::kGps},
                                   {"tanker.imu", NavStreamKind::kImu},
                                   {"receiver.gps", NavStreamKind::kGps},
                                   {"receiver.imu", NavStreamKind::kImu}};

const char* kind_name(NavStreamKind k) {
  return k == NavStreamKind::kGps ? "GPS" : "IMU";
}

std::string seconds_text(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", s);
  return buf;
}

// Scenario time 0 from the logs: simulate_sensors' IMU sample k covers (t_{k-1}, t_k] with t_0 the
// start, so the first sample's interval begins there. Without IMU samples, the first GPS epoch
// (epoch 0 is at t = 0 unless an outage hid it).
std::optional<TimestampNs> start_from_logs(const SensorLogs& logs) {
  for (const auto* imu : {&logs.tanker_imu, &logs.receiver_imu}) {
    if (!imu->empty()) return imu->front().t_ns - s_to_ns(imu->front().dt_s);
  }
  std::optional<TimestampNs> t;
  for (const auto* gps : {&logs.tanker_gps, &logs.receiver_gps}) {
    if (!gps->empty()) t = std::min(t.value_or(gps->front().t_ns), gps->front().t_ns);
  }
  return t;
}

}  // namespace

NavStreamer::NavStreamer() = default;

Expected<std::unique_ptr<NavStreamer>> NavStreamer::start(const SensorLogs& logs,
                                                          std::vector<NavStreamTarget> targets,
                                                          std::shared_ptr<SimClock> clock,
                                                          NavStreamOptions options) {
  if (!clock) return make_error(kFunction, "no SimClock given");
  if (targets.empty()) return make_error(kFunction, "no targets given");
  if (options.imu_samples_per_datagram < 1 ||
      options.imu_samples_per_datagram > static_cast<int>(nav::kImuMaxSamplesPerDatagram)) {
    return make_error(kFunction, "imu_samples_per_datagram must be 1..", nav::kImuMaxSamplesPerDatagram,
                      ", got ", options.imu_samples_per_datagram);
  }
  const std::optional<TimestampNs> start_ns =
      options.scenario_start_gps_ns ? options.scenario_start_gps_ns : start_from_logs(logs);

  std::unique_ptr<NavStreamer> s(new NavStreamer());
  // One copy of each log streamed, however many targets share it.
  std::shared_ptr<const std::vector<nav::ImuSample>> imu_copies[2];
  std::shared_ptr<const std::vector<nav::GpsFix>> gps_copies[2];
  for (const NavStreamTarget& t : targets) {
    const std::string prefix = std::string(kFunction) + "target '" + t.stream + "': ";
    const auto known = std::find_if(std::begin(kStreams), std::end(kStreams),
                                    [&](const StreamInfo& i) { return t.stream == i.name; });
    if (known == std::end(kStreams)) {
      return make_error(prefix,
                        "unknown stream (expected tanker.gps, tanker.imu, receiver.gps or receiver.imu)");
    }
    if (t.kind != known->kind) {
      return make_error(prefix, "kind ", kind_name(t.kind), " does not match the stream's kind ",
                        kind_name(known->kind));
    }
    const bool tanker = t.stream.starts_with("tanker.");
    const std::size_t samples = t.kind == NavStreamKind::kImu
                                    ? (tanker ? logs.tanker_imu : logs.receiver_imu).size()
                                    : (tanker ? logs.tanker_gps : logs.receiver_gps).size();
    if (samples == 0) return make_error(prefix, "the simulated log of this stream is empty");

    std::vector<std::pair<TimestampNs, TimestampNs>> mute_ns;
    for (const auto& [t0, t1] : t.mute_s) {
      if (!std::isfinite(t0) || !std::isfinite(t1) || t1 < t0) {
        return make_error(prefix, "mute window [", seconds_text(t0), ", ", seconds_text(t1),
                          "] s: expected finite scenario times t0 <= t1");
      }
      if (!start_ns)
        return make_error(prefix, "mute windows need scenario_start_gps_ns (no IMU or GPS log to infer it)");
      mute_ns.emplace_back(*start_ns + s_to_ns(t0), *start_ns + s_to_ns(t1));
    }

    auto hp = nav::parse_host_port(t.destination, prefix + "destination: ");
    if (!hp) return hp.error();
    auto sender = nav::UdpSender::open(hp->host, hp->port);
    if (!sender) return make_error(prefix, sender.error().message);

    Lane lane(std::move(*sender));
    lane.name = t.stream + " -> " + t.destination;
    lane.kind = t.kind;
    lane.mute_ns = std::move(mute_ns);
    const int slot = tanker ? 0 : 1;
    if (t.kind == NavStreamKind::kImu) {
      if (!imu_copies[slot]) {
        imu_copies[slot] =
            std::make_shared<const std::vector<nav::ImuSample>>(tanker ? logs.tanker_imu : logs.receiver_imu);
      }
      lane.imu = imu_copies[slot];
    } else {
      if (!gps_copies[slot]) {
        gps_copies[slot] =
            std::make_shared<const std::vector<nav::GpsFix>>(tanker ? logs.tanker_gps : logs.receiver_gps);
      }
      lane.gps = gps_copies[slot];
    }
    s->lanes_.push_back(std::move(lane));
  }
  s->clock_ = std::move(clock);
  s->options_ = std::move(options);
  for (Lane& lane : s->lanes_) s->plan(lane);
  s->thread_ = std::thread([p = s.get()] {
    set_thread_name("augrig-simnav");
    p->run();
  });
  return s;
}

NavStreamer::~NavStreamer() {
  stop();
}

void NavStreamer::stop() {
  stop_ = true;
  std::lock_guard lock(join_mutex_);
  if (thread_.joinable()) thread_.join();
}

NavStreamStats NavStreamer::stats() const {
  std::lock_guard lock(stats_mutex_);
  return stats_;
}

// The lane's next step from lane.next: a muted sample alone (so it is counted when it would have
// been sent), or up to imu_samples_per_datagram consecutive unmuted IMU samples (a datagram cannot
// span a gap in the sequence numbers), or one GPS epoch.
void NavStreamer::plan(Lane& lane) const {
  const std::size_t n = lane.size();
  if (lane.next >= n) {
    lane.done = true;
    return;
  }
  lane.begin = lane.next;
  lane.muted = lane.is_muted(lane.begin);
  lane.end = lane.begin + 1;
  if (!lane.muted && lane.kind == NavStreamKind::kImu) {
    const std::size_t limit =
        std::min(n, lane.begin + static_cast<std::size_t>(options_.imu_samples_per_datagram));
    while (lane.end < limit && !lane.is_muted(lane.end)) ++lane.end;
  }
  lane.due_ns = lane.arrival_ns(lane.end - 1);
}

void NavStreamer::step(Lane& lane) {
  if (lane.muted) {
    std::lock_guard lock(stats_mutex_);
    stats_.muted += lane.end - lane.begin;
    return;
  }
  Status sent;
  if (lane.kind == NavStreamKind::kImu) {
    const std::span<const nav::ImuSample> samples(lane.imu->data() + lane.begin, lane.end - lane.begin);
    // Sequence numbers are log indices: muted samples keep their numbers and show as a gap.
    auto bytes = nav::encode_imu_datagram(samples, lane.begin, ClockDomain::kGps);
    sent = bytes ? lane.sender.send(*bytes) : Status(bytes.error());
  } else {
    std::string text;
    for (const std::string& sentence : nav::nmea_sentences((*lane.gps)[lane.begin], options_.nmea)) {
      text += sentence;
      text += options_.nmea.line_ending;
    }
    sent = lane.sender.send(text);
  }
  std::lock_guard lock(stats_mutex_);
  if (!sent) {
    ++stats_.send_errors;
    stats_.last_error = "NavStreamer: " + lane.name + ": " + sent.error().message;
  } else if (lane.kind == NavStreamKind::kImu) {
    ++stats_.imu_datagrams;
    stats_.imu_samples += lane.end - lane.begin;
  } else {
    ++stats_.gps_datagrams;
  }
}

void NavStreamer::run() {
  while (!stop_) {
    // The earliest step of all lanes; ties go to the first target.
    Lane* next = nullptr;
    for (Lane& lane : lanes_) {
      if (!lane.done && (!next || lane.due_ns < next->due_ns)) next = &lane;
    }
    if (!next) {
      finished_ = true;
      return;
    }
    if (!clock_->wait_until(next->due_ns, &stop_)) return;
    step(*next);
    next->next = next->end;
    plan(*next);
  }
}

std::vector<NavStreamTarget> loopback_targets(std::uint16_t tanker_gps, std::uint16_t tanker_imu,
                                              std::uint16_t receiver_gps, std::uint16_t receiver_imu) {
  const auto at = [](std::uint16_t port) { return "127.0.0.1:" + std::to_string(port); };
  return {{"tanker.gps", NavStreamKind::kGps, at(tanker_gps), {}},
          {"tanker.imu", NavStreamKind::kImu, at(tanker_imu), {}},
          {"receiver.gps", NavStreamKind::kGps, at(receiver_gps), {}},
          {"receiver.imu", NavStreamKind::kImu, at(receiver_imu), {}}};
}

}  // namespace augrig::sim
