// gps_time: GPS time <-> UTC civil time, without timegm(), time zones or the locale.
//
// augrig timestamps in ClockDomain::kGps are int64 nanoseconds since the GPS epoch
// 1980-01-06 00:00:00 (GPS time has no leap seconds). UTC = GPS - leap_seconds, where leap_seconds
// is the GPS-UTC offset in whole seconds: 0 at the GPS epoch, one more at each leap second inserted
// into UTC since, 18 since 2017-01-01. The conversions below take it as a parameter; the table
// kLeapSecondSteps gives the value that applied on any date (leap_seconds_on(), the *_by_table
// conversions), which is what the NMEA reader and writer use unless told a value.
//
// Civil dates use the proleptic Gregorian calendar (H. Hinnant's days_from_civil algorithm).
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "core/conventions.hpp"

namespace augrig::nav {

inline constexpr int kDefaultLeapSeconds = 18;  // GPS - UTC since 2017-01-01
inline constexpr std::int64_t kNsPerSecond = 1'000'000'000;
inline constexpr std::int64_t kNsPerDay = 86'400 * kNsPerSecond;

struct CivilDate {
  int year = 1980;
  int month = 1;  // 1..12
  int day = 6;    // 1..31
  friend bool operator==(const CivilDate&, const CivilDate&) = default;
};

// Days since 1970-01-01 of a Gregorian date (negative before it).
constexpr std::int64_t days_from_civil(int y, int m, int d) {
  y -= m <= 2 ? 1 : 0;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const std::int64_t yoe = y - era * 400;                                    // [0, 399]
  const std::int64_t doy = (153 * (m > 2 ? m - 3 : m + 9) + 2) / 5 + d - 1;  // [0, 365]
  const std::int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;            // [0, 146096]
  return era * 146097 + doe - 719468;
}
constexpr std::int64_t days_from_civil(const CivilDate& c) {
  return days_from_civil(c.year, c.month, c.day);
}

// The Gregorian date of a day count since 1970-01-01.
constexpr CivilDate civil_from_days(std::int64_t z) {
  z += 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const std::int64_t doe = z - era * 146097;
  const std::int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const std::int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const std::int64_t mp = (5 * doy + 2) / 153;
  const int d = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  const int m = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  const int y = static_cast<int>(yoe + era * 400 + (m <= 2 ? 1 : 0));
  return {y, m, d};
}

// Days in a month of a Gregorian year (0 for a month outside 1..12).
constexpr int days_in_month(int year, int month) {
  constexpr int kDays[12] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  if (month < 1 || month > 12) return 0;
  const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
  return kDays[month - 1] + (month == 2 && leap ? 1 : 0);
}

constexpr bool is_valid_date(const CivilDate& c) {
  return c.month >= 1 && c.month <= 12 && c.day >= 1 && c.day <= days_in_month(c.year, c.month);
}

// 1980-01-06, the GPS epoch, in days since 1970-01-01 (3657).
inline constexpr std::int64_t kGpsEpochUnixDays = days_from_civil(1980, 1, 6);

// ---- The range augrig's timestamps may take (docs/NAV_FORMATS.md, "Time range") ----
//
// int64 nanoseconds reach only about 292 years either side of their epoch. Every timestamp read
// from a file or the network is kept within +-kMaxAbsTimestampNs (about 126.8 years) and every time
// offset within +-kMaxAbsTimeOffsetNs, so that any difference of two timestamps and any timestamp
// plus an offset stay inside int64 (no overflow, which would be undefined behaviour). Civil dates
// (NMEA ZDA/RMC, gpsd times, scenario start times) must lie in the years kMinYear..kMaxYear, whose
// GPS times are well inside that bound.
inline constexpr int kMinYear = 1980;
inline constexpr int kMaxYear = 2099;
inline constexpr const char* kYearRangeText = "1980..2099";
inline constexpr std::int64_t kMaxAbsTimestampNs = 4'000'000'000'000'000'000;  // 4e18 ns, ~126.8 years
inline constexpr std::int64_t kMaxAbsTimeOffsetNs = 500'000'000'000'000'000;   // 5e17 ns, ~15.8 years
inline constexpr const char* kTimestampRangeText = "-4e18..4e18 ns";
inline constexpr const char* kTimeOffsetRangeText = "-5e17..5e17 ns (about 15.8 years)";

constexpr bool is_supported_year(int year) {
  return year >= kMinYear && year <= kMaxYear;
}
constexpr bool is_supported_timestamp(std::int64_t t_ns) {
  return t_ns >= -kMaxAbsTimestampNs && t_ns <= kMaxAbsTimestampNs;
}
constexpr bool is_supported_time_offset(std::int64_t offset_ns) {
  return offset_ns >= -kMaxAbsTimeOffsetNs && offset_ns <= kMaxAbsTimeOffsetNs;
}
// Days since 1970-01-01 of the first day of kMinYear and of the day after kMaxYear ends.
inline constexpr std::int64_t kFirstSupportedUnixDay = days_from_civil(kMinYear, 1, 1);
inline constexpr std::int64_t kEndSupportedUnixDay = days_from_civil(kMaxYear + 1, 1, 1);

// A UTC instant as a date and the nanoseconds since that date's midnight. ns_of_day may reach
// 86400 s during an inserted leap second (23:59:60).
struct UtcTime {
  CivilDate date;
  std::int64_t ns_of_day = 0;
};

// ---- GPS - UTC by date (docs/NAV_FORMATS.md, "Time base") ----
//
// The leap seconds inserted into UTC since the GPS epoch (IERS Bulletin C): each at the end of the
// day before `from`, so GPS - UTC = gps_minus_utc_s from `from` 00:00:00 UTC on. None has been
// inserted since 2016-12-31 23:59:60; should IERS Bulletin C announce another, it needs a row here
// (until then the value can be given to the reader).
struct LeapSecondStep {
  CivilDate from;
  int gps_minus_utc_s = 0;
};
inline constexpr std::array<LeapSecondStep, 18> kLeapSecondSteps = {{
    {{1981, 7, 1}, 1},  {{1982, 7, 1}, 2},  {{1983, 7, 1}, 3},  {{1985, 7, 1}, 4},  {{1988, 1, 1}, 5},
    {{1990, 1, 1}, 6},  {{1991, 1, 1}, 7},  {{1992, 7, 1}, 8},  {{1993, 7, 1}, 9},  {{1994, 7, 1}, 10},
    {{1996, 1, 1}, 11}, {{1997, 7, 1}, 12}, {{1999, 1, 1}, 13}, {{2006, 1, 1}, 14}, {{2009, 1, 1}, 15},
    {{2012, 7, 1}, 16}, {{2015, 7, 1}, 17}, {{2017, 1, 1}, 18},
}};

// GPS - UTC on a UTC day (days since 1970-01-01): 0 before 1981-07-01, 18 from 2017-01-01 on.
constexpr int leap_seconds_on_day(std::int64_t unix_day) {
  int leap = 0;
  for (const LeapSecondStep& s : kLeapSecondSteps)
    if (unix_day >= days_from_civil(s.from)) leap = s.gps_minus_utc_s;
  return leap;
}
constexpr int leap_seconds_on(const CivilDate& utc_date) {
  return leap_seconds_on_day(days_from_civil(utc_date));
}

// GPS ns from a UTC date and time of day: (days - GPS epoch) * 86400 s + ns_of_day + leap seconds.
// Only for dates of supported years (is_supported_year()), a ns_of_day within a day (plus a leap
// second) and leap seconds within +-1000: outside those the sum may overflow.
constexpr TimestampNs gps_ns_from_utc(const CivilDate& date, std::int64_t ns_of_day,
                                      int leap_seconds = kDefaultLeapSeconds) {
  return (days_from_civil(date) - kGpsEpochUnixDays) * kNsPerDay + ns_of_day +
         static_cast<std::int64_t>(leap_seconds) * kNsPerSecond;
}

// gps_ns_from_utc() for any input: nullopt when the date is invalid or its year outside
// kMinYear..kMaxYear, ns_of_day outside [0, 86401 s) or |leap_seconds| > 1000.
constexpr std::optional<TimestampNs> gps_ns_from_utc_checked(const CivilDate& date, std::int64_t ns_of_day,
                                                             int leap_seconds = kDefaultLeapSeconds) {
  if (!is_supported_year(date.year) || !is_valid_date(date) || ns_of_day < 0 ||
      ns_of_day >= kNsPerDay + kNsPerSecond || leap_seconds < -1000 || leap_seconds > 1000) {
    return std::nullopt;
  }
  return gps_ns_from_utc(date, ns_of_day, leap_seconds);
}

// GPS ns of a UTC time given as seconds and nanoseconds since 1970-01-01 (a timespec), or nullopt
// when it falls outside the supported years or the nanoseconds outside [0, 1 s).
constexpr std::optional<TimestampNs> gps_ns_from_unix_checked(std::int64_t unix_s, std::int64_t ns,
                                                              int leap_seconds = kDefaultLeapSeconds) {
  if (unix_s < kFirstSupportedUnixDay * 86'400 || unix_s >= kEndSupportedUnixDay * 86'400 || ns < 0 ||
      ns >= kNsPerSecond || leap_seconds < -1000 || leap_seconds > 1000) {
    return std::nullopt;
  }
  return (unix_s - kGpsEpochUnixDays * 86'400) * kNsPerSecond + ns +
         static_cast<std::int64_t>(leap_seconds) * kNsPerSecond;
}

// The UTC date and time of day of a GPS timestamp (ns_of_day in [0, 86400 s)).
constexpr UtcTime utc_from_gps_ns(TimestampNs t_gps_ns, int leap_seconds = kDefaultLeapSeconds) {
  const std::int64_t utc_ns = t_gps_ns - static_cast<std::int64_t>(leap_seconds) * kNsPerSecond;
  std::int64_t days = utc_ns / kNsPerDay;
  std::int64_t rem = utc_ns % kNsPerDay;
  if (rem < 0) {
    rem += kNsPerDay;
    --days;
  }
  return {civil_from_days(days + kGpsEpochUnixDays), rem};
}

// The conversions with the table's GPS - UTC for the date. A time of day in the inserted leap second
// (23:59:60.x, ns_of_day >= 86400 s, on the day before a step) is GPS time continuous with the
// seconds around it; nullopt as gps_ns_from_utc_checked() says.
constexpr std::optional<TimestampNs> gps_ns_from_utc_by_table(const CivilDate& date, std::int64_t ns_of_day) {
  if (!is_supported_year(date.year) || !is_valid_date(date)) return std::nullopt;
  return gps_ns_from_utc_checked(date, ns_of_day, leap_seconds_on(date));
}

// GPS - UTC in force at a GPS instant: the step's value from its first UTC second on (during an
// inserted leap second, 23:59:60, the old value).
constexpr int leap_seconds_at_gps(TimestampNs t_gps_ns) {
  int leap = 0;
  for (const LeapSecondStep& s : kLeapSecondSteps)
    if (t_gps_ns >= gps_ns_from_utc(s.from, 0, s.gps_minus_utc_s)) leap = s.gps_minus_utc_s;
  return leap;
}

// The UTC of a GPS instant with the table's GPS - UTC; inside an inserted leap second it is
// 23:59:60.x of the day before the step (ns_of_day in [86400 s, 86401 s)).
constexpr UtcTime utc_from_gps_ns_by_table(TimestampNs t_gps_ns) {
  for (const LeapSecondStep& s : kLeapSecondSteps) {
    const TimestampNs step_ns = gps_ns_from_utc(s.from, 0, s.gps_minus_utc_s);
    if (t_gps_ns >= step_ns - kNsPerSecond && t_gps_ns < step_ns) {
      return {civil_from_days(days_from_civil(s.from) - 1), kNsPerDay + (t_gps_ns - (step_ns - kNsPerSecond))};
    }
  }
  return utc_from_gps_ns(t_gps_ns, leap_seconds_at_gps(t_gps_ns));
}

}  // namespace augrig::nav
