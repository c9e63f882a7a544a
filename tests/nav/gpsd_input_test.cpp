// Tests for nav/gpsd_input.hpp. The report logic is fed the JSON reports gpsd 3.22 sends (copied
// from a gpsd session, including its broken ATT reports); the client is tested against a real
// gpsd started by gpsfake (gpsd-clients) on the simulator's NMEA log of the tanker, whose fixes,
// read back by the batch NMEA parser, are the oracle. Tolerances: what gpsd's JSON keeps of the
// NMEA values (lat/lon 1e-9 deg, altHAE 0.1 mm, geoidSep 1 mm, speed 1 mm/s, track 1e-4 deg,
// GST sigmas 1 mm, ATT heading 1e-3 deg), each allowed half a unit of rounding plus a margin.
#include "nav/gpsd_input.hpp"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "nav/geodesy.hpp"
#include "nav/nmea.hpp"
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

// 2024-06-01 12:00:00 UTC in GPS ns with 18 leap seconds.
const TimestampNs kNoon = gps_ns_from_utc({2024, 6, 1}, 12 * 3600 * kNsPerSecond, 18);

std::vector<NavEvent> pop_all(GpsdReportMerger& m) {
  std::vector<NavEvent> out;
  NavEvent e;
  while (m.pop(e)) out.push_back(e);
  return out;
}

// ---- The report logic -------------------------------------------------------------------------

TEST(GpsdInput, MergesOneEpochsReportsAsGpsd322SendsThem) {
  GpsdReportMerger m("gpsd://test", {});
  // One epoch as gpsd 3.22 reports the tanker's log: GST, TPV, then an ATT with a time, which
  // gpsd 3.22 writes as broken JSON.
  m.push_report(R"({"class":"VERSION","release":"3.22","rev":"3.22","proto_major":3,"proto_minor":14})", 1);
  m.push_report(
      R"({"class":"GST","device":"/dev/pts/7","time":"2024-06-01T12:00:00.800Z","major":0.010,"minor":0.010,"orient":0.000,"lat":0.011,"lon":0.012,"alt":0.020})",
      100);
  m.push_report(
      R"({"class":"TPV","device":"/dev/pts/7","status":3,"mode":3,"time":"2024-06-01T12:00:00.800Z","ept":0.005,"lat":50.999999942,"lon":-0.998112821,"altHAE":7003.1133,"altMSL":6967.1102,"alt":6967.1102,"track":89.9913,"magtrack":89.5736,"magvar":-0.4,"speed":160.022,"geoidSep":36.003,"eph":13.300})",
      200);
  m.push_report(
      R"({"class":"ATT","device":"/dev/pts/7",,"time":"2024-06-01T12:00:00.800Z""heading":90.010,"dip":0.010,"acc_x":0.010,"acc_y":0.010,"acc_z":0.000,"gyro_x":0.020,"depth":0.010})",
      300);
  EXPECT_TRUE(pop_all(m).empty());  // the epoch may still grow
  EXPECT_EQ(m.quiet_deadline_ns(), 300 + 20'000'000);
  // The next epoch's first report closes it.
  m.push_report(
      R"({"class":"GST","device":"/dev/pts/7","time":"2024-06-01T12:00:00.900Z","major":0.010,"minor":0.010,"orient":0.000,"lat":0.010,"lon":0.010,"alt":0.020})",
      400);
  std::vector<NavEvent> ev = pop_all(m);
  ASSERT_EQ(ev.size(), 1u);
  const GpsFix& f = ev[0].gps();
  EXPECT_EQ(f.t_ns, kNoon + 800'000'000);
  EXPECT_EQ(f.arrival_ns, 200);  // the TPV's
  EXPECT_EQ(f.quality, FixQuality::kRtkFixed);
  EXPECT_DOUBLE_EQ(rad_to_deg(f.antenna.lat_rad), 50.999999942);
  EXPECT_DOUBLE_EQ(rad_to_deg(f.antenna.lon_rad), -0.998112821);
  EXPECT_DOUBLE_EQ(f.antenna.h_m, 7003.1133);
  EXPECT_DOUBLE_EQ(f.geoid_separation_m, 36.003);
  EXPECT_DOUBLE_EQ(*f.ground_speed_mps, 160.022);
  EXPECT_DOUBLE_EQ(*f.course_rad, deg_to_rad(89.9913));
  ASSERT_TRUE(f.sigma_ned_m);
  EXPECT_EQ(*f.sigma_ned_m, Eigen::Vector3d(0.011, 0.012, 0.020));
  ASSERT_TRUE(f.heading_rad);  // read from the broken ATT's text
  EXPECT_DOUBLE_EQ(*f.heading_rad, deg_to_rad(90.010));
  EXPECT_FALSE(ev[0].velocity_ned_mps);
  EXPECT_EQ(ev[0].sensor_clock, ClockDomain::kGps);
  // A well-formed ATT without a time joins the open epoch; the quiet gap then closes it.
  m.push_report(
      R"({"class":"TPV","device":"/dev/pts/7","status":4,"mode":3,"time":"2024-06-01T12:00:00.900Z","lat":51,"lon":-1,"altHAE":7000})",
      500);
  m.push_report(R"({"class":"ATT","device":"/dev/pts/7","heading":91.5})", 600);
  m.poll_quiet(600 + 19'999'999);
  EXPECT_TRUE(pop_all(m).empty());
  m.poll_quiet(600 + 20'000'000);
  ev = pop_all(m);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].gps().quality, FixQuality::kRtkFloat);
  EXPECT_DOUBLE_EQ(*ev[0].gps().heading_rad, deg_to_rad(91.5));
  EXPECT_EQ(*ev[0].gps().sigma_ned_m, Eigen::Vector3d(0.010, 0.010, 0.020));
  EXPECT_FALSE(m.quiet_deadline_ns());
  const NavInputStats& st = m.stats();
  EXPECT_EQ(st.lines, 7u);
  EXPECT_EQ(st.events, 2u);
  EXPECT_EQ(st.malformed, 0u);
}

TEST(GpsdInput, MapsModeAndStatusToFixQuality) {
  const std::vector<std::tuple<int, int, FixQuality>> table = {
      {3, 0, FixQuality::kSingle},        {3, 1, FixQuality::kSingle},   {3, 2, FixQuality::kDgps},
      {3, 3, FixQuality::kRtkFixed},      {3, 4, FixQuality::kRtkFloat}, {3, 5, FixQuality::kDeadReckoning},
      {3, 6, FixQuality::kDeadReckoning}, {3, 7, FixQuality::kInvalid},  {3, 8, FixQuality::kInvalid},
      {3, 9, FixQuality::kPps},           {2, 3, FixQuality::kRtkFixed}, {1, 3, FixQuality::kInvalid},
  };
  GpsdReportMerger m("gpsd://test", {});
  int second = 0;
  for (const auto& [mode, status, quality] : table) {
    char json[512];
    std::snprintf(
        json, sizeof json,
        R"({"class":"TPV","device":"d","mode":%d,"status":%d,"time":"2024-06-01T12:00:%02d.000Z","lat":10.5,"lon":-20.25,"altMSL":100.0,"geoidSep":-30.5})",
        mode, status, second++);
    m.push_report(json, second);
  }
  m.flush();
  const std::vector<NavEvent> ev = pop_all(m);
  ASSERT_EQ(ev.size(), table.size());
  for (std::size_t i = 0; i < ev.size(); ++i) {
    const auto& [mode, status, quality] = table[i];
    const GpsFix& f = ev[i].gps();
    EXPECT_EQ(f.quality, quality) << "mode " << mode << " status " << status;
    EXPECT_EQ(f.t_ns, kNoon + static_cast<TimestampNs>(i) * kNsPerSecond);
    if (mode >= 2) {
      EXPECT_DOUBLE_EQ(rad_to_deg(f.antenna.lat_rad), 10.5);
      EXPECT_DOUBLE_EQ(rad_to_deg(f.antenna.lon_rad), -20.25);
    } else {
      EXPECT_TRUE(std::isnan(f.antenna.lat_rad));
    }
    if (mode == 3) {
      EXPECT_DOUBLE_EQ(f.antenna.h_m, 100.0 - 30.5);  // no altHAE: altMSL + geoidSep
    } else {
      EXPECT_TRUE(std::isnan(f.antenna.h_m)) << "a 2D fix has no height";
    }
    EXPECT_DOUBLE_EQ(f.geoid_separation_m, -30.5);
  }
}

TEST(GpsdInput, DeviceFilterSkyLeapSecondsVelocityAndBadReports) {
  GpsdOptions o;
  o.device = "/dev/ttyACM0";
  o.leap_seconds = 17;
  GpsdReportMerger m("gpsd://test?device=/dev/ttyACM0", o);
  m.push_report(
      R"({"class":"SKY","device":"/dev/ttyACM0","hdop":0.7,"satellites":[{"PRN":1,"el":10,"az":20,"ss":30,"used":true},{"PRN":2,"el":10,"az":20,"ss":30,"used":true},{"PRN":3,"el":10,"az":20,"ss":30,"used":false}]})",
      1);
  m.push_report(
      R"({"class":"TPV","device":"/dev/ttyUSB1","mode":3,"time":"2024-06-01T11:00:00.000Z","lat":1,"lon":2,"altHAE":3})",
      2);  // another device
  m.push_report(
      R"({"class":"TPV","device":"/dev/ttyACM0","mode":3,"time":"2024-06-01T12:00:00.000Z","lat":1,"lon":2,"altHAE":3,"velN":1.5,"velE":-2.25,"velD":0.125})",
      3);
  m.push_report(R"({"class":"TPV","device":"/dev/ttyACM0","mode":3,"lat":1,"lon":2,"altHAE":3})",
                4);  // no time yet
  m.push_report("not json at all", 5);
  m.push_report(R"({"class":"TPV","device":"/dev/ttyACM0",)", 6);
  m.push_report(R"({"class":"TPV","device":"/dev/ttyACM0","mode":"three"})", 7);
  m.push_report(R"({"class":"ERROR","message":"Can't open /dev/ttyACM0."})", 8);
  m.push_report(
      R"({"class":"TPV","device":"/dev/ttyACM0","mode":3,"time":"2024-06-01T12:00:01.000Z","leapseconds":18,"lat":1,"lon":2,"altHAE":3})",
      9);
  m.push_report(
      R"({"class":"TPV","device":"/dev/ttyACM0","mode":3,"time":"2024-06-01T11:59:59.000Z","lat":1,"lon":2,"altHAE":3})",
      10);  // older
  m.flush();
  const std::vector<NavEvent> ev = pop_all(m);
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0].gps().t_ns, kNoon - kNsPerSecond);  // 17 leap seconds, as configured
  EXPECT_EQ(ev[0].gps().satellites, 2);
  EXPECT_DOUBLE_EQ(ev[0].gps().hdop, 0.7);
  ASSERT_TRUE(ev[0].velocity_ned_mps);
  EXPECT_EQ(*ev[0].velocity_ned_mps, Eigen::Vector3d(1.5, -2.25, 0.125));
  EXPECT_EQ(ev[1].gps().t_ns, kNoon + kNsPerSecond);  // gpsd's leap seconds win once it reports them
  const NavInputStats& st = m.stats();
  EXPECT_EQ(st.malformed, 3u);     // not JSON, cut short, a TPV without a readable mode
  EXPECT_EQ(st.out_of_order, 1u);  // the older fix
  EXPECT_EQ(st.dropped, 2u);       // the older fix and the TPV without time
  std::string all;
  for (const std::string& e : st.last_errors) all += e + "\n";
  EXPECT_TRUE(contains(all, "gpsd says: Can't open /dev/ttyACM0.")) << all;
  EXPECT_TRUE(contains(all, "a TPV without time")) << all;
  EXPECT_TRUE(contains(all, "report 5: expected a JSON object")) << all;
}

// libgps 3.22 never returns from gps_unpack() on the 16 bytes {s"class":"TPV"}: the merger must
// reject it (and any report that is not a JSON object with a string "class") before libgps. Run in
// a thread so that a regression fails the test instead of hanging it.
// Without gpsd's leapseconds and none configured, a report's UTC date picks GPS - UTC from the
// table: 17 s in 2016, 18 s in 2024.
TEST(GpsdInput, LeapSecondsFromTheTableByDate) {
  GpsdReportMerger m("gpsd://test", GpsdOptions{});
  m.push_report(R"({"class":"TPV","mode":3,"time":"2016-06-01T12:00:00.000Z","lat":1,"lon":2,"altHAE":3})", 1);
  m.push_report(R"({"class":"TPV","mode":3,"time":"2024-06-01T12:00:00.000Z","lat":1,"lon":2,"altHAE":3})", 2);
  m.flush();
  const std::vector<NavEvent> ev = pop_all(m);
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0].gps().t_ns, gps_ns_from_utc({2016, 6, 1}, 12 * 3600 * kNsPerSecond, 17));
  EXPECT_EQ(ev[1].gps().t_ns, kNoon);
}

TEST(GpsdInput, MalformedJsonNeverReachesLibgps) {
  auto m = std::make_shared<GpsdReportMerger>("gpsd://test", GpsdOptions{});
  auto done = std::make_shared<std::promise<void>>();
  std::future<void> finished = done->get_future();
  std::thread([m, done] {
    m->push_report(R"({s"class":"TPV"})", 1);
    m->push_report(R"({"class":["TPV"],"mode":3})", 2);           // class not a string
    m->push_report(R"(["class","TPV"])", 3);                      // not an object
    m->push_report(R"({"class":"TPV","mode":3}})", 4);            // trailing garbage
    m->push_report(R"({"klass":"TPV","x":{"class":"TPV"}})", 5);  // "class" only nested
    // A repeated key: libgps loops forever on this one (found by fuzz/fuzz_gpsd).
    m->push_report(R"({"class":"TPV","class":"VERSION"})", 6);
    m->push_report(R"({"class":"TPV","mode":3,"x":{"a":1,"a":2}})", 7);  // repeated in a nested object
    done->set_value();
  }).detach();
  ASSERT_EQ(finished.wait_for(10s), std::future_status::ready) << "push_report() hangs (libgps gps_unpack)";
  const NavInputStats& st = m->stats();
  EXPECT_EQ(st.malformed, 7u);
  std::string all;
  for (const std::string& e : st.last_errors) all += e + "\n";
  EXPECT_TRUE(contains(
      all,
      R"(expected a JSON object with a string "class" and no key repeated, got '{"class":"TPV","class":"VERSION"}')"))
      << all;
  m->flush();
  EXPECT_TRUE(pop_all(*m).empty());
}

// Times in years whose ns overflow int64 (9999) are dropped with a note, not wrapped around.
TEST(GpsdInput, TimesOutsideTheSupportedYearsAreDropped) {
  GpsdReportMerger m("gpsd://test", GpsdOptions{});
  m.push_report(R"({"class":"TPV","mode":3,"time":"9999-12-31T23:59:59.000Z","lat":1,"lon":2,"altHAE":3})",
                1);
  m.push_report(R"({"class":"GST","time":"9999-12-31T23:59:59.000Z","lat":0.1,"lon":0.1,"alt":0.2})", 2);
  m.push_report(R"({"class":"ATT","device":"x",,"time":"9999-12-31T23:59:59.000Z""heading":90.0})", 3);
  m.push_report(R"({"class":"ATT","time":"9999-12-31T23:59:59.000Z","heading":90.0})", 4);
  m.push_report(R"({"class":"TPV","mode":3,"time":"2024-06-01T12:00:00.000Z","lat":1,"lon":2,"altHAE":3})",
                5);
  m.flush();
  const std::vector<NavEvent> ev = pop_all(m);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].gps().t_ns, kNoon);
  EXPECT_FALSE(ev[0].gps().heading_rad);  // the 9999 ATT did not land in the 2024 epoch
  const NavInputStats& st = m.stats();
  EXPECT_GE(st.malformed, 3u);  // the TPV and both ATTs (libgps may not read the GST's time)
  std::string all;
  for (const std::string& e : st.last_errors) all += e + "\n";
  EXPECT_TRUE(contains(all, "report 1: a TPV time outside the years 1980..2099")) << all;
  EXPECT_TRUE(contains(all, "report 3: a ATT time outside the years 1980..2099")) << all;
}

// The live client reads gpsd's socket itself and checks each report before libgps: a gpsd peer
// that sends the report libgps hangs on must not stall the input.
TEST(GpsdInput, ClientSurvivesAReportThatHangsLibgps) {
  const int srv = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(srv, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  ASSERT_EQ(::bind(srv, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(srv, 4), 0);
  ASSERT_EQ(getsockname(srv, reinterpret_cast<sockaddr*>(&a), &len), 0);
  const std::uint16_t port = ntohs(a.sin_port);
  // A fake gpsd: the probe connection sends nothing and closes; the client's sends ?WATCH, and
  // gets the evil report, then a good epoch.
  std::thread server([srv] {
    for (int i = 0; i < 4; ++i) {
      const int c = ::accept(srv, nullptr, nullptr);
      if (c < 0) return;
      char buf[512];
      const ssize_t n = ::recv(c, buf, sizeof buf, 0);
      if (n > 0) {
        const std::string reports =
            "{\"class\":\"VERSION\",\"release\":\"3.22\",\"proto_major\":3,\"proto_minor\":14}\r\n"
            "{s\"class\":\"TPV\"}\r\n"
            "{\"class\":\"TPV\",\"mode\":3,\"time\":\"2024-06-01T12:00:00.000Z\",\"lat\":1,\"lon\":2,"
            "\"altHAE\":3}\r\n";
        (void)!::send(c, reports.data(), reports.size(), MSG_NOSIGNAL);
        std::this_thread::sleep_for(300ms);
        ::close(c);
        return;
      }
      ::close(c);
    }
  });
  GpsdOptions o;
  o.host = "127.0.0.1";
  o.port = port;
  auto in = GpsdInput::open(o);
  if (!in) {
    ::shutdown(srv, SHUT_RDWR);  // ends the server's accept()
    server.join();
    ::close(srv);
    FAIL() << in.error().message;
  }
  auto done = std::make_shared<std::promise<std::vector<NavEvent>>>();
  std::future<std::vector<NavEvent>> result = done->get_future();
  GpsdInput* input = in->get();
  std::thread reader([input, done] {
    std::vector<NavEvent> got;
    for (int i = 0; i < 50; ++i) {
      NavEvent e;
      auto r = input->read(e, 100ms);
      if (!r || *r == NavReadStatus::kEnd) break;
      if (*r == NavReadStatus::kEvent) got.push_back(e);
    }
    done->set_value(got);
  });
  if (result.wait_for(20s) != std::future_status::ready) {
    reader.detach();  // stuck in libgps: fail rather than hang
    server.join();
    ::close(srv);
    (void)in->release();  // the stuck thread still uses it
    FAIL() << "GpsdInput::read() hangs on a malformed report";
  }
  reader.join();
  server.join();
  ::close(srv);
  const std::vector<NavEvent> got = result.get();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].gps().t_ns, kNoon);
  EXPECT_EQ((*in)->stats().malformed, 1u);
}

// ---- A real gpsd, fed by gpsfake --------------------------------------------------------------

std::string find_program(const std::string& name) {
  for (const char* dir : {"/usr/bin", "/usr/sbin", "/usr/local/bin", "/usr/local/sbin", "/bin", "/sbin"}) {
    const std::string p = std::string(dir) + "/" + name;
    if (access(p.c_str(), X_OK) == 0) return p;
  }
  return {};
}

std::uint16_t free_tcp_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    ::close(fd);
    return 0;
  }
  ::close(fd);
  return ntohs(a.sin_port);
}

// gpsfake (and the gpsd it starts) in a process group of their own, stopped with the group.
class Gpsfake {
 public:
  Gpsfake(const std::string& gpsfake, const std::string& log, std::uint16_t port, const std::string& output,
          double cycle_s)
      : output_(output) {
    const std::string port_text = std::to_string(port);
    char cycle[32];
    std::snprintf(cycle, sizeof cycle, "%.3f", cycle_s);
    pid_ = fork();
    if (pid_ == 0) {
      setpgid(0, 0);
      const int fd = ::open(output.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        dup2(fd, 1);
        dup2(fd, 2);
      }
      // gpsfake runs the gpsd it finds on PATH (or in GPSD_HOME): make sure /usr/sbin is there.
      const char* path = std::getenv("PATH");
      setenv("PATH", (std::string(path ? path : "/usr/bin:/bin") + ":/usr/sbin:/sbin").c_str(), 1);
      // gpsd's control socket goes to $TMPDIR/gpsfake-PID.sock: keep it with the test's output.
      setenv("TMPDIR", std::filesystem::path(output).parent_path().c_str(), 1);
      // -1: play the log once; -c: seconds between sentences; -P: gpsd's port; -q: quiet.
      execl(gpsfake.c_str(), gpsfake.c_str(), "-1", "-q", "-c", cycle, "-P", port_text.c_str(), log.c_str(),
            static_cast<char*>(nullptr));
      _exit(127);
    }
    if (pid_ > 0) setpgid(pid_, pid_);  // also from here, whichever runs first
  }
  ~Gpsfake() { stop(); }
  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return false;
    }
    return true;
  }
  void stop() {
    if (pid_ <= 0) return;
    kill(-pid_, SIGTERM);
    for (int i = 0; i < 300; ++i) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
        kill(-pid_, SIGKILL);  // gpsd, if it outlived gpsfake
        pid_ = -1;
        return;
      }
      std::this_thread::sleep_for(10ms);
    }
    kill(-pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  std::string output() const {
    std::ifstream in(output_);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

 private:
  std::string output_;
  pid_t pid_ = -1;
};

TEST(GpsdInput, FixesFromGpsdFedByGpsfakeMatchTheLog) {
  const std::string gpsfake = find_program("gpsfake");
  if (gpsfake.empty() || find_program("gpsd").empty()) {
    GTEST_SKIP() << "gpsfake or gpsd not installed (Debian: gpsd, gpsd-clients)";
  }
  if (std::system("/usr/bin/python3 -c 'import gps.fake' > /dev/null 2>&1") != 0) {
    GTEST_SKIP() << "gpsfake needs the python3-gps module (Debian: python3-gps)";
  }
  // The simulator's tanker log (GGA, GST, RMC, VTG, HDT, ZDA each epoch), with fix qualities
  // changing along the way so that their mapping shows.
  sim::Scenario s = *sim::builtin_scenario("demo");
  s.duration_s = 8.0;
  const sim::Flight flight = *sim::Flight::create(s);
  std::vector<GpsFix> fixes = sim::simulate_sensors(s, flight).tanker_gps;
  ASSERT_EQ(fixes.size(), 81u);
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    if (i >= 45 && i < 52) fixes[i].quality = FixQuality::kRtkFloat;
    if (i >= 52 && i < 58) fixes[i].quality = FixQuality::kDgps;
    if (i >= 58 && i < 63) fixes[i].quality = FixQuality::kSingle;
    if (i >= 63 && i < 66) fixes[i].quality = FixQuality::kDeadReckoning;
  }
  const std::string dir = test::output_dir("gpsd_input_gpsfake");
  const std::string log = dir + "/tanker.nmea";
  ASSERT_TRUE(write_nmea_file(log, fixes));  // no arrival prefix: what a receiver sends
  const auto oracle = read_nmea_file(log);
  ASSERT_TRUE(oracle) << oracle.error().message;
  std::map<TimestampNs, GpsFix> by_time;
  for (const GpsFix& f : oracle->fixes) by_time[f.t_ns] = f;

  const std::uint16_t port = free_tcp_port();
  ASSERT_NE(port, 0);
  Gpsfake fake(gpsfake, log, port, dir + "/gpsfake.out", 0.01);
  // gpsd needs a moment to listen: retry the connection.
  std::unique_ptr<NavInput> in;
  const std::string uri = "gpsd://127.0.0.1:" + std::to_string(port) + "?quiet_ms=300";
  for (int attempt = 0; attempt < 200 && !in; ++attempt) {
    auto opened = open_nav_input(uri);
    if (opened) {
      in = std::move(*opened);
    } else {
      ASSERT_TRUE(fake.running()) << "gpsfake stopped: " << fake.output();
      std::this_thread::sleep_for(50ms);
    }
  }
  ASSERT_TRUE(in) << "gpsd did not accept a connection on port " << port << ": " << fake.output();
  EXPECT_EQ(in->uri(), uri);

  std::vector<NavEvent> got;
  const TimestampNs start = monotonic_now_ns();
  while (monotonic_now_ns() - start < 30 * kNsPerSecond) {
    NavEvent e;
    auto r = in->read(e, 500ms);
    ASSERT_TRUE(r) << r.error().message;
    if (*r == NavReadStatus::kEnd) break;
    if (*r == NavReadStatus::kEvent) {
      got.push_back(e);
      if (e.gps().t_ns == oracle->fixes.back().t_ns) break;  // the log's last epoch
    }
  }
  fake.stop();

  // gpsfake starts playing before the client connects: the first epochs are lost, the rest arrive.
  ASSERT_GE(got.size(), 40u) << fake.output();
  ASSERT_EQ(got.back().gps().t_ns, oracle->fixes.back().t_ns) << "the last epoch did not arrive";
  std::map<FixQuality, int> qualities;
  TimestampNs prev_arrival = start;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const GpsFix& g = got[i].gps();
    const auto it = by_time.find(g.t_ns);
    ASSERT_NE(it, by_time.end()) << "a fix at a time the log does not have: " << g.t_ns;
    const GpsFix& o = it->second;
    EXPECT_GE(g.arrival_ns, prev_arrival) << i;
    prev_arrival = g.arrival_ns;
    EXPECT_EQ(g.quality, o.quality) << i;
    ++qualities[g.quality];
    // The first epoch gpsd reports may be partial (its first sentences went by before the client).
    const bool partial = i == 0;
    if (!partial) {
      EXPECT_NEAR(rad_to_deg(g.antenna.lat_rad), rad_to_deg(o.antenna.lat_rad), 0.6e-9) << i;
      EXPECT_NEAR(rad_to_deg(g.antenna.lon_rad), rad_to_deg(o.antenna.lon_rad), 0.6e-9) << i;
      EXPECT_NEAR(g.antenna.h_m, o.antenna.h_m, 0.6e-4) << i;
      EXPECT_LT((ecef_from_geodetic(g.antenna) - ecef_from_geodetic(o.antenna)).norm(), 0.2e-3) << i;
      EXPECT_NEAR(g.geoid_separation_m, o.geoid_separation_m, 0.6e-3) << i;
      ASSERT_TRUE(g.ground_speed_mps && g.course_rad) << i;
      EXPECT_NEAR(*g.ground_speed_mps, *o.ground_speed_mps, 0.6e-3) << i;
      EXPECT_NEAR(rad_to_deg(*g.course_rad), rad_to_deg(*o.course_rad), 0.6e-4) << i;
      ASSERT_TRUE(g.sigma_ned_m) << i;
      EXPECT_LT((*g.sigma_ned_m - *o.sigma_ned_m).cwiseAbs().maxCoeff(), 0.6e-3) << i;
      ASSERT_TRUE(g.heading_rad) << i;
      EXPECT_NEAR(rad_to_deg(*g.heading_rad), rad_to_deg(*o.heading_rad), 0.6e-3) << i;
    }
  }
  EXPECT_EQ(qualities[FixQuality::kRtkFloat], 7);
  EXPECT_EQ(qualities[FixQuality::kDgps], 6);
  EXPECT_EQ(qualities[FixQuality::kSingle], 5);
  EXPECT_EQ(qualities[FixQuality::kDeadReckoning], 3);
  EXPECT_GT(qualities[FixQuality::kRtkFixed], 20);
  const NavInputStats st = in->stats();
  EXPECT_EQ(st.events, got.size());
  EXPECT_EQ(st.malformed, 0u);
  EXPECT_GT(st.lines, 2 * got.size());  // GST, TPV and ATT per epoch, and the session's reports
}

}  // namespace
}  // namespace augrig::nav
