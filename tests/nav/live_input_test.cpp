// Tests for nav/live_input.hpp: URIs and the factory's errors, and NMEA over UDP from a test
// sender. Oracle for the NMEA input: the batch parser (parse_nmea) on the same text, which is the
// simulator's NMEA log of both aircraft (written in-process with nav::write_nmea, as `augrig sim`
// writes it, without arrival prefixes as a receiver sends it).
#include "nav/live_input.hpp"

#include <chrono>
#include <cmath>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "nav/nmea.hpp"
#include "nav/udp_socket.hpp"
#include "sim/flight.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::nav {
namespace {

using namespace std::chrono_literals;

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// ---- URIs -------------------------------------------------------------------------------------

TEST(LiveInput, ParsesUris) {
  auto u = parse_nav_uri("udp://0.0.0.0:10110?format=nmea&quiet_ms=50");
  ASSERT_TRUE(u) << u.error().message;
  EXPECT_EQ(u->scheme, "udp");
  EXPECT_EQ(u->host, "0.0.0.0");
  EXPECT_EQ(u->port, 10110);
  EXPECT_EQ(u->path, "");
  ASSERT_EQ(u->options.size(), 2u);
  EXPECT_EQ(u->options[0], (std::pair<std::string, std::string>("format", "nmea")));
  EXPECT_EQ(u->options[1], (std::pair<std::string, std::string>("quiet_ms", "50")));
  u = parse_nav_uri("serial:///dev/serial/by-id/usb-u-blox_GNSS-if00?baud=115200");
  ASSERT_TRUE(u) << u.error().message;
  EXPECT_EQ(u->host, "");
  EXPECT_FALSE(u->port);
  EXPECT_EQ(u->path, "/dev/serial/by-id/usb-u-blox_GNSS-if00");
  u = parse_nav_uri("gpsd://localhost");
  ASSERT_TRUE(u) << u.error().message;
  EXPECT_EQ(u->host, "localhost");
  EXPECT_FALSE(u->port);
  u = parse_nav_uri("gpsd://[::1]:2947?device=/dev/ttyACM0");
  ASSERT_TRUE(u) << u.error().message;
  EXPECT_EQ(u->host, "::1");
  EXPECT_EQ(u->port, 2947);
  EXPECT_EQ(u->options[0].second, "/dev/ttyACM0");
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"", "expected SCHEME://"},
      {"udp:/0.0.0.0:1", "expected SCHEME://"},
      {"udp://h:99999?format=nmea", "expected a port number 0..65535, got '99999'"},
      {"udp://h:?format=nmea", "expected a port number after ':'"},
      {"udp://h:1?format", "expected an option KEY=VALUE, got 'format'"},
      {"udp://h:1?format=nmea&format=imu", "option 'format' given twice"},
      {"udp://::1:5?format=nmea", "[brackets]"},
      {"udp://[::1?format=nmea", "no ']'"},
  };
  for (const auto& [text, part] : bad) {
    auto e = parse_nav_uri(text);
    ASSERT_FALSE(e) << text;
    EXPECT_TRUE(contains(e.error().message, "'" + text + "'")) << e.error().message;
    EXPECT_TRUE(contains(e.error().message, part)) << text << ": " << e.error().message;
  }
}

TEST(LiveInput, BadUrisAreErrorsNamingTheUriAndWhatWasExpected) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"ftp://h:1", "unknown scheme 'ftp': expected udp://BIND_ADDR:PORT?format=nmea|imu, serial://"},
      {"udp://127.0.0.1:0", "expected the option format=nmea, format=imu or format=ubx"},
      {"udp://127.0.0.1:0?format=xml", "format=nmea, format=imu or format=ubx, got format=xml"},
      {"udp://127.0.0.1?format=nmea", "expected udp://BIND_ADDR:PORT?format=nmea|imu"},
      {"udp://127.0.0.1:0/x?format=nmea", "expected no path after the port"},
      {"udp://127.0.0.1:0?format=nmea&bogus=1",
       "unknown option 'bogus' (udp options: format, max_datagram, rcvbuf, "
       "quiet_ms, leap_seconds, date)"},
      {"udp://127.0.0.1:0?format=imu&quiet_ms=5",
       "unknown option 'quiet_ms' (udp options: format, max_datagram, rcvbuf)"},
      {"udp://127.0.0.1:0?format=nmea&quiet_ms=0",
       "option quiet_ms: expected the quiet gap that closes an epoch, in ms "
       "(1..10000), got '0'"},
      {"udp://127.0.0.1:0?format=nmea&max_datagram=70000",
       "option max_datagram: expected the largest datagram kept"},
      {"udp://127.0.0.1:0?format=nmea&date=2024-02-30",
       "option date: expected a date YYYY-MM-DD, got '2024-02-30'"},
      {"udp://192.0.2.1:0?format=nmea", "no interface of this host has that address"},
      {"serial:///dev/ttyUSB0", "expected the option baud=RATE"},
      {"serial:///dev/ttyUSB0?baud=1234", "option baud: expected a baud rate (one of 1200, "},
      {"serial://dev/ttyUSB0?baud=9600", "expected serial:///dev/DEVICE?baud=RATE (three slashes"},
      {"serial:///nonexistent/tty0?baud=9600",
       "nav::SerialPort::open(): /nonexistent/tty0: cannot open the serial port"},
      {"gpsd://127.0.0.1:0", "expected a gpsd port 1..65535"},
      {"gpsd://127.0.0.1/dev/ttyUSB0", "the device goes in device="},
      {"gpsd://127.0.0.1:1", "cannot connect to gpsd at 127.0.0.1:1"},
      {"gpsd://127.0.0.1:1?colour=red",
       "unknown option 'colour' (gpsd options: device, quiet_ms, leap_seconds, "
       "connect_timeout_ms)"},
  };
  for (const auto& [uri, part] : bad) {
    auto in = open_nav_input(uri);
    ASSERT_FALSE(in) << uri;
    const std::string& m = in.error().message;
    EXPECT_TRUE(contains(m, uri)) << uri << ": " << m;
    EXPECT_TRUE(contains(m, part)) << uri << ": " << m;
  }
}

TEST(LiveInput, StatsKeepTheLastErrors) {
  NavInputStats st;
  for (int i = 0; i < 20; ++i) st.note("e" + std::to_string(i));
  ASSERT_EQ(st.last_errors.size(), NavInputStats::kMaxErrors);
  EXPECT_EQ(st.last_errors.front(), "e12");
  EXPECT_EQ(st.last_errors.back(), "e19");
}

// ---- NMEA over UDP ----------------------------------------------------------------------------

struct SimLogs {
  std::string tanker, receiver;  // NMEA text, CR LF, no arrival prefix
};

SimLogs sim_nmea(double duration_s) {
  sim::Scenario s = *sim::builtin_scenario("demo");
  s.duration_s = duration_s;
  const sim::Flight f = *sim::Flight::create(s);
  const sim::SensorLogs logs = sim::simulate_sensors(s, f);
  return {write_nmea(logs.tanker_gps), write_nmea(logs.receiver_gps)};
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line + "\n");  // keeps the CR
  return out;
}

// Reads whatever has arrived (no waiting) into `out`.
void drain(NavInput& in, std::vector<NavEvent>& out) {
  NavEvent e;
  for (;;) {
    auto r = in.read(e, 0ns);
    ASSERT_TRUE(r) << r.error().message;
    if (*r != NavReadStatus::kEvent) return;
    out.push_back(e);
  }
}

TEST(LiveInput, NmeaOverUdpGivesTheBatchParsersFixes) {
  const SimLogs logs = sim_nmea(8.0);
  // A long quiet gap: here epochs close on the next time tag, whatever the machine's load.
  auto opened = open_nav_input("udp://127.0.0.1:0?format=nmea&quiet_ms=400");
  ASSERT_TRUE(opened) << opened.error().message;
  auto* in = dynamic_cast<UdpNmeaInput*>(opened->get());
  ASSERT_NE(in, nullptr);
  auto tx = UdpSender::open("127.0.0.1", in->port());
  ASSERT_TRUE(tx) << tx.error().message;

  const TimestampNs start = monotonic_now_ns();
  std::vector<NavEvent> got;
  std::size_t junk = 0, oversized = 0, epochs = 0;
  // The tanker's log one line per datagram, with junk and oversized datagrams between epochs.
  for (const std::string& line : lines_of(logs.tanker)) {
    if (line.find("GGA") != std::string::npos && ++epochs % 10 == 5) {
      ASSERT_TRUE(tx->send(std::string_view("\x01\x02 not NMEA \xff\r\n")));
      ASSERT_TRUE(tx->send(
          "$GNGGA,120000.000,5100.0,N,00100.0,W,4,16,0.70,6000.0,M,36.0,M,,*00\r\n"));  // bad checksum
      ASSERT_TRUE(tx->send(std::string(1500, '$')));
      junk += 2;
      ++oversized;
    }
    ASSERT_TRUE(tx->send(line));
    drain(**opened, got);
  }
  NavEvent e;
  for (;;) {  // the last epoch closes when the sender has been quiet for 400 ms
    auto r = (*opened)->read(e, 1s);
    ASSERT_TRUE(r) << r.error().message;
    if (*r != NavReadStatus::kEvent) break;
    got.push_back(e);
  }

  const auto batch = [](const std::string& text) {
    std::istringstream s(text);
    return *parse_nmea(s, "sim.nmea");
  };
  const NmeaLog tanker = batch(logs.tanker);
  ASSERT_EQ(tanker.fixes.size(), 81u);  // 8 s at 10 Hz, both ends
  ASSERT_EQ(got.size(), tanker.fixes.size());
  TimestampNs prev_arrival = start;
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_TRUE(got[i].is_gps());
    GpsFix live = got[i].gps();
    EXPECT_GE(live.arrival_ns, prev_arrival) << i;  // CLOCK_MONOTONIC, non-decreasing
    prev_arrival = live.arrival_ns;
    live.arrival_ns = 0;  // the batch log has none
    test::expect_same_fix(live, tanker.fixes[i], "fix " + std::to_string(i));
    ASSERT_TRUE(live.heading_rad) << i;  // the tanker has a dual-antenna heading
    EXPECT_EQ(got[i].sensor_clock, ClockDomain::kGps);
  }
  EXPECT_LE(prev_arrival, monotonic_now_ns());
  const NavInputStats st = (*opened)->stats();
  EXPECT_EQ(st.events, got.size());
  EXPECT_EQ(st.malformed, junk);
  EXPECT_EQ(st.oversized, oversized);
  EXPECT_EQ(st.datagrams, lines_of(logs.tanker).size() + junk + oversized);
  EXPECT_EQ(st.lines, lines_of(logs.tanker).size() + junk);
  EXPECT_EQ(st.dropped, 0u);
  bool named_oversized = false, named_checksum = false;
  for (const std::string& m : st.last_errors) {
    named_oversized |= contains(m, "1500 bytes, more than max_datagram 1472: dropped");
    named_checksum |= contains(m, "bad checksum");
  }
  EXPECT_TRUE(named_oversized);
  EXPECT_TRUE(named_checksum);
}

TEST(LiveInput, NmeaDatagramsMayCarrySeveralLines) {
  const SimLogs logs = sim_nmea(3.0);
  auto opened = open_nav_input("udp://127.0.0.1:0?format=nmea&quiet_ms=400");
  ASSERT_TRUE(opened) << opened.error().message;
  auto tx = UdpSender::open("127.0.0.1", dynamic_cast<UdpNmeaInput*>(opened->get())->port());
  ASSERT_TRUE(tx);
  // One datagram per epoch, the last line without its line end.
  std::vector<NavEvent> got;
  std::string datagram;
  for (const std::string& line : lines_of(logs.receiver)) {
    if (line.find("GGA") != std::string::npos && !datagram.empty()) {
      datagram.resize(datagram.size() - 2);  // no CR LF at the end
      ASSERT_TRUE(tx->send(datagram));
      datagram.clear();
      drain(**opened, got);
    }
    datagram += line;
  }
  ASSERT_TRUE(tx->send(datagram));
  NavEvent e;
  while (true) {
    auto r = (*opened)->read(e, 2s);
    ASSERT_TRUE(r);
    if (*r != NavReadStatus::kEvent) break;
    got.push_back(e);
  }
  std::istringstream s(logs.receiver);
  const NmeaLog batch = *parse_nmea(s, "sim.nmea");
  ASSERT_EQ(got.size(), batch.fixes.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].gps().t_ns, batch.fixes[i].t_ns);
    EXPECT_EQ(got[i].gps().antenna.lat_rad, batch.fixes[i].antenna.lat_rad);
    EXPECT_EQ(got[i].gps().ground_speed_mps, batch.fixes[i].ground_speed_mps);
    EXPECT_FALSE(got[i].gps().heading_rad);  // the receiver has none
  }
  const NavInputStats st = (*opened)->stats();
  EXPECT_EQ(st.datagrams, batch.fixes.size());
  EXPECT_EQ(st.lines, lines_of(logs.receiver).size());
  EXPECT_EQ(st.malformed, 0u);
}

// The raw tap sees every line exactly as sent (without its line end), with its arrival time, before
// parsing; malformed lines too, since it is what recording keeps.
TEST(LiveInput, RawTapSeesEveryLineAsReceived) {
  const SimLogs logs = sim_nmea(2.0);
  auto opened = open_nav_input("udp://127.0.0.1:0?format=nmea&quiet_ms=100");
  ASSERT_TRUE(opened) << opened.error().message;
  std::vector<std::pair<std::string, TimestampNs>> tapped;
  (*opened)->set_raw_tap([&](std::string_view data, TimestampNs arrival_ns, bool binary) {
    EXPECT_FALSE(binary);
    tapped.emplace_back(std::string(data), arrival_ns);
  });
  auto tx = UdpSender::open("127.0.0.1", dynamic_cast<UdpNmeaInput*>(opened->get())->port());
  ASSERT_TRUE(tx);
  std::vector<std::string> sent;
  for (std::string line : lines_of(logs.receiver)) {
    while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
    sent.push_back(line);
  }
  sent.insert(sent.begin() + 3, "$GPGGA,garbage*00");
  std::vector<NavEvent> got;
  for (const std::string& line : sent) {
    ASSERT_TRUE(tx->send(line));
    drain(**opened, got);
  }
  NavEvent e;
  while (*(*opened)->read(e, 300ms) == NavReadStatus::kEvent) {
  }
  ASSERT_EQ(tapped.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_EQ(tapped[i].first, sent[i]);
    EXPECT_GT(tapped[i].second, 0);
    if (i) {
      EXPECT_GE(tapped[i].second, tapped[i - 1].second);
    }
  }
  EXPECT_EQ((*opened)->stats().malformed, 1u);
}

TEST(LiveInput, AnEpochClosesAfterTheQuietGap) {
  auto opened = open_nav_input("udp://127.0.0.1:0?format=nmea&quiet_ms=50");
  ASSERT_TRUE(opened) << opened.error().message;
  auto tx = UdpSender::open("127.0.0.1", dynamic_cast<UdpNmeaInput*>(opened->get())->port());
  ASSERT_TRUE(tx);
  const SimLogs logs = sim_nmea(0.05);  // one epoch
  ASSERT_TRUE(tx->send(logs.receiver));
  NavEvent e;
  auto r = (*opened)->read(e, 5s);
  ASSERT_TRUE(r) << r.error().message;
  ASSERT_EQ(*r, NavReadStatus::kEvent);
  // Not before the sender has been quiet for 50 ms: nothing could have completed it earlier.
  EXPECT_GE(monotonic_now_ns() - e.arrival_ns(), 50'000'000);
  EXPECT_TRUE(e.gps().ground_speed_mps);  // the whole epoch: GGA and RMC
  r = (*opened)->read(e, 20ms);
  ASSERT_TRUE(r);
  EXPECT_EQ(*r, NavReadStatus::kTimeout);
}

}  // namespace
}  // namespace augrig::nav
