// NavInputStamper: the sensor time of a recorded nav input read from its data. IMU datagrams give
// their last sample's time and their clock; NMEA time tags give GPS time once the stream's date is
// known (RMC, ZDA), across midnight too; sentences without time, before any date, with a bad
// checksum, and undecodable datagrams stay 0 / unknown.
#include "recorder/nav_inputs.hpp"

#include <gtest/gtest.h>

#include "nav/imu_stream.hpp"
#include "nav/nmea.hpp"

namespace augrig::recorder {
namespace {

NavInputRecord text(const std::string& stream, const std::string& body) {
  return NavInputRecord{stream, 123, ClockDomain::kGps, 42, nav::nmea_sentence(body), false};
}

TEST(NavInputStamper, ImuDatagramGivesItsLastSampleTimeAndClock) {
  std::vector<nav::ImuSample> s(3);
  for (int k = 0; k < 3; ++k) {
    s[static_cast<std::size_t>(k)].t_ns = 1'400'000'000'000'000'000 + k * 5'000'000;
    s[static_cast<std::size_t>(k)].dt_s = 0.005;
  }
  for (ClockDomain c : {ClockDomain::kGps, ClockDomain::kDevice}) {
    auto d = nav::encode_imu_datagram(s, 7, c);
    ASSERT_TRUE(d);
    NavInputRecord r{"tanker.imu", 0, ClockDomain::kUnknown, 99, std::string(d->begin(), d->end()), true};
    NavInputStamper st;
    EXPECT_EQ(st.stamp(r), NavInputTimeSource::kImuDatagram);
    EXPECT_EQ(r.t_ns, s.back().t_ns);
    EXPECT_EQ(r.clock, c);
    EXPECT_EQ(r.arrival_ns, 99);  // untouched
    r.data[20] ^= 1;              // the CRC fails
    EXPECT_EQ(st.stamp(r), NavInputTimeSource::kNone);
    EXPECT_EQ(r.t_ns, 0);
    EXPECT_EQ(r.clock, ClockDomain::kUnknown);
  }
}

TEST(NavInputStamper, NmeaTimeTagsOnceTheDateIsKnown) {
  NavInputStamper st;
  // A GGA before any date: its time cannot be placed.
  auto gga = text("gps", "GNGGA,235959.900,5100.0,N,00100.0,W,4,16,0.7,7000.0,M,36.0,M,,");
  EXPECT_EQ(st.stamp(gga), NavInputTimeSource::kNoDateYet);
  EXPECT_EQ(gga.t_ns, 0);
  EXPECT_EQ(gga.clock, ClockDomain::kUnknown);
  // RMC brings the date (ddmmyy) and is itself stamped.
  auto rmc = text("gps", "GNRMC,235959.900,A,5100.0,N,00100.0,W,310.0,90.0,310524,,,R");
  EXPECT_EQ(st.stamp(rmc), NavInputTimeSource::kNmeaTimeTag);
  const TimestampNs want = nav::gps_ns_from_utc({2024, 5, 31}, (23 * 3600 + 59 * 60 + 59) * nav::kNsPerSecond + 900'000'000);
  EXPECT_EQ(rmc.t_ns, want);
  EXPECT_EQ(rmc.clock, ClockDomain::kGps);
  EXPECT_EQ(st.date("gps"), (nav::CivilDate{2024, 5, 31}));
  // Midnight passes before the next RMC: the next day.
  auto gga2 = text("gps", "GNGGA,000000.000,5100.0,N,00100.0,W,4,16,0.7,7000.0,M,36.0,M,,");
  EXPECT_EQ(st.stamp(gga2), NavInputTimeSource::kNmeaTimeTag);
  EXPECT_EQ(gga2.t_ns, nav::gps_ns_from_utc({2024, 6, 1}, 0));
  EXPECT_EQ(gga2.t_ns - want, 100'000'000);
  // No time tag: VTG and HDT.
  auto hdt = text("gps", "GNHDT,90.0,T");
  EXPECT_EQ(st.stamp(hdt), NavInputTimeSource::kNone);
  EXPECT_EQ(hdt.t_ns, 0);
  EXPECT_EQ(hdt.clock, ClockDomain::kUnknown);
  // Another stream has no date yet; ZDA gives one, with the leap seconds asked for.
  NavInputStamper st17(17);
  auto zda = text("receiver.gps", "GNZDA,120000.500,01,06,2024,00,00");
  EXPECT_EQ(st17.stamp(zda), NavInputTimeSource::kNmeaTimeTag);
  EXPECT_EQ(zda.t_ns, nav::gps_ns_from_utc({2024, 6, 1}, 12 * 3600 * nav::kNsPerSecond + 500'000'000, 17));
  // A damaged checksum, and a line that is no sentence.
  auto bad = zda;
  bad.data[10] = '9';
  EXPECT_EQ(st17.stamp(bad), NavInputTimeSource::kNone);
  NavInputRecord json{"gps", 0, ClockDomain::kUnknown, 1, "{\"class\":\"TPV\"}", false};
  EXPECT_EQ(st17.stamp(json), NavInputTimeSource::kNone);
  // An arrival prefix as logs hold it is skipped.
  auto prefixed = text("receiver.gps", "GNGGA,120001.000,5100.0,N,00100.0,W,4,16,0.7,7000.0,M,36.0,M,,");
  prefixed.data = "11679687842081 " + prefixed.data;
  EXPECT_EQ(st17.stamp(prefixed), NavInputTimeSource::kNmeaTimeTag);
  EXPECT_EQ(prefixed.t_ns, nav::gps_ns_from_utc({2024, 6, 1}, 12 * 3600 * nav::kNsPerSecond + nav::kNsPerSecond, 17));
}

}  // namespace
}  // namespace augrig::recorder
