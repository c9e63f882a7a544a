// The u-blox UBX live input (nav/ubx_input.hpp) over real UDP on loopback and a pty standing in for
// the serial port: NAV-PVT as fixes and NAV-RELPOSNED as moving-baseline events on GPS time (the
// week from the NAV-PVT's UTC date), frames split across datagrams, damage counted and named, the
// raw tap, and the URI's options.
#include "nav/ubx_input.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <pty.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <thread>

#include <gtest/gtest.h>

#include "nav/gps_time.hpp"

namespace augrig::nav {
namespace {

using namespace std::chrono_literals;

// 2024-06-01 (a Saturday) 12:00:00 UTC = GPS week 2317, time of week 6 days 12:00:18.
constexpr std::uint32_t kTowNoonMs = (6u * 86400u + 12u * 3600u + 18u) * 1000u;

UbxNavPvt pvt(std::uint32_t itow_ms) {
  UbxNavPvt m;
  m.itow_ms = itow_ms;
  m.year = 2024, m.month = 6, m.day = 1, m.hour = 12, m.minute = 0;
  m.second = static_cast<int>((itow_ms - kTowNoonMs) / 1000);
  m.valid_date = m.valid_time = m.fully_resolved = true;
  m.fix_type = 3;
  m.gnss_fix_ok = true;
  m.satellites = 14;
  m.lat_deg = 51.0, m.lon_deg = -1.0, m.height_m = 7050.0, m.height_msl_m = 7002.0;
  m.h_acc_m = 1.4, m.v_acc_m = 2.5;
  m.vel_ned_mps = {0.0, 160.0, 0.5};
  m.pdop = 1.2;
  return m;
}

UbxRelPosNed relposned(std::uint32_t itow_ms, int carr_soln = 2) {
  UbxRelPosNed m;
  m.itow_ms = itow_ms;
  m.rel_pos_ned_m = {-20.1234, 1.0567, 8.2101};
  m.acc_ned_m = {0.01, 0.01, 0.015};
  m.gnss_fix_ok = m.diff_soln = m.rel_pos_valid = m.is_moving = true;
  m.carr_soln = carr_soln;
  return m;
}

std::vector<std::uint8_t> cat(std::initializer_list<std::vector<std::uint8_t>> parts) {
  std::vector<std::uint8_t> out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

std::vector<NavEvent> drain(NavInput& in, std::size_t want, std::chrono::milliseconds patience = 2000ms) {
  std::vector<NavEvent> out;
  NavEvent e;
  const auto until = std::chrono::steady_clock::now() + patience;
  while (out.size() < want && std::chrono::steady_clock::now() < until) {
    auto r = in.read(e, 50ms);
    EXPECT_TRUE(r) << r.error().message;
    if (!r || *r == NavReadStatus::kEnd) break;
    if (*r == NavReadStatus::kEvent) out.push_back(e);
  }
  return out;
}

// A sender on loopback.
struct Sender {
  int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  explicit Sender(std::uint16_t port) {
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  }
  ~Sender() { ::close(fd); }
  void send(const std::vector<std::uint8_t>& bytes) const {
    ASSERT_EQ(::sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to),
              static_cast<ssize_t>(bytes.size()));
  }
};

TEST(UbxInput, FixesAndBaselinesOverUdpOnGpsTime) {
  auto opened = open_nav_input("udp://127.0.0.1:0?format=ubx");
  ASSERT_TRUE(opened) << opened.error().message;
  auto& in = dynamic_cast<UdpUbxInput&>(**opened);
  std::vector<std::string> tapped;
  in.set_raw_tap([&](std::string_view data, TimestampNs, bool binary) {
    EXPECT_TRUE(binary);
    tapped.emplace_back(data);
  });
  Sender tx(in.port());
  const auto a = encode_nav_pvt(pvt(kTowNoonMs));
  const auto b = encode_nav_relposned(relposned(kTowNoonMs));
  auto bad = encode_nav_relposned(relposned(kTowNoonMs + 100));
  bad[20] ^= 0x40;  // a flipped bit: the checksum fails
  const auto c = encode_nav_relposned(relposned(kTowNoonMs + 200, 1));
  const auto old = encode_nav_relposned(relposned(kTowNoonMs + 100));  // older than c: out of order
  // One frame split across two datagrams, two in one, garbage between.
  const std::vector<std::uint8_t> all = cat({a, b, bad, {0x00, 0x42, 0x13}, c, old});
  const std::size_t split = a.size() / 2;
  tx.send({all.begin(), all.begin() + static_cast<std::ptrdiff_t>(split)});
  tx.send({all.begin() + static_cast<std::ptrdiff_t>(split), all.end()});
  const std::vector<NavEvent> events = drain(in, 3);
  ASSERT_EQ(events.size(), 3u);
  const TimestampNs noon = *gps_ns_from_utc_by_table({2024, 6, 1}, 12 * 3600 * kNsPerSecond);
  ASSERT_TRUE(events[0].is_gps());
  const GpsFix& fix = events[0].gps();
  EXPECT_EQ(fix.t_ns, noon);
  EXPECT_EQ(fix.quality, FixQuality::kSingle);
  EXPECT_NEAR(rad_to_deg(fix.antenna.lat_rad), 51.0, 1e-7);
  EXPECT_NEAR(fix.antenna.h_m, 7050.0, 1e-3);
  ASSERT_TRUE(fix.sigma_ned_m);
  EXPECT_NEAR(fix.sigma_ned_m->z(), 2.5, 1e-3);
  EXPECT_NEAR(*fix.course_rad, kPi / 2, 1e-9);
  ASSERT_TRUE(events[0].velocity_ned_mps);
  ASSERT_TRUE(events[1].is_baseline());
  const BaselineMeasurement& m = events[1].baseline();
  EXPECT_EQ(m.t_ns, noon);
  EXPECT_GT(m.arrival_ns, 0);
  EXPECT_NEAR(m.ned_m.x(), -20.1234, 1e-4);
  EXPECT_NEAR(m.sigma_ned_m.z(), 0.015, 1e-4);
  EXPECT_EQ(m.carr_soln, 2);
  EXPECT_TRUE(m.valid);
  ASSERT_TRUE(events[2].is_baseline());
  EXPECT_EQ(events[2].baseline().t_ns, noon + 200'000'000);
  EXPECT_EQ(events[2].baseline().carr_soln, 1);
  const NavInputStats st = in.stats();
  EXPECT_EQ(st.datagrams, 2u);
  EXPECT_EQ(st.bytes, all.size());
  EXPECT_EQ(st.events, 3u);
  EXPECT_EQ(st.malformed, 1u);
  EXPECT_EQ(st.out_of_order, 1u);
  EXPECT_EQ(tapped.size(), 4u) << "every whole frame with a good checksum, before it is decoded";
  EXPECT_EQ(tapped[0], std::string(a.begin(), a.end()));
  std::string said;
  for (const std::string& e : st.last_errors) said += e + "\n";
  EXPECT_NE(said.find("NAV-RELPOSNED at iTOW " + std::to_string(kTowNoonMs + 100) + " ms not after the previous"),
            std::string::npos)
      << said;
  EXPECT_NE(said.find("bad checksum"), std::string::npos) << said;
}

TEST(UbxInput, BaselinesOnlyWhenFixesAreOffAndTheWeekFromTheHostClockBeforeAnyPvt) {
  auto opened = open_nav_input("udp://127.0.0.1:0?format=ubx&fixes=0");
  ASSERT_TRUE(opened) << opened.error().message;
  auto& in = dynamic_cast<UdpUbxInput&>(**opened);
  Sender tx(in.port());
  // No NAV-PVT yet: the week is the one nearest the host's clock.
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const std::int64_t unix_s = std::chrono::duration_cast<std::chrono::seconds>(now).count();
  const TimestampNs gps_now = (unix_s - 315964800 + 18) * kNsPerSecond;  // GPS epoch 1980-01-06, 18 leap s
  const auto tow_ms = static_cast<std::uint32_t>((gps_now / 1'000'000) % (604800LL * 1000));
  tx.send(cat({encode_nav_relposned(relposned(tow_ms)), encode_nav_pvt(pvt(kTowNoonMs))}));
  const std::vector<NavEvent> events = drain(in, 1);
  ASSERT_EQ(events.size(), 1u);
  ASSERT_TRUE(events[0].is_baseline());
  EXPECT_LT(std::abs(events[0].t_ns() - gps_now), 2 * kNsPerSecond);
  EXPECT_TRUE(drain(in, 1, 200ms).empty()) << "NAV-PVT is not a fix with fixes=0";
}

TEST(UbxInput, UriOptionsAreChecked) {
  for (const char* bad : {"udp://127.0.0.1:0?format=ubx&fixes=2", "udp://127.0.0.1:0?format=ubx&quiet_ms=5",
                          "udp://127.0.0.1:0?format=xml", "serial:///dev/null?baud=9600&format=xml"}) {
    auto in = open_nav_input(bad);
    ASSERT_FALSE(in) << bad;
    EXPECT_NE(in.error().message.find(bad), std::string::npos) << in.error().message;
  }
}

TEST(UbxInput, ByteStreamOnASerialPort) {
  int master = -1, slave = -1;
  ASSERT_EQ(openpty(&master, &slave, nullptr, nullptr, nullptr), 0);
  const std::string path = ttyname(slave);
  auto opened = open_nav_input("serial://" + path + "?baud=115200&format=ubx");
  ASSERT_TRUE(opened) << opened.error().message;
  const std::vector<std::uint8_t> bytes =
      cat({encode_nav_pvt(pvt(kTowNoonMs)), encode_nav_relposned(relposned(kTowNoonMs)),
           encode_nav_relposned(relposned(kTowNoonMs + 200))});
  // In pieces of 7 bytes, as a UART delivers them.
  std::thread writer([&] {
    for (std::size_t at = 0; at < bytes.size(); at += 7) {
      const std::size_t n = std::min<std::size_t>(7, bytes.size() - at);
      ASSERT_EQ(::write(master, bytes.data() + at, n), static_cast<ssize_t>(n));
      std::this_thread::sleep_for(1ms);
    }
  });
  const std::vector<NavEvent> events = drain(**opened, 3);
  writer.join();
  ASSERT_EQ(events.size(), 3u);
  EXPECT_TRUE(events[0].is_gps());
  EXPECT_TRUE(events[1].is_baseline());
  EXPECT_EQ(events[2].t_ns() - events[1].t_ns(), 200'000'000);
  EXPECT_EQ((*opened)->stats().malformed, 0u);
  ::close(master);
  ::close(slave);
}

}  // namespace
}  // namespace augrig::nav
