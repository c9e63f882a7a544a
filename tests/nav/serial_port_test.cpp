// Tests for nav/serial_port.hpp with a pty pair as the port: the test writes NMEA on the master
// side as a receiver would, the input reads the slave side. Oracle: the batch parser on the same
// text (the simulator's NMEA log of the tanker, written in-process with nav::write_nmea).
#include "nav/serial_port.hpp"

#include <cerrno>
#include <chrono>
#include <cstring>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"

namespace augrig::nav {
namespace {

using namespace std::chrono_literals;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// A pty pair; the slave's path is the "serial port".
struct Pty {
  int master = -1, slave = -1;
  std::string path;
  Pty() {
    if (openpty(&master, &slave, nullptr, nullptr, nullptr) != 0) return;
    path = ttyname(slave);
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
  }
  ~Pty() {
    close_master();
    if (slave >= 0) ::close(slave);
  }
  void close_master() {
    if (master >= 0) ::close(master);
    master = -1;
  }
  // Writes all of `s` (the slave side is read meanwhile by `drain`, so the pty never fills).
  void write(const std::string& s) const {
    std::size_t at = 0;
    while (at < s.size()) {
      const ssize_t n = ::write(master, s.data() + at, s.size() - at);
      if (n > 0) at += static_cast<std::size_t>(n);
      if (n < 0 && errno != EAGAIN && errno != EINTR)
        FAIL() << "write to the pty master: " << std::strerror(errno);
      if (n <= 0) std::this_thread::sleep_for(1ms);
    }
  }
};

std::string sim_tanker_nmea(double duration_s) {
  sim::Scenario s = *sim::builtin_scenario("demo");
  s.duration_s = duration_s;
  const sim::Flight f = *sim::Flight::create(s);
  return write_nmea(sim::simulate_sensors(s, f).tanker_gps);
}

std::vector<NavEvent> drain(NavInput& in, std::chrono::nanoseconds timeout = 0ns) {
  std::vector<NavEvent> out;
  NavEvent e;
  for (;;) {
    auto r = in.read(e, timeout);
    EXPECT_TRUE(r) << r.error().message;
    if (!r || *r != NavReadStatus::kEvent) return out;
    out.push_back(e);
  }
}

TEST(SerialPort, ParsesBaudRates) {
  for (int b : {1200, 4800, 9600, 38400, 115200, 230400, 460800, 921600}) {
    auto r = parse_baud(std::to_string(b));
    ASSERT_TRUE(r) << b;
    EXPECT_EQ(*r, b);
  }
  for (const char* bad : {"", "0", "1234", "115200 ", "-9600", "9600x", "fast", "99999999999"}) {
    auto r = parse_baud(bad);
    ASSERT_FALSE(r) << bad;
    EXPECT_TRUE(contains(r.error().message, "expected a baud rate (one of 1200, 1800, 2400, 4800, 9600"))
        << r.error().message;
    EXPECT_TRUE(contains(r.error().message, "got '" + std::string(bad) + "'")) << r.error().message;
  }
}

TEST(SerialPort, OpensAPtyRaw8N1AtTheBaud) {
  Pty pty;
  ASSERT_FALSE(pty.path.empty()) << "openpty() failed";
  auto port = SerialPort::open(pty.path, 115200);
  ASSERT_TRUE(port) << port.error().message;
  EXPECT_EQ(port->baud(), 115200);
  termios t{};
  ASSERT_EQ(tcgetattr(port->fd(), &t), 0);
  EXPECT_EQ(cfgetispeed(&t), B115200);
  EXPECT_EQ(cfgetospeed(&t), B115200);
  EXPECT_EQ(t.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
  EXPECT_EQ(t.c_cflag & (PARENB | CSTOPB | CRTSCTS), 0u);
  EXPECT_EQ(t.c_lflag & (ICANON | ECHO | ISIG), 0u);   // raw: no line editing, no echo
  EXPECT_EQ(t.c_iflag & (ICRNL | IXON | ISTRIP), 0u);  // CR LF arrive untouched
  // Bytes written on the master come out of the port unchanged.
  pty.write("ab\r\n\x01");
  std::uint8_t buf[16];
  std::string got;
  while (got.size() < 5) {
    auto r = port->read(buf, 1s);
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_GT(r->bytes, 0u);
    EXPECT_GT(r->arrival_ns, 0);
    got.append(reinterpret_cast<char*>(buf), r->bytes);
  }
  EXPECT_EQ(got, "ab\r\n\x01");
  auto quiet = port->read(buf, 10ms);
  ASSERT_TRUE(quiet);
  EXPECT_EQ(quiet->bytes, 0u);
  EXPECT_FALSE(quiet->hung_up);
  // Errors name the device and why.
  auto missing = SerialPort::open("/nonexistent/ttyUSB9", 9600);
  ASSERT_FALSE(missing);
  EXPECT_TRUE(contains(missing.error().message, "/nonexistent/ttyUSB9: cannot open the serial port"));
  auto file = SerialPort::open("/dev/null", 9600);
  ASSERT_FALSE(file);
  EXPECT_TRUE(contains(file.error().message, "/dev/null: not a serial port")) << file.error().message;
  auto rate = SerialPort::open(pty.path, 1234);
  ASSERT_FALSE(rate);
  EXPECT_TRUE(contains(rate.error().message, "expected a baud rate")) << rate.error().message;
}

TEST(SerialPort, NmeaWrittenOnTheMasterArrivesAsTheBatchParsersFixes) {
  Pty pty;
  ASSERT_FALSE(pty.path.empty()) << "openpty() failed";
  const std::string uri = "serial://" + pty.path + "?baud=115200&quiet_ms=400";
  auto opened = open_nav_input(uri);
  ASSERT_TRUE(opened) << opened.error().message;
  EXPECT_EQ((*opened)->uri(), uri);
  const std::string text = sim_tanker_nmea(5.0);

  // Written in pieces that cut lines anywhere, with a line far too long and junk in between.
  std::vector<NavEvent> got;
  const TimestampNs start = monotonic_now_ns();
  std::uint32_t x = 7;
  std::size_t at = 0, pieces = 0;
  while (at < text.size()) {
    x = x * 1664525u + 1013904223u;
    const std::size_t n = std::min<std::size_t>(1 + (x >> 24) % 150, text.size() - at);
    pty.write(text.substr(at, n));
    at += n;
    if (++pieces == 40) {
      const std::size_t eol = text.find('\n', at);  // finish the line first, then the junk lines
      pty.write(text.substr(at, eol + 1 - at));
      at = eol + 1;
      pty.write(std::string(3000, 'Z') + "\r\n" + "garbage\r\n");
    }
    for (NavEvent& e : drain(**opened)) got.push_back(e);
  }
  for (NavEvent& e : drain(**opened, 1s)) got.push_back(e);

  std::istringstream s(text);
  const NmeaLog batch = *parse_nmea(s, "sim.nmea");
  ASSERT_EQ(batch.fixes.size(), 51u);
  ASSERT_EQ(got.size(), batch.fixes.size());
  TimestampNs prev = start;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const GpsFix& f = got[i].gps();
    const GpsFix& b = batch.fixes[i];
    EXPECT_EQ(f.t_ns, b.t_ns) << i;
    EXPECT_EQ(f.antenna.lat_rad, b.antenna.lat_rad) << i;
    EXPECT_EQ(f.antenna.lon_rad, b.antenna.lon_rad) << i;
    EXPECT_EQ(f.antenna.h_m, b.antenna.h_m) << i;
    EXPECT_EQ(f.quality, b.quality) << i;
    EXPECT_EQ(f.sigma_ned_m, b.sigma_ned_m) << i;
    EXPECT_EQ(f.ground_speed_mps, b.ground_speed_mps) << i;
    EXPECT_EQ(f.heading_rad, b.heading_rad) << i;
    EXPECT_GE(f.arrival_ns, prev) << i;  // CLOCK_MONOTONIC, non-decreasing
    prev = f.arrival_ns;
  }
  EXPECT_LE(prev, monotonic_now_ns());
  NavInputStats st = (*opened)->stats();
  EXPECT_EQ(st.oversized, 1u);
  EXPECT_EQ(st.malformed, 1u);  // "garbage"
  EXPECT_EQ(st.bytes, text.size() + 3000 + 2 + 9);
  EXPECT_EQ(st.lines, batch.lines + 1);  // + "garbage"; the long line never reached the parser
  EXPECT_EQ(st.events, got.size());

  // The first epoch again: an older fix, refused once the quiet gap closes it.
  pty.write(text.substr(0, text.find("GNGGA", 10)));
  NavEvent e;
  auto r = (*opened)->read(e, 1s);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(*r, NavReadStatus::kTimeout);
  // The other side closes: the input ends, and stays ended.
  pty.close_master();
  r = (*opened)->read(e, 2s);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(*r, NavReadStatus::kEnd);
  r = (*opened)->read(e, 0ns);
  ASSERT_TRUE(r);
  EXPECT_EQ(*r, NavReadStatus::kEnd);
  st = (*opened)->stats();
  EXPECT_EQ(st.out_of_order, 1u);  // the repeated first epoch
  EXPECT_TRUE(contains(st.last_errors.back(), "hung up")) << st.last_errors.back();
}

}  // namespace
}  // namespace augrig::nav
