// The item types' helpers: stage and clock names, and IMU samples as nav CSV rows that read back
// bit-exact through nav/logs.hpp.
#include "recorder/record.hpp"

#include <sstream>

#include <gtest/gtest.h>

#include "nav/logs.hpp"

namespace augrig::recorder {
namespace {

TEST(Record, DropStageNames) {
  for (DropStage s : kAllDropStages) {
    DropStage back = DropStage::kCamera;
    ASSERT_TRUE(parse_drop_stage(to_string(s), back)) << to_string(s);
    EXPECT_EQ(back, s);
  }
  DropStage out;
  EXPECT_FALSE(parse_drop_stage("Camera", out));
  EXPECT_FALSE(parse_drop_stage("", out));
  EXPECT_EQ(to_string(DropStage::kRecorder), "recorder");
}

TEST(Record, ClockDomainNames) {
  for (ClockDomain c : {ClockDomain::kUnknown, ClockDomain::kHostMonotonic, ClockDomain::kHostRealtime,
                        ClockDomain::kDevice, ClockDomain::kGps, ClockDomain::kSim}) {
    ClockDomain back = ClockDomain::kUnknown;
    ASSERT_TRUE(parse_clock_domain(to_string(c), back)) << to_string(c);
    EXPECT_EQ(back, c);
  }
  ClockDomain out;
  EXPECT_FALSE(parse_clock_domain("utc", out));
}

TEST(Record, ImuInputReadsBackBitExact) {
  std::vector<nav::ImuSample> samples(3);
  samples[0] = {
      1'400'000'000'005'000'000, 0.005, {1e-5, -2.5e-6, 0.1 / 3}, {0.049, -1e-300, 9.81 * 0.005}, 77};
  samples[1] = {1'400'000'000'010'000'000, 0.005, {0.0, -0.0, 1.0 / 7}, {std::nextafter(1.0, 2.0), 0, 0}, 0};
  samples[2] = {1'400'000'000'015'000'000,
                0.005,
                {2.2250738585072014e-308, 1.7976931348623157e308, -3.3},
                {1, 2, 3},
                123456789};
  std::string csv = std::string(imu_input_header()) + "\n";
  for (const auto& s : samples) {
    const NavInputRecord r = imu_input(s, "tanker.imu");
    EXPECT_EQ(r.stream, "tanker.imu");
    EXPECT_EQ(r.t_ns, s.t_ns);
    EXPECT_EQ(r.arrival_ns, s.arrival_ns);
    EXPECT_FALSE(r.binary);
    EXPECT_EQ(r.data.find('\n'), std::string::npos);
    csv += r.data + "\n";
  }
  std::istringstream in(csv);
  auto log = nav::parse_imu_csv(in, "recorded.imu");
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->samples.size(), samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const auto& a = samples[i];
    const auto& b = log->samples[i];
    EXPECT_EQ(a.t_ns, b.t_ns);
    EXPECT_EQ(a.dt_s, b.dt_s);
    EXPECT_EQ(a.arrival_ns, b.arrival_ns);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(a.dtheta_rad[k], b.dtheta_rad[k]);
      EXPECT_EQ(a.dv_mps[k], b.dv_mps[k]);
    }
  }
}

}  // namespace
}  // namespace augrig::recorder
