// ubx_input: a u-blox receiver's UBX binary output as a live nav input (nav/live_input.hpp), over
// UDP or a serial port:
//   udp://BIND_ADDR:PORT?format=ubx       UBX frames in UDP datagrams (any split: frames may span
//                                         datagrams, as a serial-to-UDP bridge sends them)
//   serial:///dev/ttyACM0?baud=RATE&format=ubx
// NAV-RELPOSNED becomes a moving-baseline event (nav::BaselineMeasurement: the rover's antenna
// relative to the moving base's, NED); NAV-PVT a GPS fix (unless fixes=0: when the same receiver's
// NMEA is read too). A time of week becomes GPS time in the week nearest the newest NAV-PVT's UTC
// date and time, or before any, the host's UTC clock (leap seconds by the table). Bytes that are no
// UBX frame, bad checksums, oversized lengths and messages that fail to decode are counted and
// named; events not newer than the previous of their kind are dropped as out of order. Every raw
// frame goes to the raw tap (binary) before it is decoded.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>

#include "nav/live_input.hpp"
#include "nav/serial_port.hpp"
#include "nav/ubx.hpp"
#include "nav/udp_socket.hpp"

namespace augrig::nav {

struct UbxInputOptions {
  bool fixes = true;  // NAV-PVT as GPS fixes
};

// The UBX side shared by the UDP and serial inputs: bytes in, events out.
class UbxEventSource {
 public:
  UbxEventSource(std::string name, const UbxInputOptions& options);
  // `tap` gets every whole frame (with its arrival) before it is decoded.
  template <typename Tap>
  void push(const std::uint8_t* data, std::size_t n, TimestampNs arrival_ns, Tap&& tap) {
    stream_.push(data, n);
    stats_.bytes += n;
    while (auto f = stream_.next()) {
      tap(*f, arrival_ns);
      take(*f, arrival_ns);
    }
    sync();
  }
  bool pop(NavEvent& out);
  NavInputStats& stats() { return stats_; }
  const NavInputStats& stats() const { return stats_; }
  // GPS time of a time of week (the week nearest the reference; see above).
  TimestampNs gps_time_of(std::uint32_t itow_ms) const;

 private:
  void take(const UbxFrame& f, TimestampNs arrival_ns);
  void sync();  // folds the stream's counters and messages into stats_
  std::string name_;
  UbxInputOptions options_;
  UbxStream stream_;
  NavInputStats stats_;
  std::deque<NavEvent> ready_;
  std::optional<TimestampNs> reference_gps_ns_;  // the newest NAV-PVT's time
  TimestampNs last_fix_ns_ = 0, last_baseline_ns_ = 0;
  std::uint64_t seen_bad_ = 0, seen_oversized_ = 0;
  std::size_t seen_messages_ = 0;
};

// udp://BIND_ADDR:PORT?format=ubx
class UdpUbxInput : public NavInput {
 public:
  static Expected<std::unique_ptr<UdpUbxInput>> open(const std::string& bind_host, std::uint16_t port,
                                                     const UdpReceiverOptions& socket, const UbxInputOptions& options,
                                                     std::string uri = {});
  std::string uri() const override { return uri_; }
  Expected<NavReadStatus> read(NavEvent& out, std::chrono::nanoseconds timeout) override;
  NavInputStats stats() const override { return source_.stats(); }
  std::uint16_t port() const { return socket_.port(); }
  std::uint16_t udp_port() const override { return port(); }

 private:
  UdpUbxInput(UdpReceiver socket, std::string uri, const UbxInputOptions& options);
  UdpReceiver socket_;
  std::string uri_;
  UbxEventSource source_;
  UdpDatagram datagram_;
};

// serial:///dev/DEVICE?baud=RATE&format=ubx
class SerialUbxInput : public NavInput {
 public:
  static Expected<std::unique_ptr<SerialUbxInput>> open(const std::string& path, int baud,
                                                        const UbxInputOptions& options, std::string uri = {});
  std::string uri() const override { return uri_; }
  Expected<NavReadStatus> read(NavEvent& out, std::chrono::nanoseconds timeout) override;
  NavInputStats stats() const override { return source_.stats(); }

 private:
  SerialUbxInput(SerialPort port, std::string uri, const UbxInputOptions& options);
  SerialPort port_;
  std::string uri_;
  UbxEventSource source_;
  bool hung_up_ = false;
};

// A NAV-PVT as a GPS fix: the antenna's position, the fix quality (RTK fixed/float from carrSoln,
// DGPS from diffSoln, single for a 3D fix, else invalid), hAcc/vAcc as the NED sigmas, ground speed
// and course from the NED velocity.
GpsFix fix_of(const UbxNavPvt& m, TimestampNs t_gps_ns);

}  // namespace augrig::nav
