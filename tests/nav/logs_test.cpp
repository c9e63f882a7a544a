// Tests for nav/logs.hpp: IMU and nav-solution CSV round trips (bit-exact), header and row errors
// naming file:line and column, out-of-order / duplicate / gap accounting.
#include "nav/logs.hpp"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/test_support.hpp"

namespace augrig::nav {
namespace {

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// Deterministic doubles spanning many exponents, with awkward values mixed in.
class Doubles {
 public:
  double next() {
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    const std::uint64_t r = state_ >> 11;
    switch (r % 8) {
      case 0:
        return -0.0;
      case 1:
        return std::numeric_limits<double>::denorm_min() * static_cast<double>(r % 1000 + 1);
      case 2:
        return 0.1 * static_cast<double>(r % 7);
      default: {
        const double mantissa = static_cast<double>(r) / static_cast<double>(1ULL << 53) - 0.5;
        return std::ldexp(mantissa, static_cast<int>(r % 80) - 40);
      }
    }
  }

 private:
  std::uint64_t state_ = 42;
};

std::string all_messages(const LogIssues& issues) {
  std::string s;
  for (const std::string& m : issues.messages) s += m + "\n";
  return s;
}

bool has_message(const LogIssues& issues, const std::string& start, const std::string& part) {
  for (const std::string& m : issues.messages) {
    if (m.rfind(start, 0) == 0 && m.find(part) != std::string::npos) return true;
  }
  return false;
}

Expected<ImuLog> imu_from(const std::string& text, const std::string& name = "imu.csv") {
  std::istringstream in(text);
  return parse_imu_csv(in, name);
}

Expected<NavSolutionLog> nav_from(const std::string& text, const std::string& name = "nav.csv") {
  std::istringstream in(text);
  return parse_nav_solution_csv(in, name);
}

const char* kImuHeader = "t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n";

// ------------------------------------------------------------------------------------------
// IMU

std::vector<ImuSample> make_imu(std::size_t n, bool arrival) {
  Doubles d;
  std::vector<ImuSample> v;
  for (std::size_t i = 0; i < n; ++i) {
    ImuSample s;
    s.t_ns = 1'300'000'000'000'000'000LL + static_cast<TimestampNs>(i) * 2'500'000;
    s.dt_s = 0.0025 + 1e-9 * static_cast<double>(i % 3);
    for (int k = 0; k < 3; ++k) {
      s.dtheta_rad[k] = d.next();
      s.dv_mps[k] = d.next();
    }
    s.arrival_ns = arrival ? 5'000'000'000 + static_cast<TimestampNs>(i) * 2'500'123 : 0;
    v.push_back(s);
  }
  return v;
}

TEST(ImuCsv, RoundTripIsBitExact) {
  for (bool arrival : {false, true}) {
    const std::vector<ImuSample> in = make_imu(500, arrival);
    std::ostringstream out;
    CsvWriteOptions o;
    o.clock = ClockDomain::kHostMonotonic;
    o.metadata["imu"] = "ADIS16505";
    ASSERT_TRUE(write_imu_csv(out, in, o));
    const std::string text = out.str();
    EXPECT_EQ(text.find("arrival_ns") != std::string::npos, arrival);
    EXPECT_NE(text.find("# clock: host_monotonic\n"), std::string::npos);
    const auto log = imu_from(text);
    ASSERT_TRUE(log) << log.error().message;
    EXPECT_EQ(log->clock, ClockDomain::kHostMonotonic);
    EXPECT_EQ(log->metadata.at("imu"), "ADIS16505");
    EXPECT_TRUE(log->issues.messages.empty()) << all_messages(log->issues);
    ASSERT_EQ(log->samples.size(), in.size());
    for (std::size_t i = 0; i < in.size(); ++i) {
      const ImuSample& a = in[i];
      const ImuSample& b = log->samples[i];
      ASSERT_EQ(b.t_ns, a.t_ns);
      ASSERT_EQ(b.arrival_ns, a.arrival_ns);
      ASSERT_TRUE(same_bits(b.dt_s, a.dt_s)) << i;
      for (int k = 0; k < 3; ++k) {
        ASSERT_TRUE(same_bits(b.dtheta_rad[k], a.dtheta_rad[k])) << i << " " << a.dtheta_rad[k];
        ASSERT_TRUE(same_bits(b.dv_mps[k], a.dv_mps[k])) << i << " " << a.dv_mps[k];
      }
    }
  }
}

TEST(ImuCsv, FileRoundTripAndDefaultClock) {
  const std::string path = test::output_dir("imu_csv") + "/imu.csv";
  const std::vector<ImuSample> in = make_imu(20, false);
  ASSERT_TRUE(write_imu_csv(path, in));
  const auto log = read_imu_csv(path);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->clock, ClockDomain::kGps);
  ASSERT_EQ(log->samples.size(), 20u);
  EXPECT_TRUE(same_bits(log->samples[7].dv_mps.y(), in[7].dv_mps.y()));
  // A file without any clock comment is GPS time too.
  const auto bare = imu_from(std::string(kImuHeader) + "1,0.01,0,0,0,0,0,0\n");
  ASSERT_TRUE(bare) << bare.error().message;
  EXPECT_EQ(bare->clock, ClockDomain::kGps);
}

TEST(ImuCsv, ColumnsInAnyOrderWithSpacesAndComments) {
  const auto log = imu_from(
      "# clock: sim\n# just a note, not metadata\n\n"
      "dv_z_mps, dv_y_mps, dv_x_mps, dtheta_z_rad, dtheta_y_rad, dtheta_x_rad, dt_s, t_ns, arrival_ns\r\n"
      "6, 5, 4, 3, 2, 1, 0.01, 10000000, 77\r\n"
      "# a comment between rows\n"
      "-6,-5,-4,-3,-2,-1,1e-2,20000000,78\n");
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->clock, ClockDomain::kSim);
  ASSERT_EQ(log->samples.size(), 2u);
  EXPECT_EQ(log->samples[0].dtheta_rad, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(log->samples[0].dv_mps, Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(log->samples[1].dv_mps, Eigen::Vector3d(-4, -5, -6));
  EXPECT_EQ(log->samples[1].arrival_ns, 78);
  EXPECT_EQ(log->issues.gaps, 0u);
}

TEST(ImuCsv, OutOfOrderDuplicatesAndGaps) {
  const auto log = imu_from(std::string(kImuHeader) +
                            "0,0.01,0,0,0,0,0,0\n"         // 2
                            "10000000,0.01,0,0,0,0,0,0\n"  // 3
                            "20000000,0.01,0,0,0,0,0,0\n"  // 4
                            "15000000,0.01,0,0,0,0,0,0\n"  // 5 out of order
                            "20000000,0.01,0,0,0,0,0,0\n"  // 6 duplicate
                            "40000000,0.01,0,0,0,0,0,0\n"  // 7 gap: 20 ms but dt 10 ms
                            "50000000,0.01,0,0,0,0,0,0\n"  // 8
                            "62000000,0.01,0,0,0,0,0,0\n"  // 9 jitter, no gap
  );
  ASSERT_TRUE(log) << log.error().message;
  const LogIssues& is = log->issues;
  EXPECT_EQ(is.out_of_order, 1u);
  EXPECT_EQ(is.duplicates, 1u);
  EXPECT_EQ(is.gaps, 1u);
  EXPECT_TRUE(has_message(is, "imu.csv:5: ", "older")) << all_messages(is);
  EXPECT_TRUE(has_message(is, "imu.csv:6: ", "repeats")) << all_messages(is);
  EXPECT_TRUE(has_message(is, "imu.csv:7: ", "gap")) << all_messages(is);
  ASSERT_EQ(log->samples.size(), 6u);
  for (std::size_t i = 1; i < log->samples.size(); ++i)
    EXPECT_GT(log->samples[i].t_ns, log->samples[i - 1].t_ns);
}

TEST(ImuCsv, BadFilesNameFileLineAndColumn) {
  const std::string good = "1,0.01,0,0,0,0,0,0\n";
  const struct {
    std::string text;
    std::vector<std::string> parts;
  } cases[] = {
      {std::string(kImuHeader) + good + "2,0.01,0,0,0,abc,0,0\n",
       {"imu.csv:3: ", "column 'dv_x_mps'", "'abc'"}},
      {std::string(kImuHeader) + good + good + "3,0.01,0,0,0,0,0\n",
       {"imu.csv:4: ", "expected 8 fields", "got 7"}},
      {std::string(kImuHeader) + "3,0.01,0,0,0,0,0,0,9\n", {"imu.csv:2: ", "expected 8 fields", "got 9"}},
      {std::string(kImuHeader) + "2,0.01,0,nan,0,0,0,0\n",
       {"imu.csv:2: ", "column 'dtheta_y_rad'", "finite"}},
      {std::string(kImuHeader) + "2,0.01,0,0,inf,0,0,0\n", {"imu.csv:2: ", "column 'dtheta_z_rad'"}},
      {std::string(kImuHeader) + "2,0.01,0,0,0,0,0,\n", {"imu.csv:2: ", "column 'dv_z_mps'", "''"}},
      {std::string(kImuHeader) + "2.5,0.01,0,0,0,0,0,0\n", {"imu.csv:2: ", "column 't_ns'", "integer"}},
      {std::string(kImuHeader) + "2,0,0,0,0,0,0,0\n", {"imu.csv:2: ", "column 'dt_s'", "> 0"}},
      {std::string(kImuHeader) + "2,1e999,0,0,0,0,0,0\n", {"imu.csv:2: ", "column 'dt_s'"}},
      {"# c\nt_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps\n" + good,
       {"imu.csv:2: ", "missing column 'dv_z_mps'"}},
      {"t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps,temp_c\n" + good,
       {"imu.csv:1: ", "unknown column 'temp_c'"}},
      {"t_ns,t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n" + good,
       {"imu.csv:1: ", "'t_ns' appears twice"}},
      {good, {"imu.csv:1: ", "unknown column '1'"}},
      {"# clock: gps\n\n", {"imu.csv: ", "expected the header line"}},
      {"", {"imu.csv: ", "expected the header line"}},
      {"# clock: utc\n" + std::string(kImuHeader), {"imu.csv:1: ", "clock", "'utc'"}},
  };
  for (const auto& c : cases) {
    const auto log = imu_from(c.text);
    ASSERT_FALSE(log) << c.text;
    const std::string& m = log.error().message;
    EXPECT_EQ(m.rfind("nav::parse_imu_csv(): ", 0), 0u) << m;
    for (const std::string& p : c.parts)
      EXPECT_NE(m.find(p), std::string::npos) << "'" << p << "' not in: " << m;
  }
  // The file reader names the path and its own function.
  const std::string path = test::output_dir("imu_csv_bad") + "/bad.csv";
  std::ofstream(path) << kImuHeader << good << "2,0.01,0,0,0,0,x,0\n";
  const auto log = read_imu_csv(path);
  ASSERT_FALSE(log);
  EXPECT_EQ(log.error().message.rfind("nav::read_imu_csv(): " + path + ":3: column 'dv_y_mps'", 0), 0u)
      << log.error().message;
  const auto missing = read_imu_csv("/nonexistent/imu.csv");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("/nonexistent/imu.csv"), std::string::npos);
}

// Times whose differences would overflow int64 (a span beyond 292 years) or that would overflow
// once a clock offset is added are rejected by line and column, as is an absurd dt_s.
TEST(ImuCsv, TimesOutsideTheSupportedRangeAreRejected) {
  const struct {
    std::string text;
    std::vector<std::string> parts;
  } cases[] = {
      {std::string(kImuHeader) +
           "-9223372036854775807,0.01,0,0,0,0,0,0\n9223372036854775807,0.01,0,0,0,0,0,0\n",
       {"imu.csv:2: ", "column 't_ns'", "expected a time in -4e18..4e18 ns"}},
      {std::string(kImuHeader) + "1,0.01,0,0,0,0,0,0\n4000000000000000001,0.01,0,0,0,0,0,0\n",
       {"imu.csv:3: ", "column 't_ns'", "4000000000000000001"}},
      {"t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps,arrival_ns\n"
       "1,0.01,0,0,0,0,0,0,-9223372036854775808\n",
       {"imu.csv:2: ", "column 'arrival_ns'", "expected a time in"}},
      {std::string(kImuHeader) + "1,1e300,0,0,0,0,0,0\n", {"imu.csv:2: ", "column 'dt_s'", "<= 60 s"}},
  };
  for (const auto& c : cases) {
    const auto log = imu_from(c.text);
    ASSERT_FALSE(log) << c.text;
    for (const std::string& p : c.parts)
      EXPECT_NE(log.error().message.find(p), std::string::npos)
          << "'" << p << "' not in: " << log.error().message;
  }
  // The bounds themselves are accepted, and their difference is computed without overflow.
  const auto ok = imu_from(std::string(kImuHeader) + "-4000000000000000000,0.01,0,0,0,0,0,0\n" +
                           "4000000000000000000,0.01,0,0,0,0,0,0\n");
  ASSERT_TRUE(ok) << ok.error().message;
  EXPECT_EQ(ok->issues.gaps, 1u);
  // The other CSV logs bound their times the same way.
  const auto nav = nav_from(
      "t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg\n"
      "-9000000000000000000,0,0,0,0,0,0,0,0,0\n");
  ASSERT_FALSE(nav);
  EXPECT_NE(nav.error().message.find("nav.csv:2: column 't_ns': expected a time in"), std::string::npos)
      << nav.error().message;
  std::istringstream frames("sequence,camera,t_ns,file\n0,0,9000000000000000000,a.png\n");
  const auto index = parse_frame_index_csv(frames, "frames.csv");
  ASSERT_FALSE(index);
  EXPECT_NE(index.error().message.find("frames.csv:2: column 't_ns'"), std::string::npos)
      << index.error().message;
}

// A directory where the log should be is named as such (it used to read as "imu.csv:0: read error").
TEST(ImuCsv, DirectoryIsNotAFile) {
  const std::string dir = test::output_dir("imu_csv_dir") + "/imu.csv";
  std::filesystem::create_directories(dir);
  const auto log = read_imu_csv(dir);
  ASSERT_FALSE(log);
  EXPECT_EQ(log.error().message, "nav::read_imu_csv(): " + dir + ": is a directory, expected a file");
  const auto nav = read_nav_solution_csv(dir);
  ASSERT_FALSE(nav);
  EXPECT_NE(nav.error().message.find("is a directory, expected a file"), std::string::npos);
  const auto frames = read_frame_index_csv(dir);
  ASSERT_FALSE(frames);
  EXPECT_NE(frames.error().message.find("is a directory, expected a file"), std::string::npos);
}

TEST(ImuCsv, WriterRejectsNonFiniteValues) {
  std::vector<ImuSample> v = make_imu(3, false);
  v[1].dv_mps.z() = std::numeric_limits<double>::quiet_NaN();
  std::ostringstream out;
  const Status s = write_imu_csv(out, v);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("sample 1"), std::string::npos) << s.error().message;
}

// ------------------------------------------------------------------------------------------
// Nav solution

std::vector<NavSolutionRow> make_nav(std::size_t n) {
  Doubles d;
  std::vector<NavSolutionRow> v;
  for (std::size_t i = 0; i < n; ++i) {
    NavSolutionRow r;
    r.t_ns = 1'400'000'000'000'000'000LL + static_cast<TimestampNs>(i) * 10'000'000;
    r.lat_deg = 51.4778 + 1e-3 * std::fmod(d.next(), 1.0);
    r.lon_deg = -0.0014 + 1e-3 * std::fmod(d.next(), 1.0);
    r.h_m = 3000.123456789 + std::fmod(d.next(), 100.0);
    r.vn_mps = 120 + d.next();
    r.ve_mps = d.next();
    r.vd_mps = d.next();
    r.yaw_deg = -179.999 + 0.3 * static_cast<double>(i);
    r.pitch_deg = d.next();
    r.roll_deg = d.next();
    if (i % 4 != 0) {  // every 4th row has unknown sigmas
      r.sigma_n_m = std::abs(d.next());
      r.sigma_e_m = std::abs(d.next());
      r.sigma_d_m = std::abs(d.next());
      r.sigma_yaw_deg = std::abs(d.next());
      r.sigma_pitch_deg = std::abs(d.next());
      r.sigma_roll_deg = 0.5;
    }
    v.push_back(r);
  }
  return v;
}

TEST(NavSolutionCsv, RoundTripIsBitExact) {
  const std::vector<NavSolutionRow> in = make_nav(300);
  const std::string path = test::output_dir("nav_csv") + "/nav.csv";
  ASSERT_TRUE(write_nav_solution_csv(path, in));
  const auto log = read_nav_solution_csv(path);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_TRUE(log->issues.messages.empty()) << all_messages(log->issues);
  ASSERT_EQ(log->rows.size(), in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    const NavSolutionRow& a = in[i];
    const NavSolutionRow& b = log->rows[i];
    ASSERT_EQ(b.t_ns, a.t_ns);
    const double av[] = {a.lat_deg,   a.lon_deg,   a.h_m,           a.vn_mps,          a.ve_mps,
                         a.vd_mps,    a.yaw_deg,   a.pitch_deg,     a.roll_deg,        a.sigma_n_m,
                         a.sigma_e_m, a.sigma_d_m, a.sigma_yaw_deg, a.sigma_pitch_deg, a.sigma_roll_deg};
    const double bv[] = {b.lat_deg,   b.lon_deg,   b.h_m,           b.vn_mps,          b.ve_mps,
                         b.vd_mps,    b.yaw_deg,   b.pitch_deg,     b.roll_deg,        b.sigma_n_m,
                         b.sigma_e_m, b.sigma_d_m, b.sigma_yaw_deg, b.sigma_pitch_deg, b.sigma_roll_deg};
    for (std::size_t k = 0; k < std::size(av); ++k) {
      if (std::isnan(av[k])) {
        ASSERT_TRUE(std::isnan(bv[k])) << i << " " << k;
      } else {
        ASSERT_TRUE(same_bits(av[k], bv[k])) << i << " " << k << " " << av[k];
      }
    }
  }
  // The header is the documented one, sigmas included.
  std::ifstream f(path);
  std::string line;
  while (std::getline(f, line) && line[0] == '#') {
  }
  EXPECT_EQ(line,
            "t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg,sigma_n_m,sigma_e_m,"
            "sigma_d_m,"
            "sigma_yaw_deg,sigma_pitch_deg,sigma_roll_deg");
}

TEST(NavSolutionCsv, SigmaColumnsAreOptional) {
  const auto log = nav_from(
      "t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg,sigma_n_m\n"
      "100,1,2,3,4,5,6,7,8,9,0.5\n"
      "200,1,2,3,4,5,6,7,8,9,\n");
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->rows.size(), 2u);
  EXPECT_EQ(log->rows[0].sigma_n_m, 0.5);
  EXPECT_TRUE(std::isnan(log->rows[1].sigma_n_m));
  EXPECT_TRUE(std::isnan(log->rows[0].sigma_roll_deg));
  EXPECT_EQ(log->rows[1].roll_deg, 9);
}

// The IMU clock columns (the fusion estimated the IMU clock): written after the sigmas only when a
// row has a clock offset, read back bit-exact; a file without them (older files, no clock
// estimated) reads as NaN; a negative clock sigma is an error.
TEST(NavSolutionCsv, ImuClockColumnsAtTheEndWhenEstimated) {
  std::vector<NavSolutionRow> in = make_nav(20);
  for (std::size_t i = 0; i < in.size(); ++i) {
    in[i].imu_clock_offset_ms = 7.0 + 1e-3 * static_cast<double>(i) / 3.0;
    in[i].imu_clock_drift_ppm = -20.0 / 7.0;
    in[i].sigma_imu_clock_offset_ms = i % 5 ? 0.25 / static_cast<double>(i + 1) : NavSolutionRow::kNaN;
    in[i].sigma_imu_clock_drift_ppm = 3.5;
  }
  std::ostringstream out;
  ASSERT_TRUE(write_nav_solution_csv(out, in));
  const std::string text = out.str();
  EXPECT_NE(text.find("sigma_roll_deg,imu_clock_offset_ms,imu_clock_drift_ppm,sigma_imu_clock_offset_ms,"
                      "sigma_imu_clock_drift_ppm\n"),
            std::string::npos);
  std::istringstream back(text);
  const auto log = parse_nav_solution_csv(back, "nav.csv");
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->rows.size(), in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    EXPECT_TRUE(same_bits(log->rows[i].imu_clock_offset_ms, in[i].imu_clock_offset_ms)) << i;
    EXPECT_TRUE(same_bits(log->rows[i].imu_clock_drift_ppm, in[i].imu_clock_drift_ppm)) << i;
    EXPECT_EQ(std::isnan(log->rows[i].sigma_imu_clock_offset_ms),
              std::isnan(in[i].sigma_imu_clock_offset_ms));
    EXPECT_EQ(log->rows[i].sigma_imu_clock_drift_ppm, 3.5);
  }
  const auto old = nav_from(
      "t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg\n100,1,2,3,4,5,6,7,8,9\n");
  ASSERT_TRUE(old) << old.error().message;
  EXPECT_TRUE(std::isnan(old->rows[0].imu_clock_offset_ms));
  EXPECT_TRUE(std::isnan(old->rows[0].sigma_imu_clock_drift_ppm));
  const auto bad = nav_from(
      "t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg,imu_clock_offset_ms,"
      "sigma_imu_clock_offset_ms\n100,1,2,3,4,5,6,7,8,9,-7,-0.1\n");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("column 'sigma_imu_clock_offset_ms': expected a sigma >= 0"),
            std::string::npos)
      << bad.error().message;
}

TEST(NavSolutionCsv, OrderAndGaps) {
  std::string text = "t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg\n";
  for (const char* t : {"0", "100", "200", "150", "200", "300", "700", "800"}) {
    text += std::string(t) + ",0,0,0,0,0,0,0,0,0\n";
  }
  const auto log = nav_from(text);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->issues.out_of_order, 1u);
  EXPECT_EQ(log->issues.duplicates, 1u);
  EXPECT_EQ(log->issues.gaps, 1u);
  EXPECT_TRUE(has_message(log->issues, "nav.csv:5: ", "older")) << all_messages(log->issues);
  EXPECT_TRUE(has_message(log->issues, "nav.csv:6: ", "repeats")) << all_messages(log->issues);
  EXPECT_TRUE(has_message(log->issues, "nav.csv:8: ", "gap")) << all_messages(log->issues);
  EXPECT_EQ(log->rows.size(), 6u);
}

TEST(NavSolutionCsv, BadFilesNameFileLineAndColumn) {
  const std::string header = "t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg\n";
  const struct {
    std::string text;
    std::vector<std::string> parts;
  } cases[] = {
      {header + "1,0,0,0,0,0,0,north,0,0\n", {"nav.csv:2: ", "column 'yaw_deg'", "'north'"}},
      {header + "1,91,0,0,0,0,0,0,0,0\n", {"nav.csv:2: ", "column 'lat_deg'", "-90..90"}},
      {header + "1,0,-181,0,0,0,0,0,0,0\n", {"nav.csv:2: ", "column 'lon_deg'"}},
      {header + "1,0,0,,0,0,0,0,0,0\n", {"nav.csv:2: ", "column 'h_m'"}},
      {header + "1,0,0,0,0,0,0,0,0\n", {"nav.csv:2: ", "expected 10 fields", "got 9"}},
      {"t_ns,lat_deg,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg,sigma_n_m\n"
       "1,0,0,0,0,0,0,0,0,0,-1\n",
       {"nav.csv:2: ", "column 'sigma_n_m'", ">= 0"}},
      {"t_ns,lat,lon_deg,h_m,vn_mps,ve_mps,vd_mps,yaw_deg,pitch_deg,roll_deg\n",
       {"nav.csv:1: ", "unknown column 'lat'"}},
  };
  for (const auto& c : cases) {
    const auto log = nav_from(c.text);
    ASSERT_FALSE(log) << c.text;
    const std::string& m = log.error().message;
    EXPECT_EQ(m.rfind("nav::parse_nav_solution_csv(): ", 0), 0u) << m;
    for (const std::string& p : c.parts)
      EXPECT_NE(m.find(p), std::string::npos) << "'" << p << "' not in: " << m;
  }
  std::vector<NavSolutionRow> rows = make_nav(2);
  rows[1].h_m = std::numeric_limits<double>::infinity();
  std::ostringstream out;
  EXPECT_FALSE(write_nav_solution_csv(out, rows));
  EXPECT_FALSE(write_nav_solution_csv("/nonexistent/dir/nav.csv", make_nav(1)));
}

TEST(FrameIndexCsv, RoundTripAndErrors) {
  FrameIndex index;
  index.metadata["scenario"] = "demo";
  index.rows = {{0, 0, 1000, "left/000000.png"},
                {0, 1, 1005, "right/000000.png"},
                {1, 0, 34334, "left/000001.png"},
                {2, 1, 67672, "right/000002.png"}};
  const std::string path = test::output_dir("nav_logs_frame_index") + "/frame_index.csv";
  ASSERT_TRUE(write_frame_index_csv(path, index));
  auto back = read_frame_index_csv(path);
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->rows.size(), 4u);
  EXPECT_EQ(back->clock, ClockDomain::kDevice);
  EXPECT_EQ(back->metadata.at("scenario"), "demo");
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(back->rows[i].sequence, index.rows[i].sequence);
    EXPECT_EQ(back->rows[i].camera, index.rows[i].camera);
    EXPECT_EQ(back->rows[i].t_ns, index.rows[i].t_ns);
    EXPECT_EQ(back->rows[i].file, index.rows[i].file);
  }
  const std::pair<const char*, const char*> bad[] = {
      {"sequence,camera,t_ns,file\n0,0,5,a.png\n1,0,5,b.png\n",
       "idx.csv:3: camera 0: sequence and t_ns must increase"},
      {"sequence,camera,t_ns,file\n0,99,5,a.png\n", "idx.csv:2: column 'camera': expected a camera index"},
      {"sequence,camera,t_ns,file\n0,0,5,../a.png\n", "idx.csv:2: column 'file'"},
      {"sequence,camera,t_ns\n", "idx.csv:1: header: missing column 'file'"},
      {"sequence,camera,t_ns,file\n0,0,x,a.png\n", "idx.csv:2: column 't_ns': expected an integer"},
  };
  for (const auto& [text, expect] : bad) {
    std::istringstream in(text);
    auto r = parse_frame_index_csv(in, "idx.csv");
    ASSERT_FALSE(r) << text;
    EXPECT_NE(r.error().message.find(expect), std::string::npos) << r.error().message;
  }
}

TEST(CameraPoseCsv, RoundTripBitExactAndErrors) {
  std::vector<CameraPoseRow> rows(2);
  rows[0] = {3, 0, 100, 200, -1.25, 0.1, 20.123456789012345, 0.5, 0.5, 0.5, 0.5};
  rows[0].sigma_pos_m = 0.012;
  rows[1] = {3, 1, 101, 201, 1.0 / 3.0, -2.0, 19.0, 1.0, 0.0, 0.0, 0.0};
  rows[1].boom_elevation_deg = 30.5;
  const std::string path = test::output_dir("nav_logs_poses") + "/poses.csv";
  ASSERT_TRUE(write_camera_pose_csv(path, rows));
  auto back = read_camera_pose_csv(path);
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->rows.size(), 2u);
  EXPECT_EQ(back->rows[0].z_m, rows[0].z_m);
  EXPECT_EQ(back->rows[1].x_m, rows[1].x_m);
  EXPECT_EQ(back->rows[0].sigma_pos_m, 0.012);
  EXPECT_TRUE(std::isnan(back->rows[0].boom_elevation_deg));
  EXPECT_EQ(back->rows[1].boom_elevation_deg, 30.5);
  std::istringstream in("sequence,camera,t_ns,t_nav_ns,x_m,y_m,z_m,qw,qx,qy,qz\n0,0,1,1,0,0,5,1,1,0,0\n");
  auto r = parse_camera_pose_csv(in, "p.csv");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("p.csv:2: columns qw..qz: expected a unit quaternion"), std::string::npos)
      << r.error().message;
}

}  // namespace
}  // namespace augrig::nav
