// Tests for nav/nmea.hpp and nav/gps_time.hpp. Oracles: checksums printed in published example
// sentences (NMEA references of gpsinformation.org, Trimble and NovAtel manuals), GPS week
// rollover dates, Python's datetime for GPS-epoch second counts, hand-computed positions.
#include "nav/nmea.hpp"

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "nav/geodesy.hpp"
#include "nav/gps_time.hpp"
#include "tests/support/test_support.hpp"

namespace augrig::nav {
namespace {

constexpr double kKnot = 1852.0 / 3600.0;

Expected<NmeaLog> parse_text(const std::string& text, const NmeaOptions& o = {},
                             const std::string& name = "t.nmea") {
  std::istringstream in(text);
  return parse_nmea(in, name, o);
}

// "$" + body + "*HH" with the checksum computed here, independently of nmea_checksum().
std::string sentence(const std::string& body) {
  unsigned x = 0;
  for (unsigned char c : body) x ^= c;
  char buf[8];
  std::snprintf(buf, sizeof buf, "*%02X", x);
  return "$" + body + buf;
}

bool has_message(const LogIssues& issues, const std::string& start, const std::string& part) {
  for (const std::string& m : issues.messages) {
    if (m.rfind(start, 0) == 0 && m.find(part) != std::string::npos) return true;
  }
  return false;
}

std::string all_messages(const LogIssues& issues) {
  std::string s;
  for (const std::string& m : issues.messages) s += m + "\n";
  return s;
}

// ------------------------------------------------------------------------------------------
// GPS time

TEST(GpsTime, CivilDays) {
  EXPECT_EQ(days_from_civil(1970, 1, 1), 0);
  EXPECT_EQ(days_from_civil(2000, 3, 1), 11017);  // Python: (date(2000,3,1)-date(1970,1,1)).days
  EXPECT_EQ(days_from_civil(1600, 2, 29), -135081);
  EXPECT_EQ(kGpsEpochUnixDays, 3657);
  for (std::int64_t d = -800000; d <= 800000; d += 997) {
    EXPECT_EQ(days_from_civil(civil_from_days(d)), d);
  }
  EXPECT_EQ(civil_from_days(days_from_civil(2024, 2, 28) + 1), (CivilDate{2024, 2, 29}));
  EXPECT_EQ(civil_from_days(days_from_civil(2023, 2, 28) + 1), (CivilDate{2023, 3, 1}));
  EXPECT_EQ(civil_from_days(days_from_civil(2100, 2, 28) + 1), (CivilDate{2100, 3, 1}));
  EXPECT_TRUE(is_valid_date({2000, 2, 29}));
  EXPECT_FALSE(is_valid_date({1900, 2, 29}));
  EXPECT_FALSE(is_valid_date({2023, 13, 1}));
  EXPECT_FALSE(is_valid_date({2023, 4, 31}));
}

TEST(GpsTime, WeekRolloversAndLeapSeconds) {
  // GPS week 2048 began 2019-04-07 00:00:00 GPS = 2019-04-06 23:59:42 UTC (18 leap seconds);
  // week 1024 began 1999-08-22 00:00:00 GPS = 1999-08-21 23:59:47 UTC (13 leap seconds).
  const TimestampNs week2048 = 2048LL * 7 * 86400 * kNsPerSecond;
  const UtcTime u = utc_from_gps_ns(week2048, 18);
  EXPECT_EQ(u.date, (CivilDate{2019, 4, 6}));
  EXPECT_EQ(u.ns_of_day, (23 * 3600 + 59 * 60 + 42) * kNsPerSecond);
  EXPECT_EQ(gps_ns_from_utc({2019, 4, 6}, u.ns_of_day, 18), week2048);
  const TimestampNs week1024 = 1024LL * 7 * 86400 * kNsPerSecond;
  EXPECT_EQ(gps_ns_from_utc({1999, 8, 21}, (23 * 3600 + 59 * 60 + 47) * kNsPerSecond, 13), week1024);
  EXPECT_EQ(gps_ns_from_utc({1980, 1, 6}, 0, 0), 0);
  // Python: ((datetime(2020,12,31,23,59,59) - datetime(1980,1,6)).total_seconds() + 18) * 1e9
  EXPECT_EQ(gps_ns_from_utc({2020, 12, 31}, 86399 * kNsPerSecond, 18), 1293494417000000000LL);
  // Before the epoch: negative, and the inverse still works.
  const UtcTime before = utc_from_gps_ns(-1, 0);
  EXPECT_EQ(before.date, (CivilDate{1980, 1, 5}));
  EXPECT_EQ(before.ns_of_day, kNsPerDay - 1);
}

// The table of leap seconds against the published GPS - UTC values (USNO/IERS: TAI - UTC - 19 s),
// the week starts above and the step instants.
TEST(GpsTime, LeapSecondTableByDate) {
  EXPECT_EQ(leap_seconds_on({1980, 1, 6}), 0);
  EXPECT_EQ(leap_seconds_on({1981, 6, 30}), 0);
  EXPECT_EQ(leap_seconds_on({1981, 7, 1}), 1);
  EXPECT_EQ(leap_seconds_on({1994, 3, 23}), 9);
  EXPECT_EQ(leap_seconds_on({1999, 8, 21}), 13);  // the week-1024 rollover above
  EXPECT_EQ(leap_seconds_on({2006, 5, 4}), 14);
  EXPECT_EQ(leap_seconds_on({2012, 6, 30}), 15);
  EXPECT_EQ(leap_seconds_on({2012, 7, 1}), 16);
  EXPECT_EQ(leap_seconds_on({2016, 12, 31}), 17);
  EXPECT_EQ(leap_seconds_on({2017, 1, 1}), 18);
  EXPECT_EQ(leap_seconds_on({2019, 4, 6}), 18);  // the week-2048 rollover above
  EXPECT_EQ(leap_seconds_on({2099, 12, 31}), kDefaultLeapSeconds);
  // Steps are strictly increasing in date and by one second each.
  for (std::size_t i = 1; i < kLeapSecondSteps.size(); ++i) {
    EXPECT_LT(days_from_civil(kLeapSecondSteps[i - 1].from), days_from_civil(kLeapSecondSteps[i].from));
    EXPECT_EQ(kLeapSecondSteps[i].gps_minus_utc_s, kLeapSecondSteps[i - 1].gps_minus_utc_s + 1);
  }
  // Across the leap second at the end of 2016: 23:59:59, 23:59:60, 00:00:00 are one second apart in
  // GPS time, and the GPS instants convert back to the same UTC (23:59:60 included).
  const auto a = gps_ns_from_utc_by_table({2016, 12, 31}, 86399 * kNsPerSecond);
  const auto b = gps_ns_from_utc_by_table({2016, 12, 31}, 86400 * kNsPerSecond);
  const auto c = gps_ns_from_utc_by_table({2017, 1, 1}, 0);
  ASSERT_TRUE(a && b && c);
  EXPECT_EQ(*b - *a, kNsPerSecond);
  EXPECT_EQ(*c - *b, kNsPerSecond);
  // Python: (datetime(2017,1,1) - datetime(1980,1,6)).total_seconds() + 18
  EXPECT_EQ(*c, 1167264018LL * kNsPerSecond);
  EXPECT_EQ(leap_seconds_at_gps(*a), 17);
  EXPECT_EQ(leap_seconds_at_gps(*b), 17);
  EXPECT_EQ(leap_seconds_at_gps(*c), 18);
  const UtcTime ub = utc_from_gps_ns_by_table(*b + 250'000'000);
  EXPECT_EQ(ub.date, (CivilDate{2016, 12, 31}));
  EXPECT_EQ(ub.ns_of_day, 86400 * kNsPerSecond + 250'000'000);
  EXPECT_EQ(utc_from_gps_ns_by_table(*a).ns_of_day, 86399 * kNsPerSecond);
  EXPECT_EQ(utc_from_gps_ns_by_table(*c).date, (CivilDate{2017, 1, 1}));
  EXPECT_EQ(utc_from_gps_ns_by_table(*c).ns_of_day, 0);
}

// ------------------------------------------------------------------------------------------
// Checksums and published sentences

TEST(Nmea, ChecksumsOfPublishedSentences) {
  const std::vector<std::string> published = {
      "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47",
      "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A",
      "$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48",
      "$GPZDA,201530.00,04,07,2002,00,00*60",
      "$GPGST,172814.0,0.006,0.023,0.020,273.6,0.023,0.020,0.031*6A",
      "$GPHDT,123.456,T*32",
      "$GPGGA,172814.0,3723.46587704,N,12202.26957864,W,2,6,1.2,18.893,M,-25.669,M,2.0,0031*4F",
  };
  for (const std::string& s : published) {
    const std::size_t star = s.find('*');
    const std::string body = s.substr(1, star - 1);
    EXPECT_EQ(nmea_checksum(body), std::stoi(s.substr(star + 1), nullptr, 16)) << s;
    EXPECT_EQ(nmea_sentence(body), s);
  }
}

TEST(Nmea, ParsesThePublishedGgaAndRmc) {
  NmeaOptions o;
  o.leap_seconds = 9;  // GPS - UTC on 1994-03-23
  const auto log = parse_text(
      "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
      "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n",
      o);
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 1u);
  const GpsFix& f = log->fixes[0];
  EXPECT_EQ(f.t_ns, 448461328000000000LL);  // Python datetime, 1994-03-23 12:35:19 UTC + 9 s
  EXPECT_NEAR(rad_to_deg(f.antenna.lat_rad), 48.0 + 7.038 / 60.0, 1e-12);
  EXPECT_NEAR(rad_to_deg(f.antenna.lon_rad), 11.0 + 31.0 / 60.0, 1e-12);
  EXPECT_NEAR(f.antenna.h_m, 545.4 + 46.9, 1e-9);  // MSL + separation = ellipsoidal
  EXPECT_DOUBLE_EQ(f.geoid_separation_m, 46.9);
  EXPECT_EQ(f.quality, FixQuality::kSingle);
  EXPECT_EQ(f.satellites, 8);
  EXPECT_DOUBLE_EQ(f.hdop, 0.9);
  ASSERT_TRUE(f.ground_speed_mps && f.course_rad);
  EXPECT_NEAR(*f.ground_speed_mps, 22.4 * kKnot, 1e-12);
  EXPECT_NEAR(*f.course_rad, deg_to_rad(84.4), 1e-12);
  EXPECT_FALSE(f.heading_rad);
  EXPECT_FALSE(f.sigma_ned_m);
  EXPECT_EQ(log->issues.malformed, 0u);
  EXPECT_EQ(log->sentence_counts.at("GGA"), 1u);
  EXPECT_EQ(log->sentence_counts.at("RMC"), 1u);
}

TEST(Nmea, ParsesThePublishedTrimbleEpoch) {
  // Western hemisphere, negative separation, GST and HDT of the same epoch.
  NmeaOptions o;
  o.default_date = CivilDate{2006, 5, 4};
  const auto log = parse_text(
      "$GPGGA,172814.0,3723.46587704,N,12202.26957864,W,2,6,1.2,18.893,M,-25.669,M,2.0,0031*4F\n"
      "$GPGST,172814.0,0.006,0.023,0.020,273.6,0.023,0.020,0.031*6A\n"
      "$GPHDT,123.456,T*32\n",
      o);
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 1u);
  const GpsFix& f = log->fixes[0];
  EXPECT_NEAR(rad_to_deg(f.antenna.lat_rad), 37.0 + 23.46587704 / 60.0, 1e-12);
  EXPECT_NEAR(rad_to_deg(f.antenna.lon_rad), -(122.0 + 2.26957864 / 60.0), 1e-12);
  EXPECT_NEAR(f.antenna.h_m, 18.893 - 25.669, 1e-9);
  EXPECT_EQ(f.quality, FixQuality::kDgps);
  ASSERT_TRUE(f.sigma_ned_m);
  EXPECT_DOUBLE_EQ(f.sigma_ned_m->x(), 0.023);
  EXPECT_DOUBLE_EQ(f.sigma_ned_m->y(), 0.020);
  EXPECT_DOUBLE_EQ(f.sigma_ned_m->z(), 0.031);
  ASSERT_TRUE(f.heading_rad);
  EXPECT_NEAR(*f.heading_rad, deg_to_rad(123.456), 1e-12);
  // GPS - UTC was 14 s on 2006-05-04: the table's value, not today's 18 (which put it 4 s late).
  EXPECT_EQ(f.t_ns, gps_ns_from_utc({2006, 5, 4}, (17 * 3600 + 28 * 60 + 14) * kNsPerSecond, 14));
  EXPECT_EQ(log->leap_seconds.applied, (std::map<int, std::size_t>{{14, 1}}));
  EXPECT_EQ(log->leap_seconds.from_table, 1u);
}

TEST(Nmea, ParsesVtgOldAndNewForms) {
  NmeaOptions o;
  o.default_date = CivilDate{2002, 7, 4};
  const std::string gga = sentence("GPGGA,201530.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,");
  auto log = parse_text(gga + "\n$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48\n", o);
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_TRUE(log->fixes[0].ground_speed_mps);
  EXPECT_NEAR(*log->fixes[0].ground_speed_mps, 5.5 * kKnot, 1e-12);
  EXPECT_NEAR(*log->fixes[0].course_rad, deg_to_rad(54.7), 1e-12);
  log = parse_text(gga + "\n" + sentence("GPVTG,054.7,034.4,005.5,010.2") + "\n", o);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_NEAR(*log->fixes[0].ground_speed_mps, 5.5 * kKnot, 1e-12);
  // Only km/h given.
  log = parse_text(gga + "\n" + sentence("GPVTG,054.7,T,,M,,N,36.0,K,A") + "\n", o);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_NEAR(*log->fixes[0].ground_speed_mps, 10.0, 1e-12);
  // ZDA date from the published ZDA (same time tag) overrides the default date.
  NmeaOptions o13;
  o13.leap_seconds = 13;  // GPS - UTC in 2002
  log = parse_text(gga + "\n$GPZDA,201530.00,04,07,2002,00,00*60\n", o13);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->fixes[0].t_ns, 709848943000000000LL);  // Python datetime: 2002-07-04 20:15:30 UTC + 13 s
}

// ------------------------------------------------------------------------------------------
// Writer

GpsFix make_fix(TimestampNs t_ns, double lat_deg, double lon_deg, double h_m, double sep_m) {
  GpsFix f;
  f.t_ns = t_ns;
  f.antenna = {deg_to_rad(lat_deg), deg_to_rad(lon_deg), h_m};
  f.geoid_separation_m = sep_m;
  f.quality = FixQuality::kRtkFixed;
  f.satellites = 17;
  f.hdop = 0.71;
  return f;
}

TEST(Nmea, WriterFieldsAndHeightRule) {
  GpsFix f =
      make_fix(gps_ns_from_utc({2023, 6, 15}, (10 * 3600 + 20 * 60 + 30) * kNsPerSecond + 250'000'000),
               -(33.0 + 51.0 / 60.0 + 35.9 / 3600.0), 151.0 + 12.0 / 60.0 + 40.0 / 3600.0, 69.5, 22.125);
  f.ground_speed_mps = 10 * kKnot;
  f.course_rad = deg_to_rad(-90.0);       // written as 270
  f.heading_rad = deg_to_rad(359.99999);  // rounds to 360.0000 -> 0.0000
  f.sigma_ned_m = Eigen::Vector3d(0.01, 0.02, 0.03);
  const std::vector<std::string> s = nmea_sentences(f);
  ASSERT_EQ(s.size(), 6u);
  // Latitude 33 deg 51.59833333 min S, longitude 151 deg 12.66666667 min E; MSL = 69.5 - 22.125.
  EXPECT_EQ(s[0],
            sentence("GNGGA,102030.250,3351.59833333,S,15112.66666667,E,4,17,0.71,47.3750,M,22.1250,M,,"));
  EXPECT_EQ(s[1], sentence("GNGST,102030.250,,0.0200,0.0100,90.0,0.0100,0.0200,0.0300"));
  EXPECT_EQ(s[2],
            sentence("GNRMC,102030.250,A,3351.59833333,S,15112.66666667,E,10.0000,270.0000,150623,,,R"));
  EXPECT_EQ(s[3], sentence("GNVTG,270.0000,T,,M,10.0000,N,18.5200,K,R"));
  EXPECT_EQ(s[4], sentence("GNHDT,0.0000,T"));
  EXPECT_EQ(s[5], sentence("GNZDA,102030.250,15,06,2023,00,00"));

  // The parser reads the GGA altitude as MSL and adds the separation back.
  const auto log = parse_text(write_nmea({f}));
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_NEAR(log->fixes[0].antenna.h_m, 69.5, 1e-9);
  EXPECT_NEAR(log->fixes[0].geoid_separation_m, 22.125, 1e-12);
}

TEST(Nmea, WriterLineEndingsTalkersAndRounding) {
  GpsFix f = make_fix(gps_ns_from_utc({2023, 12, 31}, kNsPerDay - 400'000), 47.999999999999, -0.0000000000001,
                      100, 0);
  NmeaWriterOptions o;
  o.talker = "GP";
  o.heading_talker = "HE";
  f.heading_rad = 1.0;
  const std::string text = write_nmea({f}, o);
  // Every line ends in CR LF.
  std::size_t lines = 0;
  for (std::size_t p = text.find('\n'); p != std::string::npos; p = text.find('\n', p + 1)) {
    ASSERT_GT(p, 0u);
    EXPECT_EQ(text[p - 1], '\r');
    ++lines;
  }
  EXPECT_EQ(lines, 4u);  // GGA, RMC, HDT, ZDA
  EXPECT_NE(text.find("$HEHDT,"), std::string::npos);
  // 23:59:59.9996 rounds to the next day's 00:00:00.000, and the date follows.
  EXPECT_NE(text.find("$GPGGA,000000.000,4800.00000000,N,00000.00000000,E,"), std::string::npos) << text;
  EXPECT_NE(text.find("$GPZDA,000000.000,01,01,2024,00,00*"), std::string::npos) << text;
}

TEST(Nmea, RoundTripBelowATenthOfAMillimetre) {
  const struct {
    double lat, lon, h, sep;
  } points[] = {{0, 0, 0, 17.16},
                {51.4778, -0.0014, 45.9, 47.01},
                {-33.8688, 151.2093, 58.2, 22.3},
                {-89.9999, -179.9999, 2835, -30},
                {89.99999, 179.99999, 12000.123456, 14.9},
                {37.39, -122.03, -25.3, -32.2},
                {12.3456789012, 98.7654321098, 1234.56789, -105.43}};
  std::vector<GpsFix> fixes;
  TimestampNs t = gps_ns_from_utc({2024, 2, 28}, 86395 * kNsPerSecond);
  for (const auto& p : points) {
    GpsFix f = make_fix(t, p.lat, p.lon, p.h, p.sep);
    f.ground_speed_mps = 123.456;
    f.course_rad = deg_to_rad(123.4567);
    f.heading_rad = deg_to_rad(10.5);
    f.sigma_ned_m = Eigen::Vector3d(0.0123, 0.0234, 0.0345);
    f.arrival_ns = 987654321000 + t / 1000;
    fixes.push_back(f);
    t += 1'001'000'000;  // crosses midnight into 2024-02-29
  }
  NmeaWriterOptions wo;
  wo.write_arrival_prefix = true;
  const auto log = parse_text(write_nmea(fixes, wo));
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->issues.malformed, 0u) << all_messages(log->issues);
  ASSERT_EQ(log->fixes.size(), fixes.size());
  for (std::size_t i = 0; i < fixes.size(); ++i) {
    const GpsFix& a = fixes[i];
    const GpsFix& b = log->fixes[i];
    EXPECT_EQ(b.t_ns, a.t_ns) << i;
    EXPECT_EQ(b.arrival_ns, a.arrival_ns) << i;
    EXPECT_LT((ecef_from_geodetic(b.antenna) - ecef_from_geodetic(a.antenna)).norm(), 1e-4) << i;
    EXPECT_LT(std::abs(b.antenna.h_m - a.antenna.h_m), 0.51e-4) << i;
    EXPECT_EQ(b.quality, a.quality);
    EXPECT_EQ(b.satellites, a.satellites);
    EXPECT_DOUBLE_EQ(b.hdop, a.hdop);
    EXPECT_NEAR(*b.ground_speed_mps, *a.ground_speed_mps, 0.51e-4 * kKnot);
    EXPECT_NEAR(*b.course_rad, *a.course_rad, deg_to_rad(0.51e-4));
    EXPECT_NEAR(*b.heading_rad, *a.heading_rad, deg_to_rad(0.51e-4));
    EXPECT_LT((*b.sigma_ned_m - *a.sigma_ned_m).cwiseAbs().maxCoeff(), 0.51e-4);
  }
  EXPECT_EQ(utc_from_gps_ns(log->fixes.back().t_ns).date, (CivilDate{2024, 2, 29}));
}

TEST(Nmea, InvalidFixIsKeptAndMarked) {
  GpsFix f;
  f.t_ns = gps_ns_from_utc({2023, 1, 1}, 0);
  f.antenna = {NAN, NAN, NAN};
  const std::string text = write_nmea({f});
  EXPECT_NE(text.find("GNGGA,000000.000,,,,,0,00,0.00,,M,0.0000,M,,"), std::string::npos) << text;
  EXPECT_NE(text.find("GNRMC,000000.000,V,"), std::string::npos) << text;
  const auto log = parse_text(text);
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 1u);
  EXPECT_EQ(log->fixes[0].quality, FixQuality::kInvalid);
  EXPECT_TRUE(std::isnan(log->fixes[0].antenna.lat_rad));
  EXPECT_EQ(log->issues.malformed, 0u) << all_messages(log->issues);
}

// ------------------------------------------------------------------------------------------
// Merging, dates, leap seconds, arrival prefix

TEST(Nmea, MergesSentencesByTimeTag) {
  const std::string text =
      sentence("GNZDA,120000.00,01,03,2021,00,00") + "\n" +
      sentence("GNGGA,120000.00,4000.00000000,N,00500.00000000,E,1,10,1.0,100.0,M,50.0,M,,") + "\n" +
      sentence("GNHDT,45.0,T") + "\n" + sentence("GNGST,120000.00,,1,1,0,0.5,0.6,0.7") + "\n" +
      // next epoch: RMC first, then VTG (no time: joins 12:00:00.2), then GGA
      sentence("GNRMC,120000.20,A,4000.0,N,00500.0,E,2.0,90.0,010321,,,A") + "\n" +
      sentence("GNVTG,91.0,T,,M,3.0,N,5.556,K,A") + "\n" + sentence("GNHDT,46.0,T") + "\n" +
      sentence("GNGGA,120000.20,4000.00000000,N,00500.00000000,E,1,10,1.0,100.0,M,50.0,M,,") + "\n";
  const auto log = parse_text(text);
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 2u);
  const GpsFix& a = log->fixes[0];
  const GpsFix& b = log->fixes[1];
  EXPECT_EQ(b.t_ns - a.t_ns, 200'000'000);
  EXPECT_EQ(a.t_ns, gps_ns_from_utc({2021, 3, 1}, 12 * 3600 * kNsPerSecond));
  EXPECT_NEAR(*a.heading_rad, deg_to_rad(45.0), 1e-12);
  EXPECT_EQ(*a.sigma_ned_m, Eigen::Vector3d(0.5, 0.6, 0.7));
  EXPECT_FALSE(a.ground_speed_mps);
  EXPECT_NEAR(*b.heading_rad, deg_to_rad(46.0), 1e-12);
  EXPECT_FALSE(b.sigma_ned_m);
  // RMC came first in the epoch: its speed and course win over the VTG's.
  EXPECT_NEAR(*b.ground_speed_mps, 2.0 * kKnot, 1e-12);
  EXPECT_NEAR(*b.course_rad, deg_to_rad(90.0), 1e-12);
  EXPECT_EQ(log->issues.malformed, 0u);
  EXPECT_EQ(log->epochs_without_gga, 0u);
}

TEST(Nmea, MidnightRolloverAndLeapYear) {
  const auto gga = [](const char* t) {
    return sentence(std::string("GNGGA,") + t + ",4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,") + "\r\n";
  };
  const std::string text = sentence("GNZDA,235959.00,28,02,2024,00,00") + "\r\n" + gga("235959.00") +
                           gga("235959.50") + gga("000000.00") + gga("000000.50") + gga("000001.00");
  const auto log = parse_text(text);
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 5u);
  for (std::size_t i = 1; i < 5; ++i)
    EXPECT_EQ(log->fixes[i].t_ns - log->fixes[i - 1].t_ns, 500'000'000) << i;
  EXPECT_EQ(utc_from_gps_ns(log->fixes[2].t_ns).date, (CivilDate{2024, 2, 29}));
  EXPECT_EQ(log->fixes[2].t_ns, gps_ns_from_utc({2024, 2, 29}, 0));
  EXPECT_EQ(log->issues.gaps + log->issues.out_of_order + log->issues.duplicates, 0u);
}

TEST(Nmea, FixesBeforeAnyDate) {
  const std::string text = sentence("GNGGA,100000.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,") + "\n" +
                           sentence("GNGGA,100001.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,") + "\n" +
                           sentence("GNRMC,100001.00,A,4000.0,N,00500.0,E,0.0,0.0,010120,,,A") + "\n" +
                           sentence("GNGGA,100002.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,") + "\n";
  // Without a default date the first fix is reported and dropped; the second gets its RMC's date.
  auto log = parse_text(text, {}, "nodate.nmea");
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 2u);
  EXPECT_EQ(log->fixes_without_date, 1u);
  EXPECT_TRUE(has_message(log->issues, "nodate.nmea:1: ", "before any date")) << all_messages(log->issues);
  EXPECT_EQ(log->fixes[0].t_ns, gps_ns_from_utc({2020, 1, 1}, 36001 * kNsPerSecond));
  // With one, all three are kept.
  NmeaOptions o;
  o.default_date = CivilDate{2020, 1, 1};
  log = parse_text(text, o);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->fixes.size(), 3u);
  EXPECT_EQ(log->fixes_without_date, 0u);
  // Nothing but undated fixes: an error that says what to do.
  const auto none =
      parse_text(sentence("GNGGA,100000.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,") + "\n");
  ASSERT_FALSE(none);
  EXPECT_NE(none.error().message.find("default_date"), std::string::npos) << none.error().message;
}

// Years whose GPS ns would overflow int64 (9999) or leave the documented range (1700, 2250) are
// rejected by name, never turned into a wrapped-around time; a fix among them keeps its own date.
TEST(Nmea, DatesOutsideTheSupportedYearsAreRejected) {
  const auto gga = [](const char* t) {
    return sentence(std::string("GNGGA,") + t + ",4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,") + "\n";
  };
  for (const char* year : {"9999", "1700", "2250", "1979", "2100", "0000"}) {
    const std::string text = sentence(std::string("GNZDA,120000.00,01,01,") + year + ",00,00") + "\n" +
                             gga("120000.00") + gga("120001.00");
    const auto log = parse_text(text, {}, "far.nmea");
    ASSERT_FALSE(log) << year;
    EXPECT_NE(log.error().message.find("far.nmea:1: "), std::string::npos) << log.error().message;
    EXPECT_NE(log.error().message.find("field 4 (year): expected a year in 1980..2099"), std::string::npos)
        << log.error().message;
  }
  // Two dates far apart in one log: the second is rejected, so no difference of times overflows.
  const std::string mixed = sentence("GNZDA,120000.00,01,01,2024,00,00") + "\n" + gga("120000.00") +
                            gga("120001.00") + sentence("GNZDA,120002.00,01,01,2250,00,00") + "\n" +
                            gga("120002.00") + gga("120003.00");
  const auto log = parse_text(mixed, {}, "mixed.nmea");
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->fixes.size(), 4u);  // the 2250 ZDA dropped: its GGAs keep 2024's date
  EXPECT_EQ(log->issues.malformed, 1u);
  EXPECT_EQ(utc_from_gps_ns(log->fixes.back().t_ns).date, (CivilDate{2024, 1, 1}));
  // A default date outside the range: the fixes are dropped with a message, not overflowed.
  NmeaOptions o;
  o.default_date = CivilDate{9999, 12, 31};
  const auto far = parse_text(gga("120000.00") + gga("120001.00"), o, "default.nmea");
  ASSERT_FALSE(far);
  EXPECT_NE(far.error().message.find("expected a date in the years 1980..2099"), std::string::npos)
      << far.error().message;
}

TEST(Nmea, LeapSecondsShiftGpsTime) {
  const std::string text = sentence("GNGGA,120000.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,") + "\n" +
                           sentence("GNZDA,120000.00,01,07,2015,00,00") + "\n";
  NmeaOptions o17, o18;
  o17.leap_seconds = 17;  // GPS - UTC from 2015-07-01 to 2016-12-31
  o18.leap_seconds = 18;  // given wrong
  const auto a = parse_text(text, o17);
  const auto b = parse_text(text, o18);
  const auto table = parse_text(text);  // none given: the table's 17 for 2015-07-01
  ASSERT_TRUE(a && b && table);
  EXPECT_EQ(b->fixes[0].t_ns - a->fixes[0].t_ns, kNsPerSecond);
  EXPECT_EQ(table->fixes[0].t_ns, a->fixes[0].t_ns);
  EXPECT_EQ(a->leap_seconds.disagreements, 0u);
  EXPECT_EQ(b->leap_seconds.disagreements, 1u);
  // Python: (datetime(2015,7,1,12) - datetime(1980,1,6)).total_seconds() + 17
  EXPECT_EQ(a->fixes[0].t_ns, 1119787217LL * kNsPerSecond);
  // The writer applies the same offset in reverse.
  NmeaWriterOptions wo;
  wo.leap_seconds = 17;
  EXPECT_NE(write_nmea(a->fixes, wo).find("GNGGA,120000.000,"), std::string::npos);
}

// Unless told, each fix takes the GPS - UTC of its own UTC date from the table: logs of any year
// come out in GPS time, and the log says what it applied.
TEST(Nmea, LeapSecondsOfEachFixsDateFromTheTable) {
  const auto epoch = [](const std::string& date_ddmmyyyy, const std::string& time = "120000.00") {
    return sentence("GNGGA," + time + ",4000.0,N,00500.0,E,4,10,1.0,100.0,M,50.0,M,,") + "\n" +
           sentence("GNZDA," + time + "," + date_ddmmyyyy + ",00,00") + "\n";
  };
  for (const auto& [text, date, leap] : {std::tuple{epoch("23,03,1994"), CivilDate{1994, 3, 23}, 9},
                                         std::tuple{epoch("01,06,2016"), CivilDate{2016, 6, 1}, 17},
                                         std::tuple{epoch("01,06,2024"), CivilDate{2024, 6, 1}, 18}}) {
    const auto log = parse_text(text);
    ASSERT_TRUE(log) << log.error().message;
    EXPECT_EQ(log->fixes[0].t_ns, gps_ns_from_utc(date, 12 * 3600 * kNsPerSecond, leap));
    EXPECT_EQ(log->leap_seconds.applied, (std::map<int, std::size_t>{{leap, 1}}));
    EXPECT_EQ(log->leap_seconds.from_table, 1u);
    EXPECT_FALSE(log->leap_seconds.given);
    EXPECT_EQ(log->leap_seconds.disagreements, 0u);
  }
  EXPECT_EQ(describe(parse_text(epoch("01,06,2016"))->leap_seconds),
            "GPS-UTC 17 s (the leap-second table for the UTC date 2016-06-01)");
  // A value given that the date contradicts: used, and said, naming the line of the first fix.
  NmeaOptions o18;
  o18.leap_seconds = 18;
  const auto wrong = parse_text("\n" + epoch("01,06,2016") + epoch("01,06,2016", "120000.10"), o18, "old.nmea");
  ASSERT_TRUE(wrong) << wrong.error().message;
  EXPECT_EQ(wrong->fixes[0].t_ns, gps_ns_from_utc({2016, 6, 1}, 12 * 3600 * kNsPerSecond, 18));
  EXPECT_EQ(wrong->leap_seconds.disagreements, 2u);
  EXPECT_EQ(wrong->leap_seconds.first_disagreement,
            "old.nmea:2: GPS-UTC 18 s given, but it was 17 s on 2016-06-01 (the leap-second table): the fix times "
            "are 1 s late");
  EXPECT_TRUE(has_message(wrong->issues, "old.nmea:2: ", "GPS-UTC 18 s given")) << all_messages(wrong->issues);
  EXPECT_EQ(describe(wrong->leap_seconds), "GPS-UTC 18 s (given)");
}

// A log across the leap second inserted at the end of 2016, written as a receiver outputs it (the
// table's value at each fix, 23:59:60 included) and read back with the table: the same GPS times.
TEST(Nmea, LogAcrossTheLeapSecondOf2016RoundTrips) {
  const TimestampNs t0 = *gps_ns_from_utc_by_table({2016, 12, 31}, (86400 - 2) * kNsPerSecond);
  std::vector<GpsFix> fixes;
  for (int i = 0; i < 9; ++i) fixes.push_back(make_fix(t0 + i * 500'000'000LL, 40.0, 5.0, 100.0, 50.0));
  const std::string text = write_nmea(fixes);
  EXPECT_NE(text.find("GNGGA,235959.500,"), std::string::npos) << text;
  EXPECT_NE(text.find("GNGGA,235960.000,"), std::string::npos) << text;
  EXPECT_NE(text.find("GNGGA,235960.500,"), std::string::npos) << text;
  EXPECT_NE(text.find("GNGGA,000000.000,"), std::string::npos) << text;
  EXPECT_NE(text.find("GNZDA,000001.000,01,01,2017,00,00"), std::string::npos) << text;
  const auto back = parse_text(text);
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->fixes.size(), fixes.size()) << all_messages(back->issues);
  for (std::size_t i = 0; i < fixes.size(); ++i) EXPECT_EQ(back->fixes[i].t_ns, fixes[i].t_ns) << i;
  EXPECT_EQ(back->leap_seconds.applied, (std::map<int, std::size_t>{{17, 6}, {18, 3}}));  // 23:59:58 to :60.5
  EXPECT_EQ(back->issues.gaps, 0u);
  EXPECT_EQ(describe(back->leap_seconds),
            "GPS-UTC 17 s (6 fixes) and 18 s (3 fixes) (the leap-second table for the UTC dates 2016-12-31 to "
            "2017-01-01)");
}

// u-blox $PUBX,04 carries the receiver's own GPS - UTC: used when none is given (and preferred to
// the table), a given value checked against it naming the line, the firmware default ('D') ignored,
// and its week and time of week checked against its date and time.
TEST(Nmea, ReceiverLeapSecondsFromPubx04) {
  const std::string gga = sentence("GNGGA,120000.00,4000.0,N,00500.0,E,4,10,1.0,100.0,M,50.0,M,,");
  const std::string zda = sentence("GNZDA,120000.00,01,06,2016,00,00");
  // 2016-06-01 is day 3 (Wednesday) of GPS week 1899: 3 * 86400 + 43200 s.
  const std::string pubx17 = sentence("PUBX,04,120000.00,010616,302400.00,1899,17,-1234,12.345,21,");
  const auto reported = parse_text(gga + "\n" + zda + "\n" + pubx17 + "\n", {}, "u.nmea");
  ASSERT_TRUE(reported) << reported.error().message;
  EXPECT_EQ(reported->leap_seconds.receiver_reports, 1u);
  EXPECT_EQ(reported->leap_seconds.receiver_value, 17);
  EXPECT_EQ(reported->leap_seconds.from_receiver, 1u);
  EXPECT_EQ(reported->fixes[0].t_ns, gps_ns_from_utc({2016, 6, 1}, 12 * 3600 * kNsPerSecond, 17));
  EXPECT_EQ(reported->unused_sentences, 0u);
  EXPECT_EQ(describe(reported->leap_seconds), "GPS-UTC 17 s (reported by the receiver, PUBX,04)");
  // Given 18: the receiver's report says otherwise, with its line.
  NmeaOptions o18;
  o18.leap_seconds = 18;
  const auto given = parse_text(gga + "\n" + zda + "\n" + pubx17 + "\n", o18, "u.nmea");
  ASSERT_TRUE(given);
  EXPECT_EQ(given->leap_seconds.first_disagreement,
            "u.nmea:1: GPS-UTC 18 s given, but the receiver reports 17 s (PUBX,04, line 3): the fix times are 1 s "
            "late");
  // The firmware's default is not the receiver's knowledge: the table stands.
  const auto dflt = parse_text(gga + "\n" + zda + "\n" +
                                   sentence("PUBX,04,120000.00,010616,302400.00,1899,15D,-1234,12.345,21,") + "\n",
                               {}, "d.nmea");
  ASSERT_TRUE(dflt);
  EXPECT_EQ(dflt->leap_seconds.receiver_default_reports, 1u);
  EXPECT_FALSE(dflt->leap_seconds.receiver_value);
  EXPECT_EQ(dflt->leap_seconds.applied, (std::map<int, std::size_t>{{17, 1}}));
  EXPECT_TRUE(has_message(dflt->issues, "d.nmea:3: ", "default leap seconds (15D)")) << all_messages(dflt->issues);
  // A receiver that knows of a leap second the table lacks: its value is used, and said.
  const std::string gga31 = sentence("GNGGA,120000.00,4000.0,N,00500.0,E,4,10,1.0,100.0,M,50.0,M,,");
  // 2031-01-01 is day 3 of GPS week 2660 (Python: (date(2031,1,1)-date(1980,1,6)).days = 18623).
  const auto newer = parse_text(sentence("PUBX,04,115959.00,010131,302399.00,2660,19,,,,") + "\n" + gga31 + "\n" +
                                    sentence("GNZDA,120000.00,01,01,2031,00,00") + "\n",
                                {}, "n.nmea");
  ASSERT_TRUE(newer) << newer.error().message;
  EXPECT_EQ(newer->fixes[0].t_ns, gps_ns_from_utc({2031, 1, 1}, 12 * 3600 * kNsPerSecond, 19));
  EXPECT_EQ(newer->leap_seconds.first_disagreement,
            "n.nmea:2: the receiver reports GPS-UTC 19 s (PUBX,04, line 1) where the leap-second table gives 18 s "
            "for 2031-01-01: the receiver's value is used");
  // Week and time of week that contradict the date: a malformed line, named; a leap second field
  // that is not a number likewise.
  const auto bad = parse_text(gga + "\n" + zda + "\n" +
                                  sentence("PUBX,04,120000.00,010616,302400.00,1898,17,,,,") + "\n" +
                                  sentence("PUBX,04,120000.00,010616,302400.00,1899,x7,,,,") + "\n",
                              {}, "b.nmea");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->issues.malformed, 2u);
  EXPECT_TRUE(has_message(bad->issues, "b.nmea:3: ", "PUBX field 4 (UTC time of week): week 1898"))
      << all_messages(bad->issues);
  EXPECT_TRUE(has_message(bad->issues, "b.nmea:4: ", "field 6 (leap seconds)")) << all_messages(bad->issues);
  EXPECT_FALSE(bad->leap_seconds.receiver_value);
  // The writer's PUBX,04 reads back as the receiver's report of the table's value.
  NmeaWriterOptions wo;
  wo.pubx04 = true;
  std::vector<GpsFix> fixes;
  const TimestampNs t = *gps_ns_from_utc_by_table({2016, 6, 1}, 12 * 3600 * kNsPerSecond);
  for (int i = 0; i < 3; ++i) fixes.push_back(make_fix(t + i * 100'000'000LL, 40.0, 5.0, 100.0, 50.0));
  const std::string text = write_nmea(fixes, wo);
  EXPECT_NE(text.find("$PUBX,04,120000.000,010616,302400.00,1899,17,,,*"), std::string::npos) << text;
  const auto round = parse_text(text);
  ASSERT_TRUE(round) << round.error().message;
  EXPECT_EQ(round->leap_seconds.receiver_reports, 3u);
  EXPECT_EQ(round->leap_seconds.receiver_value, 17);
  EXPECT_EQ(round->issues.malformed, 0u) << all_messages(round->issues);
  for (std::size_t i = 0; i < fixes.size(); ++i) EXPECT_EQ(round->fixes[i].t_ns, fixes[i].t_ns);
}

TEST(Nmea, ReadsTheReceiverLogFile) {
  const auto log = read_nmea_file(test::data_path("nav/receiver.nmea"));
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 5u);
  // Line 1 is a comment the logger wrote: one malformed line, named.
  EXPECT_EQ(log->issues.malformed, 1u);
  EXPECT_TRUE(has_message(log->issues, test::data_path("nav/receiver.nmea") + ":1: ", "'$'"))
      << all_messages(log->issues);
  EXPECT_EQ(log->unused_sentences, 1u);  // one GSV
  EXPECT_EQ(log->sentence_counts.at("GSV"), 1u);
  EXPECT_EQ(log->sentence_counts.at("GGA"), 5u);
  for (std::size_t i = 0; i < 5; ++i) {
    const GpsFix& f = log->fixes[i];
    // Python datetime: 2023-06-15 10:20:30 UTC + 18 s.
    EXPECT_EQ(f.t_ns, 1370859648000000000LL + static_cast<TimestampNs>(i) * 100'000'000);
    EXPECT_EQ(f.arrival_ns, 1700000000003000000LL + static_cast<TimestampNs>(i) * 100'000'000);
    EXPECT_NEAR(rad_to_deg(f.antenna.lat_rad), 51 + (28.66872345 + i * 1e-6) / 60, 1e-13);
    EXPECT_NEAR(rad_to_deg(f.antenna.lon_rad), -(0.50123456 + i * 2e-6) / 60, 1e-13);
    EXPECT_NEAR(f.antenna.h_m, 45.1234 + 47.0123, 1e-9);
    EXPECT_EQ(f.quality, FixQuality::kRtkFixed);
    EXPECT_EQ(f.satellites, 21);
    EXPECT_NEAR(*f.ground_speed_mps, 0.0972 * kKnot, 1e-12);
    EXPECT_NEAR(*f.heading_rad, deg_to_rad(271.25), 1e-12);
    EXPECT_EQ(*f.sigma_ned_m, Eigen::Vector3d(0.0120, 0.0105, 0.0250));
  }
}

// ------------------------------------------------------------------------------------------
// Malformed input

TEST(Nmea, MalformedInputIsCountedNamedAndSkipped) {
  const auto gga = [](const std::string& t) {
    return sentence("GNGGA," + t + ",4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,");
  };
  std::string good_bad_cs = gga("120001.00");
  good_bad_cs[good_bad_cs.size() - 1] = good_bad_cs.back() == '0' ? '1' : '0';
  std::string binary("\x01\x02\xff\xfe\x00junk\x7f", 10);
  const std::vector<std::string> lines = {
      sentence("GNZDA,120000.00,01,03,2021,00,00"),                     // 1
      gga("120000.00"),                                                 // 2 good
      good_bad_cs,                                                      // 3 bad checksum
      "$GNGGA,120001.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,",  // 4 no '*'
      gga("120001.00").substr(0, 30),                                   // 5 truncated (no '*')
      "$GNGGA,120001.00*ZZ",                                            // 6 non-hex checksum
      sentence("GNGGA,120001.00,4000.0,N"),                             // 7 too few fields
      sentence("GNGGA,120001.00,,,,,1,10,1.0,100.0,M,50.0,M,,"),        // 8 empty position, quality 1
      sentence("GNGGA,120001.00,40x0.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,"),  // 9 bad number
      sentence("GNGGA,126101.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,"),  // 10 minute 61
      sentence("GNGGA,120001.00,4000.0,X,00500.0,E,1,10,1.0,100.0,M,50.0,M,,"),  // 11 hemisphere
      binary,                                                                    // 12 binary junk
      "$" + std::string(5000, 'A'),                                              // 13 huge line
      "garbage text",                                                            // 14
      "12345",                                                              // 15 arrival without sentence
      sentence("GNGSV,1,1,00"),                                             // 16 unused type (not malformed)
      sentence("GNXYZ,1,2,3"),                                              // 17 unused type
      sentence("gngga,1"),                                                  // 18 bad address
      gga("120001.00"),                                                     // 19 good
      gga("120001.00"),                                                     // 20 same epoch: second GGA
      gga("120000.50"),                                                     // 21 out of order
      sentence("GNRMC,120001.50,A,4000.0,N,00500.0,E,1.0,0.0,010321,,,A"),  // 22 epoch without GGA
      gga("120001.00"),  // 23 duplicate of the previous fix
      gga("120002.00"),  // 24 good
      gga("120005.00"),  // 25 good, after a gap
      gga("120006.00"),  // 26 good
      "",                // 27 empty
      sentence("GNGGA,120007.00,4000.0,N,00500.0,E,1,10,1.0,,M,50.0,M,,"),  // 28 empty altitude
      sentence("GNHDT,abc,T"),                                              // 29 bad heading
      sentence("GNZDA,120008.00,31,02,2021,00,00"),                         // 30 impossible date
  };
  std::string text;
  for (std::size_t i = 0; i < lines.size(); ++i) text += lines[i] + (i % 2 ? "\r\n" : "\n");
  const auto log = parse_text(text, {}, "bad.nmea");
  ASSERT_TRUE(log) << log.error().message;
  const LogIssues& is = log->issues;
  const std::string msgs = all_messages(is);
  const std::vector<std::pair<int, std::string>> expected = {
      {3, "bad checksum"}, {4, "no checksum"}, {5, "no checksum"}, {6, "hex"},         {7, "at least 14"},
      {8, "latitude"},     {9, "latitude"},    {10, "time"},       {11, "hemisphere"}, {12, "'$'"},
      {13, "too long"},    {14, "'$'"},        {15, "arrival_ns"}, {18, "address"},    {28, "altitude"},
      {29, "heading"},     {30, "date"},
  };
  for (const auto& [line, part] : expected) {
    EXPECT_TRUE(has_message(is, "bad.nmea:" + std::to_string(line) + ": ", part))
        << line << " " << part << "\n"
        << msgs;
  }
  EXPECT_EQ(is.malformed, expected.size()) << msgs;
  EXPECT_TRUE(has_message(is, "bad.nmea:16: ", "GSV")) << msgs;
  EXPECT_EQ(log->unused_sentences, 2u);
  EXPECT_EQ(is.out_of_order, 1u) << msgs;
  EXPECT_TRUE(has_message(is, "bad.nmea:21: ", "older")) << msgs;
  EXPECT_EQ(is.duplicates, 2u) << msgs;  // the second GGA of an epoch, and the repeated epoch
  EXPECT_TRUE(has_message(is, "bad.nmea:20: ", "second GGA")) << msgs;
  EXPECT_TRUE(has_message(is, "bad.nmea:23: ", "repeats")) << msgs;
  EXPECT_EQ(log->epochs_without_gga, 1u);
  EXPECT_EQ(is.gaps, 1u) << msgs;
  EXPECT_TRUE(has_message(is, "bad.nmea:25: ", "gap")) << msgs;
  ASSERT_EQ(log->fixes.size(), 5u);
  for (std::size_t i = 1; i < log->fixes.size(); ++i) EXPECT_GT(log->fixes[i].t_ns, log->fixes[i - 1].t_ns);
  // Messages quote binary bytes as escapes, never raw.
  for (const std::string& m : is.messages) {
    for (unsigned char c : m) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << m;
  }
  // The same input with a strict malformed fraction is an Error naming the file.
  NmeaOptions strict;
  strict.max_malformed_fraction = 0.1;
  const auto err = parse_text(text, strict, "bad.nmea");
  ASSERT_FALSE(err);
  EXPECT_NE(err.error().message.find("bad.nmea"), std::string::npos);
  EXPECT_NE(err.error().message.find("max_malformed_fraction"), std::string::npos) << err.error().message;
}

TEST(Nmea, ArbitraryBytesNeverCrash) {
  // Pseudo-random byte soup, with and without sentence-like fragments.
  std::uint32_t x = 12345;
  const auto next = [&x] { return x = x * 1664525u + 1013904223u; };
  const std::string fragments[] = {"$GNGGA,", ",",       "*",      "\r\n", "\n",
                                   "123 ",    "$GNRMC,", "4000.0", ",N,",  "$"};
  for (int round = 0; round < 200; ++round) {
    std::string text;
    const int n = static_cast<int>(next() % 400);
    for (int i = 0; i < n; ++i) {
      if (next() % 3 == 0) {
        text += fragments[next() % std::size(fragments)];
      } else {
        text += static_cast<char>(next() >> 24);
      }
    }
    NmeaOptions o;
    o.default_date = CivilDate{2020, 1, 1};
    const auto log = parse_text(text, o, "soup.nmea");
    if (!log) {
      EXPECT_NE(log.error().message.find("soup.nmea"), std::string::npos);
    }
  }
}

TEST(Nmea, MutatedFieldsWithValidChecksumsNeverCrash) {
  // Valid sentences with one character changed and the checksum recomputed, so that the field
  // parsers (not the checksum) meet the junk.
  GpsFix f = make_fix(gps_ns_from_utc({2023, 3, 3}, 3600 * kNsPerSecond), 45.5, -73.5, 50, -30);
  f.ground_speed_mps = 3;
  f.course_rad = 1;
  f.heading_rad = 2;
  f.sigma_ned_m = Eigen::Vector3d(0.1, 0.2, 0.3);
  const std::vector<std::string> base = nmea_sentences(f);
  std::uint32_t x = 777;
  const auto next = [&x] { return x = x * 1664525u + 1013904223u; };
  const char alphabet[] = "0123456789.,-+NSEWTMAVKe *$x";
  std::size_t parsed = 0;
  for (int round = 0; round < 3000; ++round) {
    std::string text;
    for (const std::string& s : base) {
      std::string body = s.substr(1, s.size() - 4);
      if (next() % 2) {
        const std::size_t at = next() % body.size();
        const char c = alphabet[next() % (sizeof alphabet - 1)];
        if (next() % 4 == 0) {
          body.erase(at, 1);
        } else {
          body[at] = c;
        }
      }
      text += sentence(body) + "\r\n";
    }
    const auto log = parse_text(text, {}, "mutated.nmea");
    if (!log) continue;
    ++parsed;
    for (const GpsFix& g : log->fixes) {
      EXPECT_TRUE(std::isfinite(g.antenna.h_m) || g.quality == FixQuality::kInvalid);
    }
  }
  EXPECT_GT(parsed, 100u);
  // Without require_checksum a sentence lacking "*HH" is read.
  NmeaOptions lax;
  lax.require_checksum = false;
  lax.default_date = CivilDate{2020, 1, 1};
  const auto log = parse_text("$GNGGA,120000.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,\n", lax);
  ASSERT_TRUE(log) << log.error().message;
  EXPECT_EQ(log->fixes.size(), 1u);
}

TEST(Nmea, EmptyAndGarbageFilesAreErrors) {
  for (const std::string& text :
       {std::string(), std::string("\n\n"), std::string("hello\nworld\n\x01\x02\n")}) {
    const auto log = parse_text(text, {}, "empty.nmea");
    ASSERT_FALSE(log);
    EXPECT_NE(log.error().message.find("empty.nmea"), std::string::npos) << log.error().message;
    EXPECT_NE(log.error().message.find("no valid GGA sentence"), std::string::npos) << log.error().message;
    EXPECT_EQ(log.error().message.rfind("nav::parse_nmea(): empty.nmea: ", 0), 0u) << log.error().message;
  }
  const auto missing = read_nmea_file("/nonexistent/dir/x.nmea");
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().message.rfind("nav::read_nmea_file(): /nonexistent/dir/x.nmea: ", 0), 0u)
      << missing.error().message;
  const std::string path = test::output_dir("nmea_garbage") + "/garbage.nmea";
  std::ofstream(path) << "\x01\x02 not nmea\n$GPXXX\n";
  const auto garbage = read_nmea_file(path);
  ASSERT_FALSE(garbage);
  EXPECT_EQ(garbage.error().message.rfind("nav::read_nmea_file(): " + path + ": no valid GGA sentence", 0),
            0u)
      << garbage.error().message;
}

TEST(Nmea, WriteFileRoundTrip) {
  const std::string dir = test::output_dir("nmea_write_file");
  std::vector<GpsFix> fixes;
  for (int i = 0; i < 3; ++i) {
    fixes.push_back(make_fix(gps_ns_from_utc({2022, 8, 1}, i * 200'000'000), 10, 20, 30 + i, 5));
  }
  ASSERT_TRUE(write_nmea_file(dir + "/out.nmea", fixes));
  const auto log = read_nmea_file(dir + "/out.nmea");
  ASSERT_TRUE(log) << log.error().message;
  ASSERT_EQ(log->fixes.size(), 3u);
  EXPECT_EQ(log->fixes[2].t_ns, fixes[2].t_ns);
  EXPECT_NEAR(log->fixes[2].antenna.h_m, 32, 1e-9);
  EXPECT_FALSE(write_nmea_file("/nonexistent/dir/out.nmea", fixes));
}

// ------------------------------------------------------------------------------------------
// NmeaStream: the same sentence code one line at a time

// Every field of two fixes, bit for bit (NaN equal to NaN).
void expect_same_fix(const GpsFix& a, const GpsFix& b, const std::string& where) {
  const auto same = [](double x, double y) { return (std::isnan(x) && std::isnan(y)) || x == y; };
  EXPECT_EQ(a.t_ns, b.t_ns) << where;
  EXPECT_EQ(a.arrival_ns, b.arrival_ns) << where;
  EXPECT_TRUE(same(a.antenna.lat_rad, b.antenna.lat_rad)) << where;
  EXPECT_TRUE(same(a.antenna.lon_rad, b.antenna.lon_rad)) << where;
  EXPECT_TRUE(same(a.antenna.h_m, b.antenna.h_m)) << where;
  EXPECT_EQ(a.quality, b.quality) << where;
  EXPECT_EQ(a.satellites, b.satellites) << where;
  EXPECT_EQ(a.hdop, b.hdop) << where;
  EXPECT_EQ(a.geoid_separation_m, b.geoid_separation_m) << where;
  EXPECT_EQ(a.sigma_ned_m.has_value(), b.sigma_ned_m.has_value()) << where;
  if (a.sigma_ned_m && b.sigma_ned_m) {
    EXPECT_EQ(*a.sigma_ned_m, *b.sigma_ned_m) << where;
  }
  EXPECT_EQ(a.ground_speed_mps, b.ground_speed_mps) << where;
  EXPECT_EQ(a.course_rad, b.course_rad) << where;
  EXPECT_EQ(a.heading_rad, b.heading_rad) << where;
}

// A log with every sentence type, junk, repeats and reordering, and arrival prefixes.
std::string mixed_log() {
  std::vector<GpsFix> fixes;
  for (int i = 0; i < 40; ++i) {
    GpsFix f = make_fix(gps_ns_from_utc({2024, 2, 28}, 86390 * kNsPerSecond + i * 250'000'000LL),
                        51.0 + i * 1e-6, -1.0 - i * 2e-6, 6000 + i * 0.1, 36.5);
    f.quality = i % 7 == 3 ? FixQuality::kRtkFloat : FixQuality::kRtkFixed;
    f.ground_speed_mps = 150 + i;
    f.course_rad = 1.5;
    if (i % 3 != 0) f.heading_rad = 1.6;
    if (i % 4 != 0) f.sigma_ned_m = Eigen::Vector3d(0.01, 0.02, 0.03);
    f.arrival_ns = 5'000'000'000 + i * 250'000'000LL + 30'000'000;
    fixes.push_back(f);
  }
  NmeaWriterOptions wo;
  wo.write_arrival_prefix = true;
  std::string text = "# a comment\n" + write_nmea(fixes, wo);
  // Junk after the 10th GGA, a repeated epoch after the 20th, an older one after the 30th.
  const auto after_gga = [&](int n, const std::string& insert) {
    std::size_t at = 0;
    for (int k = 0; k < n; ++k) at = text.find("GNGGA", at + 1);
    at = text.find('\n', at) + 1;
    text.insert(at, insert);
  };
  after_gga(10, "$GNGGA,garbage*00\r\n\x01\x02\xff\n" + sentence("GNGSV,1,1,00") + "\r\n");
  after_gga(20, write_nmea({fixes[19]}) + write_nmea({fixes[5]}));
  return text;
}

TEST(NmeaStream, YieldsTheBatchParsersFixesAndCounts) {
  for (const std::string& text : {mixed_log(), [] {
                                    std::ifstream in(test::data_path("nav/receiver.nmea"), std::ios::binary);
                                    std::stringstream ss;
                                    ss << in.rdbuf();
                                    return ss.str();
                                  }()}) {
    const auto batch = parse_text(text, {}, "log.nmea");
    ASSERT_TRUE(batch) << batch.error().message;
    NmeaStream stream("log.nmea");
    std::vector<GpsFix> live;
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
      stream.push_line(line);
      while (auto f = stream.pop()) live.push_back(*f);
    }
    stream.flush();
    while (auto f = stream.pop()) live.push_back(*f);
    ASSERT_EQ(live.size(), batch->fixes.size());
    for (std::size_t i = 0; i < live.size(); ++i)
      expect_same_fix(live[i], batch->fixes[i], std::to_string(i));
    const NmeaLog& c = stream.counters();
    EXPECT_TRUE(c.fixes.empty());
    EXPECT_EQ(c.lines, batch->lines);
    EXPECT_EQ(c.issues.malformed, batch->issues.malformed);
    EXPECT_EQ(c.issues.duplicates, batch->issues.duplicates);
    EXPECT_EQ(c.issues.out_of_order, batch->issues.out_of_order);
    EXPECT_EQ(c.sentence_counts, batch->sentence_counts);
    EXPECT_EQ(c.unused_sentences, batch->unused_sentences);
    EXPECT_EQ(c.epochs_without_gga, batch->epochs_without_gga);
    // The same messages, less the gap reports (a whole-log check the stream does not make).
    std::vector<std::string> batch_messages;
    for (const std::string& m : batch->issues.messages)
      if (m.find(": gap of ") == std::string::npos) batch_messages.push_back(m);
    EXPECT_EQ(stream.take_messages(), batch_messages);
    EXPECT_TRUE(stream.take_messages().empty());
  }
  // The mixed log has all of it.
  const auto batch = parse_text(mixed_log());
  ASSERT_TRUE(batch);
  EXPECT_EQ(batch->fixes.size(), 40u);
  EXPECT_GE(batch->issues.malformed, 3u);
  EXPECT_EQ(batch->issues.duplicates, 1u);
  EXPECT_EQ(batch->issues.out_of_order, 1u);
}

TEST(NmeaStream, AnEpochIsOutWhenTheNextTimeTagArrives) {
  const std::string gga0 = sentence("GNGGA,120000.00,4000.0,N,00500.0,E,4,10,1.0,100.0,M,50.0,M,,");
  const std::string rmc0 = sentence("GNRMC,120000.00,A,4000.0,N,00500.0,E,2.0,90.0,010321,,,R");
  const std::string hdt = sentence("GNHDT,45.0,T");
  const std::string gga1 = sentence("GNGGA,120000.10,4000.0,N,00500.0,E,5,10,1.0,100.0,M,50.0,M,,");
  NmeaStream s("live");
  EXPECT_FALSE(s.epoch_open());
  s.push_line(gga0 + "\r\n", 1000);
  s.push_line(rmc0, 1500);
  s.push_line(hdt, 1600);
  EXPECT_TRUE(s.epoch_open());
  EXPECT_EQ(s.ready(), 0u);  // it might still grow
  EXPECT_FALSE(s.pop());
  s.push_line(gga1, 101'000);
  ASSERT_EQ(s.ready(), 1u);
  const std::optional<GpsFix> f = s.pop();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->t_ns, gps_ns_from_utc({2021, 3, 1}, 12 * 3600 * kNsPerSecond));
  EXPECT_EQ(f->arrival_ns, 1000);  // the GGA's
  EXPECT_EQ(f->quality, FixQuality::kRtkFixed);
  EXPECT_NEAR(*f->heading_rad, deg_to_rad(45.0), 1e-12);
  EXPECT_NEAR(*f->ground_speed_mps, 2.0 * kKnot, 1e-12);
  // The second epoch has no date of its own: it takes the first one's.
  s.flush();
  const std::optional<GpsFix> g = s.pop();
  ASSERT_TRUE(g);
  EXPECT_EQ(g->t_ns - f->t_ns, 100'000'000);
  EXPECT_EQ(g->quality, FixQuality::kRtkFloat);
  EXPECT_FALSE(s.epoch_open());
  EXPECT_FALSE(s.pop());
}

TEST(NmeaStream, AQuietGapClosesTheEpoch) {
  NmeaStream s("live");
  const std::string zda = sentence("GNZDA,120000.00,01,03,2021,00,00");
  const std::string gga = sentence("GNGGA,120000.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,");
  EXPECT_FALSE(s.flush_if_quiet(1'000'000'000, 10));  // nothing open
  s.push_line(zda, 1'000'000'000);
  s.push_line(gga, 1'002'000'000);
  EXPECT_EQ(s.last_arrival_ns(), 1'002'000'000);
  EXPECT_FALSE(s.flush_if_quiet(1'021'999'999, 20'000'000));  // 19.999999 ms quiet: not yet
  EXPECT_EQ(s.ready(), 0u);
  EXPECT_TRUE(s.flush_if_quiet(1'022'000'000, 20'000'000));
  ASSERT_EQ(s.ready(), 1u);
  EXPECT_EQ(s.pop()->arrival_ns, 1'002'000'000);
  // A VTG of the closed epoch arriving late is named and dropped.
  s.push_line(sentence("GNVTG,91.0,T,,M,3.0,N,5.556,K,A"), 1'030'000'000);
  const std::vector<std::string> m = s.take_messages();
  ASSERT_EQ(m.size(), 1u);
  EXPECT_NE(m[0].find("live:3: VTG after its epoch was closed"), std::string::npos) << m[0];
  EXPECT_FALSE(s.epoch_open());
  // Without arrival times a stream is never closed by quiet.
  NmeaStream t("file");
  t.push_line(gga);
  EXPECT_TRUE(t.epoch_open());
  EXPECT_FALSE(t.flush_if_quiet(std::numeric_limits<TimestampNs>::max(), 1));
}

TEST(NmeaStream, ArrivalArgumentReplacesThePrefix) {
  NmeaOptions o;
  o.default_date = CivilDate{2021, 3, 1};
  NmeaStream s("live", o);
  const std::string gga = sentence("GNGGA,120000.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,");
  s.push_line("777 " + gga, 0);  // the prefix counts when no arrival is given
  s.flush();
  EXPECT_EQ(s.pop()->arrival_ns, 777);
  s.push_line("777 " + sentence("GNGGA,120001.00,4000.0,N,00500.0,E,1,10,1.0,100.0,M,50.0,M,,"), 999);
  s.flush();
  EXPECT_EQ(s.pop()->arrival_ns, 999);
  EXPECT_EQ(s.counters().issues.malformed, 0u);
  // Line numbers in messages count the lines pushed.
  s.push_line("");
  s.push_line("junk");
  const std::vector<std::string> m = s.take_messages();
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].rfind("live:4: ", 0), 0u) << m[0];
  EXPECT_EQ(s.counters().lines, 4u);
}

TEST(NmeaStream, ArbitraryBytesNeverThrowAndMessagesStayBounded) {
  NmeaOptions o;
  o.max_messages = 5;
  NmeaStream s("soup", o);
  std::uint32_t x = 99;
  const auto next = [&x] { return x = x * 1664525u + 1013904223u; };
  for (int i = 0; i < 500; ++i) {
    std::string line;
    const int n = static_cast<int>(next() % 200);
    for (int k = 0; k < n; ++k) line += static_cast<char>(next() >> 24);
    s.push_line(line, 1 + i);
    while (s.pop()) {
    }
  }
  EXPECT_GT(s.counters().issues.malformed, 400u);
  EXPECT_LE(s.take_messages().size(), 6u);  // five and the "suppressed" note
}

}  // namespace
}  // namespace augrig::nav
