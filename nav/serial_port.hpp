// serial_port: NMEA 0183 from a GPS receiver on a serial port (serial:///dev/ttyUSB0?baud=115200).
// SerialPort opens the device raw, 8 data bits, no parity, 1 stop bit, no flow control, at the
// given baud, non-blocking, and waits with poll(); a pty works the same (the baud is then only
// recorded). SerialNmeaInput splits its bytes into lines and reads them with NmeaStream: each
// line's arrival time is when the read() that brought its first byte returned (CLOCK_MONOTONIC).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/live_input.hpp"
#include "nav/nmea.hpp"

namespace augrig::nav {

// The baud rates a port can be set to: 1200 ... 4000000 (the POSIX/Linux termios rates).
// Parses "115200"; the Error lists the accepted rates.
Expected<int> parse_baud(std::string_view text);

class SerialPort {
 public:
  static Expected<SerialPort> open(const std::string& path, int baud);
  SerialPort(SerialPort&& o) noexcept;
  SerialPort& operator=(SerialPort&& o) noexcept;
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;
  ~SerialPort();

  struct ReadResult {
    std::size_t bytes = 0;       // 0: nothing within the timeout (or hung up)
    bool hung_up = false;        // the device went away (unplugged, the pty's other side closed)
    TimestampNs arrival_ns = 0;  // CLOCK_MONOTONIC right after the read
  };
  // Waits at most `timeout` for bytes and reads what is there (at most buffer.size()).
  Expected<ReadResult> read(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout);

  const std::string& path() const { return path_; }
  int baud() const { return baud_; }
  int fd() const { return fd_; }

 private:
  SerialPort() = default;
  int fd_ = -1;
  std::string path_;
  int baud_ = 0;
};

struct SerialNmeaOptions {
  int baud = 4800;
  std::size_t max_line_bytes = 1024;  // longer lines are counted as oversized and dropped
  TimestampNs quiet_ns = 20'000'000;  // an epoch closes after this long without a line
  NmeaOptions nmea;
};

class SerialNmeaInput : public NavInput {
 public:
  static Expected<std::unique_ptr<SerialNmeaInput>> open(const std::string& path,
                                                         const SerialNmeaOptions& options,
                                                         std::string uri = {});
  std::string uri() const override { return uri_; }
  Expected<NavReadStatus> read(NavEvent& out, std::chrono::nanoseconds timeout) override;
  NavInputStats stats() const override { return source_.stats(); }
  const SerialPort& port() const { return port_; }

 private:
  SerialNmeaInput(SerialPort port, std::string uri, const SerialNmeaOptions& options);
  void take_bytes(std::span<const std::uint8_t> bytes, TimestampNs arrival_ns);

  SerialPort port_;
  std::string uri_;
  SerialNmeaOptions options_;
  NmeaEventSource source_;
  std::string line_;                 // the line being assembled
  TimestampNs line_arrival_ns_ = 0;  // arrival of its first byte
  bool discarding_ = false;          // inside an oversized line: drop bytes up to the next '\n'
  bool hung_up_ = false;
};

}  // namespace augrig::nav
