// live_input: the live navigation inputs of a flight test, behind one interface. Each NavInput
// delivers IMU samples or GPS fixes as they arrive, each with its sensor time (t_ns, in the clock
// domain the event names) and the host CLOCK_MONOTONIC time it arrived (arrival_ns,
// ClockDomain::kHostMonotonic), and counts what it received, what was malformed or oversized and
// what was lost. docs/NAV_LIVE.md describes the URIs, the formats and the counters.
//
//   udp://BIND_ADDR:PORT?format=nmea   NMEA 0183 sentences in UDP datagrams (one or more lines each)
//   udp://BIND_ADDR:PORT?format=imu    IMU increments in the binary datagrams of nav/imu_stream.hpp
//   serial:///dev/ttyUSB0?baud=115200  NMEA 0183 on a serial port (raw 8N1; a pty works too)
//   udp://BIND_ADDR:PORT?format=ubx    u-blox UBX (NAV-PVT fixes, NAV-RELPOSNED baselines; nav/ubx_input.hpp)
//   serial:///dev/ttyACM0?baud=115200&format=ubx   the same on a serial port
//   gpsd://HOST[:PORT][?device=PATH]   a gpsd daemon's fixes through libgps (nav/gpsd_input.hpp)
//
// Inputs never throw and never hang: read() waits at most its timeout. Bad input (malformed or
// oversized datagrams, bad sentences, bad reports) is counted, named in last_errors and dropped;
// only what makes the input unusable (a socket error, a bad URI) is an Error.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "core/clock.hpp"
#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/baseline_fusion.hpp"
#include "nav/nmea.hpp"
#include "nav/types.hpp"
#include "nav/udp_socket.hpp"

namespace augrig::nav {

// monotonic_now_ns() (core/clock.hpp) is the arrival clock of every live input.
using augrig::monotonic_now_ns;

// One sample from a live input.
struct NavEvent {
  // An IMU sample, a GPS fix, or a moving-baseline vector (a UBX rover's NAV-RELPOSNED).
  std::variant<ImuSample, GpsFix, BaselineMeasurement> sample;
  // The clock domain of the sample's t_ns: kGps for fixes; for IMU samples what their datagram says.
  // arrival_ns is always ClockDomain::kHostMonotonic.
  ClockDomain sensor_clock = ClockDomain::kGps;
  // GPS only, when the source reports it (gpsd's velN/velE/velD): the antenna's velocity, NED, m/s.
  // GpsFix carries only the horizontal ground speed and course.
  std::optional<Eigen::Vector3d> velocity_ned_mps;

  bool is_imu() const { return sample.index() == 0; }
  bool is_gps() const { return sample.index() == 1; }
  bool is_baseline() const { return sample.index() == 2; }
  const ImuSample& imu() const { return std::get<ImuSample>(sample); }
  const GpsFix& gps() const { return std::get<GpsFix>(sample); }
  const BaselineMeasurement& baseline() const { return std::get<BaselineMeasurement>(sample); }
  TimestampNs t_ns() const {
    return std::visit([](const auto& s) { return s.t_ns; }, sample);
  }
  TimestampNs arrival_ns() const {
    return std::visit([](const auto& s) { return s.arrival_ns; }, sample);
  }
};

enum class NavReadStatus : std::uint8_t {
  kEvent,    // `out` holds the next event
  kTimeout,  // nothing within the timeout (try again)
  kEnd,      // the source is gone for good (gpsd closed the connection, the serial port hung up)
};

// What an input received and what it could not deliver. Counters only grow.
struct NavInputStats {
  static constexpr std::size_t kMaxErrors = 8;

  std::uint64_t datagrams = 0;  // UDP datagrams received, good or bad
  std::uint64_t lines = 0;      // NMEA lines (UDP, serial) or gpsd JSON reports received
  std::uint64_t bytes = 0;      // bytes received (datagram payloads, serial bytes)
  std::uint64_t events = 0;     // samples and fixes delivered by read()
  // Dropped as unusable: IMU datagrams with a bad magic/version/type/length/CRC/value, NMEA lines
  // that fail to parse or their checksum, gpsd reports that cannot be used.
  std::uint64_t malformed = 0;
  // Dropped unread: datagrams longer than the input's max_datagram, serial lines longer than max_line.
  std::uint64_t oversized = 0;
  // Samples or fixes known to be lost or refused: IMU sequence gaps; samples and fixes not newer
  // than their predecessor (late, duplicated); NMEA fixes before any date. The next two are
  // the parts of it with their own counters.
  std::uint64_t dropped = 0;
  std::uint64_t sequence_gaps = 0;  // IMU samples missing from the sequence numbers
  std::uint64_t out_of_order = 0;   // samples or fixes not newer than their predecessor
  // Datagrams the kernel dropped for a full receive buffer (SO_RXQ_OVFL; not in `dropped`: for
  // IMU datagrams the lost samples show up as sequence gaps).
  std::uint64_t socket_overflows = 0;
  std::uint64_t restarts = 0;            // IMU senders that started a new sequence (a jump back)
  std::vector<std::string> last_errors;  // the last kMaxErrors messages, oldest first

  // Appends a message, keeping the last kMaxErrors.
  void note(std::string message);
};

class NavInput {
 public:
  virtual ~NavInput() = default;
  // The URI the input was opened with.
  virtual std::string uri() const = 0;
  // Waits at most `timeout` (0: only what has already arrived) for the next event.
  virtual Expected<NavReadStatus> read(NavEvent& out, std::chrono::nanoseconds timeout) = 0;
  virtual NavInputStats stats() const = 0;
  // A UDP input's bound port (useful after port 0); 0 for other inputs.
  virtual std::uint16_t udp_port() const { return 0; }

  // Called with every unit of input exactly as received, before it is parsed: an NMEA line (no
  // line ending), an IMU datagram, a gpsd JSON report; with its arrival time and whether it is
  // binary. For recording the inputs as received. Set it before the first read(); it runs on the
  // thread that calls read().
  using RawTap = std::function<void(std::string_view data, TimestampNs arrival_ns, bool binary)>;
  void set_raw_tap(RawTap tap) { raw_tap_ = std::move(tap); }

 protected:
  void tap(std::string_view data, TimestampNs arrival_ns, bool binary) const {
    if (raw_tap_) raw_tap_(data, arrival_ns, binary);
  }

 private:
  RawTap raw_tap_;
};

// Opens an input from its URI (the forms above; the options of each in docs/NAV_LIVE.md).
// A bad URI gives an Error naming it and what was expected.
Expected<std::unique_ptr<NavInput>> open_nav_input(std::string_view uri);

// ---- Building blocks shared by the inputs -------------------------------------------------------

// A URI split into its parts: "udp://127.0.0.1:5000?format=nmea" -> scheme "udp", host
// "127.0.0.1", port 5000, options {format: nmea}; "serial:///dev/ttyS0?baud=9600" -> path
// "/dev/ttyS0"; "[::1]:5000" -> host "::1".
struct NavUri {
  std::string text;  // as given
  std::string scheme;
  std::string host;
  std::optional<std::uint16_t> port;
  std::string path;
  std::vector<std::pair<std::string, std::string>> options;  // in order, keys unique
};
Expected<NavUri> parse_nav_uri(std::string_view uri);

// Typed access to a NavUri's options. Each getter consumes its key; finish() then names any key
// left over (unknown to the scheme) with the keys it knows. Errors name the URI.
class NavUriOptions {
 public:
  NavUriOptions(const NavUri& uri, std::string function);
  Expected<std::optional<std::string>> text(const std::string& key);
  // An integer in [min, max]; `what` says what is expected ("a port number").
  Expected<std::optional<std::int64_t>> integer(const std::string& key, std::int64_t min, std::int64_t max,
                                                const std::string& what);
  // "YYYY-MM-DD".
  Expected<std::optional<CivilDate>> date(const std::string& key);
  Status finish() const;
  // "<function>: <uri>: " for messages.
  std::string prefix() const;

 private:
  const NavUri& uri_;
  std::string function_;
  std::vector<std::string> known_;
  std::vector<bool> used_;
};

// The NMEA side shared by the UDP and serial inputs: lines in (with their arrival time), fixes
// out as NavEvents, the stream's counters and messages folded into NavInputStats. An epoch is closed
// by the next time tag or after `quiet_ns` without a line.
class NmeaEventSource {
 public:
  NmeaEventSource(const std::string& name, const NmeaOptions& options, TimestampNs quiet_ns);
  void push_line(std::string_view line, TimestampNs arrival_ns);
  // Closes an open epoch once the sender has been quiet for quiet_ns (now_ns: monotonic_now_ns()).
  void poll_quiet(TimestampNs now_ns);
  // The time at which poll_quiet would close the open epoch; nullopt when none is open.
  std::optional<TimestampNs> quiet_deadline_ns() const;
  // The next fix as an event, counted in stats().events.
  bool pop(NavEvent& out);
  // End of stream: closes the open epoch.
  void flush();
  NavInputStats& stats() { return stats_; }
  const NavInputStats& stats() const { return stats_; }

 private:
  void sync();  // folds the stream's counter changes and messages into stats_

  NmeaStream stream_;
  TimestampNs quiet_ns_;
  NavInputStats stats_;
  std::size_t seen_malformed_ = 0, seen_dropped_ = 0, seen_out_of_order_ = 0;
};

// NMEA over UDP: datagrams of one or more lines; a datagram's end also ends its last line.
struct UdpNmeaOptions {
  std::size_t max_datagram_bytes = 1472;  // larger datagrams are counted as oversized and dropped
  int receive_buffer_bytes = 1 << 20;     // SO_RCVBUF asked for (the kernel may cap it)
  TimestampNs quiet_ns = 20'000'000;      // an epoch closes after this long without a line
  NmeaOptions nmea;
};
// udp://BIND_ADDR:PORT?format=nmea
class UdpNmeaInput : public NavInput {
 public:
  static Expected<std::unique_ptr<UdpNmeaInput>> open(const std::string& bind_host, std::uint16_t port,
                                                      const UdpNmeaOptions& options = {},
                                                      std::string uri = {});
  std::string uri() const override { return uri_; }
  Expected<NavReadStatus> read(NavEvent& out, std::chrono::nanoseconds timeout) override;
  NavInputStats stats() const override { return source_.stats(); }
  std::uint16_t port() const { return socket_.port(); }
  std::uint16_t udp_port() const override { return port(); }
  const UdpReceiver& socket() const { return socket_; }

 private:
  UdpNmeaInput(UdpReceiver socket, std::string uri, const UdpNmeaOptions& options);
  UdpReceiver socket_;
  std::string uri_;
  NmeaEventSource source_;
  UdpDatagram datagram_;
};

// What a UDP input says of a datagram it read: the kernel's drops before it (socket_overflows,
// noted) and, when it was oversized, that it was dropped (oversized, noted with its number, so the
// input counts `datagrams` first). False: oversized. Datagram and byte counts stay with the input.
bool udp_datagram_usable(NavInputStats& stats, const UdpDatagram& datagram, const std::string& uri,
                         std::size_t max_datagram_bytes);

// The options shared by the NMEA inputs' URIs: quiet_ms, leap_seconds, date.
Status read_nmea_uri_options(NavUriOptions& o, TimestampNs& quiet_ns, NmeaOptions& nmea);

}  // namespace augrig::nav
