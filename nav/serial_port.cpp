#include "nav/serial_port.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <ctime>
#include <optional>
#include <utility>

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

namespace augrig::nav {
namespace {

struct BaudRate {
  int baud;
  speed_t speed;
};

constexpr BaudRate kBaudRates[] = {
    {1200, B1200},       {1800, B1800},       {2400, B2400},       {4800, B4800},       {9600, B9600},
    {19200, B19200},     {38400, B38400},     {57600, B57600},     {115200, B115200},   {230400, B230400},
    {460800, B460800},   {500000, B500000},   {576000, B576000},   {921600, B921600},   {1000000, B1000000},
    {1152000, B1152000}, {1500000, B1500000}, {2000000, B2000000}, {2500000, B2500000}, {3000000, B3000000},
    {3500000, B3500000}, {4000000, B4000000},
};

std::string baud_list() {
  std::string s;
  for (const BaudRate& b : kBaudRates) s += (s.empty() ? "" : ", ") + std::to_string(b.baud);
  return s;
}

std::optional<speed_t> speed_of(int baud) {
  for (const BaudRate& b : kBaudRates)
    if (b.baud == baud) return b.speed;
  return std::nullopt;
}

}  // namespace

Expected<int> parse_baud(std::string_view text) {
  int baud = 0;
  const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), baud);
  if (text.empty() || ec != std::errc() || p != text.data() + text.size() || !speed_of(baud)) {
    return make_error("expected a baud rate (one of ", baud_list(), "), got '", std::string(text), "'");
  }
  return baud;
}

// ---- SerialPort -----------------------------------------------------------------------------------

Expected<SerialPort> SerialPort::open(const std::string& path, int baud) {
  const std::string prefix = "nav::SerialPort::open(): " + path + ": ";
  const std::optional<speed_t> speed = speed_of(baud);
  if (!speed) return make_error(prefix, "expected a baud rate (one of ", baud_list(), "), got ", baud);
  SerialPort port;
  port.path_ = path;
  port.baud_ = baud;
  port.fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (port.fd_ < 0 && (errno == EACCES || errno == EROFS)) {
    port.fd_ = ::open(path.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);  // reading is enough
  }
  if (port.fd_ < 0) {
    const int e = errno;
    return make_error(prefix, "cannot open the serial port (", std::strerror(e), ")",
                      e == EACCES   ? ": the user needs read access (on Debian: the dialout group)"
                      : e == ENOENT ? ": no such device (is the receiver plugged in? ls /dev/serial/by-id)"
                                    : "");
  }
  if (!isatty(port.fd_)) return make_error(prefix, "not a serial port or terminal device");
  termios t{};
  if (tcgetattr(port.fd_, &t) != 0) {
    return make_error(prefix, "tcgetattr() failed: ", std::strerror(errno));
  }
  cfmakeraw(&t);  // no echo, no line editing, no CR/LF translation, 8 bits
  t.c_cflag &= ~(PARENB | CSTOPB | CSIZE | CRTSCTS);
  t.c_cflag |= CS8 | CLOCAL | CREAD;
  t.c_iflag &= ~(IXON | IXOFF | IXANY);
  t.c_cc[VMIN] = 0;
  t.c_cc[VTIME] = 0;
  if (cfsetispeed(&t, *speed) != 0 || cfsetospeed(&t, *speed) != 0) {
    return make_error(prefix, "cannot set ", baud, " baud: ", std::strerror(errno));
  }
  if (tcsetattr(port.fd_, TCSANOW, &t) != 0) {
    return make_error(prefix, "tcsetattr() failed: ", std::strerror(errno));
  }
  termios check{};
  if (tcgetattr(port.fd_, &check) != 0 || cfgetispeed(&check) != *speed) {
    return make_error(prefix, "the port did not take ", baud, " baud");
  }
  tcflush(port.fd_, TCIFLUSH);  // bytes from before: possibly at another rate, and stale anyway
  return port;
}

SerialPort::SerialPort(SerialPort&& o) noexcept
    : fd_(std::exchange(o.fd_, -1)), path_(std::move(o.path_)), baud_(o.baud_) {}

SerialPort& SerialPort::operator=(SerialPort&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(o.fd_, -1);
    path_ = std::move(o.path_);
    baud_ = o.baud_;
  }
  return *this;
}

SerialPort::~SerialPort() {
  if (fd_ >= 0) ::close(fd_);
}

Expected<SerialPort::ReadResult> SerialPort::read(std::span<std::uint8_t> buffer,
                                                  std::chrono::nanoseconds timeout) {
  const std::string prefix = "nav::SerialPort::read(): " + path_ + ": ";
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  ReadResult r;
  bool hangup = false;  // the last poll() said so
  for (;;) {
    const ssize_t n = ::read(fd_, buffer.data(), buffer.size());
    if (n > 0) {
      r.bytes = static_cast<std::size_t>(n);
      r.arrival_ns = monotonic_now_ns();
      return r;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
      if (errno == EIO || errno == ENODEV || errno == ENXIO) {  // unplugged, or the pty master closed
        r.hung_up = true;
        return r;
      }
      return make_error(prefix, "read() failed: ", std::strerror(errno));
    }
    // No data: 0 (a tty with VMIN = VTIME = 0 says so even when non-blocking), EAGAIN, or the
    // end of a hung-up tty, which poll() has told apart.
    if (hangup) {
      r.hung_up = true;
      return r;
    }
    const TimestampNs left = deadline - monotonic_now_ns();
    if (left <= 0) return r;
    timespec ts{static_cast<time_t>(left / 1'000'000'000), static_cast<long>(left % 1'000'000'000)};
    pollfd p{fd_, POLLIN, 0};
    const int rc = ppoll(&p, 1, &ts, nullptr);
    if (rc < 0 && errno != EINTR) return make_error(prefix, "poll() failed: ", std::strerror(errno));
    if (rc > 0 && (p.revents & (POLLHUP | POLLERR | POLLNVAL))) hangup = true;  // read what is left first
    if (rc == 0) return r;
  }
}

// ---- SerialNmeaInput ------------------------------------------------------------------------------

SerialNmeaInput::SerialNmeaInput(SerialPort port, std::string uri, const SerialNmeaOptions& options)
    : port_(std::move(port)),
      uri_(std::move(uri)),
      options_(options),
      source_(uri_, options.nmea, options.quiet_ns) {}

Expected<std::unique_ptr<SerialNmeaInput>> SerialNmeaInput::open(const std::string& path,
                                                                 const SerialNmeaOptions& options,
                                                                 std::string uri) {
  if (uri.empty()) uri = "serial://" + path + "?baud=" + std::to_string(options.baud);
  auto port = SerialPort::open(path, options.baud);
  if (!port) return port.error();
  return std::unique_ptr<SerialNmeaInput>(new SerialNmeaInput(std::move(*port), std::move(uri), options));
}

void SerialNmeaInput::take_bytes(std::span<const std::uint8_t> bytes, TimestampNs arrival_ns) {
  NavInputStats& st = source_.stats();
  st.bytes += bytes.size();
  for (const std::uint8_t b : bytes) {
    const char c = static_cast<char>(b);
    if (discarding_) {
      if (c == '\n') discarding_ = false;
      continue;
    }
    if (c == '\n') {
      if (!line_.empty()) {
        tap(line_, line_arrival_ns_, false);
        source_.push_line(line_, line_arrival_ns_);
      }
      line_.clear();
      continue;
    }
    if (line_.empty()) line_arrival_ns_ = arrival_ns;
    line_ += c;
    if (line_.size() > options_.max_line_bytes) {
      ++st.oversized;
      st.note(uri_ + ": a line longer than max_line " + std::to_string(options_.max_line_bytes) +
              " bytes (no line end; wrong baud rate or not NMEA?): dropped up to the next line end");
      line_.clear();
      discarding_ = true;
    }
  }
}

Expected<NavReadStatus> SerialNmeaInput::read(NavEvent& out, std::chrono::nanoseconds timeout) {
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  std::uint8_t buffer[4096];
  for (;;) {
    if (source_.pop(out)) return NavReadStatus::kEvent;
    if (hung_up_) return NavReadStatus::kEnd;
    TimestampNs now = monotonic_now_ns();
    source_.poll_quiet(now);
    if (source_.pop(out)) return NavReadStatus::kEvent;
    TimestampNs wait = std::max<TimestampNs>(deadline - now, 0);
    if (const auto q = source_.quiet_deadline_ns()) wait = std::min(wait, std::max<TimestampNs>(*q - now, 0));
    auto r = port_.read(buffer, std::chrono::nanoseconds(wait));
    if (!r) return r.error();
    if (r->bytes > 0) {
      take_bytes(std::span<const std::uint8_t>(buffer, r->bytes), r->arrival_ns);
      continue;
    }
    if (r->hung_up) {
      hung_up_ = true;
      if (!line_.empty() && !discarding_) {  // what there was
        tap(line_, line_arrival_ns_, false);
        source_.push_line(line_, line_arrival_ns_);
      }
      line_.clear();
      source_.flush();
      source_.stats().note(uri_ + ": the serial port hung up (device unplugged or the other side closed)");
      continue;
    }
    now = monotonic_now_ns();
    if (now >= deadline) {
      source_.poll_quiet(now);
      return source_.pop(out) ? NavReadStatus::kEvent : NavReadStatus::kTimeout;
    }
  }
}

}  // namespace augrig::nav
