#include "nav/nmea.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <istream>
#include <set>
#include <sstream>
#include <system_error>
#include <utility>

#include "core/file_check.hpp"

namespace augrig::nav {
namespace {

constexpr double kMpsPerKnot = 1852.0 / 3600.0;
constexpr double kMpsPerKmh = 1000.0 / 3600.0;

// ---------------------------------------------------------------------------------------------
// Small text helpers (locale-independent: std::from_chars / std::to_chars only).

// The text of a line as a message may quote it: non-printable bytes as \xHH, at most `max` chars.
std::string quoted(std::string_view s, std::size_t max = 48) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (out.size() >= max) {
      out += "...";
      break;
    }
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", c);
      out += buf;
    }
  }
  return "'" + out + "'";
}

std::string hex2(unsigned v) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  return {kHex[(v >> 4) & 0xf], kHex[v & 0xf]};
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

bool all_digits(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// A finite decimal number filling the whole field ("-12.5", "0.9"); no '+', no exponent-only junk.
bool parse_double(std::string_view s, double& out) {
  if (s.empty()) return false;
  const char* first = s.data();
  if (*first == '+') ++first;  // tolerated
  const char* last = s.data() + s.size();
  auto [p, ec] = std::from_chars(first, last, out, std::chars_format::fixed);
  return ec == std::errc() && p == last && std::isfinite(out);
}

bool parse_int(std::string_view s, int& out) {
  if (s.empty()) return false;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && p == s.data() + s.size();
}

// Fixed-point text with `decimals` digits, never "-0.000".
std::string fixed(double v, int decimals) {
  char buf[64];
  auto [p, ec] = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  if (ec != std::errc()) return {};
  std::string s(buf, p);
  if (s[0] == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);
  return s;
}

std::string two_digits(int v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%02d", v);
  return buf;
}

std::string format_tod(std::int64_t ns_of_day) {
  if (ns_of_day >= kNsPerDay) return "2359" + two_digits(static_cast<int>(60 + (ns_of_day - kNsPerDay) / kNsPerSecond));
  return two_digits(static_cast<int>(ns_of_day / (3600 * kNsPerSecond))) +
         two_digits(static_cast<int>(ns_of_day / (60 * kNsPerSecond) % 60)) +
         two_digits(static_cast<int>(ns_of_day / kNsPerSecond % 60));
}

// "12:35:19.250" for messages.
std::string clock_text(std::int64_t ns_of_day) {
  if (ns_of_day >= kNsPerDay) {  // 23:59:60.x, an inserted leap second
    char buf[32];
    std::snprintf(buf, sizeof buf, "23:59:60.%03d", static_cast<int>((ns_of_day - kNsPerDay) / 1'000'000 % 1000));
    return buf;
  }
  const std::int64_t ms = ns_of_day / 1'000'000;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%02d:%02d:%02d.%03d", static_cast<int>(ms / 3'600'000),
                static_cast<int>(ms / 60'000 % 60), static_cast<int>(ms / 1000 % 60),
                static_cast<int>(ms % 1000));
  return buf;
}

std::string date_text(const CivilDate& d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02d", d.year, d.month, d.day);
  return buf;
}

// ---------------------------------------------------------------------------------------------
// Field parsers. Each returns an empty string on success, else what was wrong.

// hhmmss[.f...] -> ns since midnight. Second 60 (leap second) is accepted.
std::string parse_tod(std::string_view s, std::int64_t& ns) {
  const std::string expected = "expected the UTC time hhmmss.sss, got " + quoted(s);
  if (s.size() < 6 || !all_digits(s.substr(0, 6))) return expected;
  const int hh = (s[0] - '0') * 10 + (s[1] - '0');
  const int mm = (s[2] - '0') * 10 + (s[3] - '0');
  const int ss = (s[4] - '0') * 10 + (s[5] - '0');
  if (hh > 23 || mm > 59 || ss > 60) return expected;
  std::int64_t frac_ns = 0;
  if (s.size() > 6) {
    const std::string_view frac = s.substr(7);
    if (s[6] != '.' || (!frac.empty() && !all_digits(frac)) || frac.size() > 9) return expected;
    std::int64_t scale = 100'000'000;
    for (char c : frac) {
      frac_ns += (c - '0') * scale;
      scale /= 10;
    }
  }
  ns = ((hh * 60 + mm) * 60 + ss) * kNsPerSecond + frac_ns;
  return {};
}

// ddmm.mmmm / dddmm.mmmm plus hemisphere -> degrees.
std::string parse_angle(std::string_view value, std::string_view hemi, bool latitude, double& deg) {
  const char* what = latitude ? "latitude ddmm.mmmm" : "longitude dddmm.mmmm";
  const std::string expected = std::string("expected the ") + what + ", got " + quoted(value);
  const std::size_t dot = std::min(value.find('.'), value.size());
  if (dot < 3 || dot > (latitude ? 4u : 5u) || !all_digits(value.substr(0, dot))) return expected;
  int d = 0;
  double minutes = 0;
  if (!parse_int(value.substr(0, dot - 2), d) || !parse_double(value.substr(dot - 2), minutes) ||
      minutes >= 60.0) {
    return expected;
  }
  deg = d + minutes / 60.0;
  if (deg > (latitude ? 90.0 : 180.0)) return expected;
  if (hemi == (latitude ? "S" : "W")) {
    deg = -deg;
  } else if (hemi != (latitude ? "N" : "E")) {
    return std::string("expected the hemisphere ") + (latitude ? "N or S" : "E or W") + ", got " +
           quoted(hemi);
  }
  return {};
}

std::string parse_number(std::string_view s, double& v, const char* what) {
  if (!parse_double(s, v)) return std::string("expected ") + what + ", got " + quoted(s);
  return {};
}

// ---------------------------------------------------------------------------------------------
// Parsed sentences.

struct Gga {
  std::int64_t tod_ns = 0;
  int quality = 0;
  int satellites = 0;
  double hdop = 0;
  double lat_deg = NAN, lon_deg = NAN, alt_msl_m = NAN;
  double separation_m = 0;
};

struct Velocity {
  std::optional<double> speed_mps;
  std::optional<double> course_rad;
};

using Fields = std::vector<std::string_view>;

std::string field_error(std::size_t index, const char* name, const std::string& what) {
  return "field " + std::to_string(index) + " (" + name + "): " + what;
}

std::string need_fields(const Fields& f, std::size_t n) {
  if (f.size() - 1 >= n) return {};
  return "expected at least " + std::to_string(n) + " fields, got " + std::to_string(f.size() - 1);
}

// Fields are numbered as in the NMEA standard: f[0] is the address, f[1] the first data field.
std::string parse_gga(const Fields& f, Gga& g) {
  if (auto e = need_fields(f, 14); !e.empty()) return e;
  if (auto e = parse_tod(f[1], g.tod_ns); !e.empty()) return field_error(1, "time", e);
  if (!parse_int(f[6], g.quality) || g.quality < 0 || g.quality > 8) {
    return field_error(6, "quality", "expected a fix quality 0..8, got " + quoted(f[6]));
  }
  const bool position_empty = f[2].empty() && f[3].empty() && f[4].empty() && f[5].empty();
  if (!(g.quality == 0 && position_empty)) {
    if (auto e = parse_angle(f[2], f[3], true, g.lat_deg); !e.empty()) return field_error(2, "latitude", e);
    if (auto e = parse_angle(f[4], f[5], false, g.lon_deg); !e.empty()) {
      return field_error(4, "longitude", e);
    }
  }
  if (!f[7].empty() && (!parse_int(f[7], g.satellites) || g.satellites < 0)) {
    return field_error(7, "satellites", "expected a count, got " + quoted(f[7]));
  }
  if (!f[8].empty()) {
    if (auto e = parse_number(f[8], g.hdop, "a number"); !e.empty()) return field_error(8, "HDOP", e);
  }
  if (!(g.quality == 0 && f[9].empty())) {
    if (auto e = parse_number(f[9], g.alt_msl_m, "the altitude above MSL in metres"); !e.empty()) {
      return field_error(9, "altitude", e);
    }
  }
  if (!f[10].empty() && f[10] != "M")
    return field_error(10, "altitude unit", "expected M, got " + quoted(f[10]));
  if (!f[11].empty()) {
    if (auto e = parse_number(f[11], g.separation_m, "the geoid separation in metres"); !e.empty()) {
      return field_error(11, "geoid separation", e);
    }
  }
  if (!f[12].empty() && f[12] != "M") {
    return field_error(12, "separation unit", "expected M, got " + quoted(f[12]));
  }
  return {};
}

std::string parse_course_speed(std::string_view course, std::string_view knots, Velocity& v, std::size_t ci,
                               std::size_t si) {
  double x = 0;
  if (!knots.empty()) {
    if (auto e = parse_number(knots, x, "the speed in knots"); !e.empty()) return field_error(si, "speed", e);
    if (x < 0) return field_error(si, "speed", "expected a speed >= 0, got " + quoted(knots));
    v.speed_mps = x * kMpsPerKnot;
  }
  if (!course.empty()) {
    if (auto e = parse_number(course, x, "the course in degrees"); !e.empty()) {
      return field_error(ci, "course", e);
    }
    v.course_rad = deg_to_rad(x);
  }
  return {};
}

std::string parse_rmc(const Fields& f, std::int64_t& tod, std::optional<CivilDate>& date, Velocity& v) {
  if (auto e = need_fields(f, 11); !e.empty()) return e;
  if (auto e = parse_tod(f[1], tod); !e.empty()) return field_error(1, "time", e);
  if (f[2] != "A" && f[2] != "V") return field_error(2, "status", "expected A or V, got " + quoted(f[2]));
  if (!f[9].empty()) {
    if (f[9].size() != 6 || !all_digits(f[9])) {
      return field_error(9, "date", "expected ddmmyy, got " + quoted(f[9]));
    }
    const auto two = [&](std::size_t i) { return (f[9][i] - '0') * 10 + (f[9][i + 1] - '0'); };
    const int yy = two(4);
    const CivilDate d{yy < 80 ? 2000 + yy : 1900 + yy, two(2), two(0)};
    if (!is_valid_date(d)) return field_error(9, "date", "expected ddmmyy, got " + quoted(f[9]));
    date = d;
  }
  const bool mode_invalid = f.size() > 12 && f[12] == "N";
  if (f[2] == "A" && !mode_invalid) return parse_course_speed(f[8], f[7], v, 8, 7);
  return {};
}

std::string parse_vtg(const Fields& f, Velocity& v) {
  if (f.size() - 1 >= 8 && f[2] == "T") {        // NMEA 2.3+: course,T,course,M,knots,N,kmh,K[,mode]
    if (f.size() > 9 && f[9] == "N") return {};  // mode: not valid
    if (auto e = parse_course_speed(f[1], f[5], v, 1, 5); !e.empty()) return e;
    if (!v.speed_mps && !f[7].empty()) {
      double kmh = 0;
      if (auto e = parse_number(f[7], kmh, "the speed in km/h"); !e.empty())
        return field_error(7, "speed", e);
      v.speed_mps = kmh * kMpsPerKmh;
    }
    return {};
  }
  if (f.size() - 1 == 4) return parse_course_speed(f[1], f[3], v, 1, 3);  // old: course,course_mag,knots,kmh
  return "expected 'course,T,course,M,knots,N,km/h,K[,mode]', got " + std::to_string(f.size() - 1) +
         " fields";
}

std::string parse_hdt(const Fields& f, std::optional<double>& heading_rad) {
  if (auto e = need_fields(f, 2); !e.empty()) return e;
  if (!f[2].empty() && f[2] != "T") return field_error(2, "reference", "expected T, got " + quoted(f[2]));
  if (f[1].empty()) return {};  // no heading solution
  double deg = 0;
  if (auto e = parse_number(f[1], deg, "the heading in degrees"); !e.empty())
    return field_error(1, "heading", e);
  heading_rad = deg_to_rad(deg);
  return {};
}

std::string parse_gst(const Fields& f, std::int64_t& tod, std::optional<Eigen::Vector3d>& sigma) {
  if (auto e = need_fields(f, 8); !e.empty()) return e;
  if (auto e = parse_tod(f[1], tod); !e.empty()) return field_error(1, "time", e);
  if (f[6].empty() || f[7].empty() || f[8].empty()) return {};  // no estimate
  Eigen::Vector3d s;
  static constexpr const char* kNames[3] = {"sigma latitude", "sigma longitude", "sigma altitude"};
  for (int i = 0; i < 3; ++i) {
    if (auto e = parse_number(f[6 + i], s[i], "a standard deviation in metres"); !e.empty()) {
      return field_error(6 + i, kNames[i], e);
    }
    if (s[i] < 0) return field_error(6 + i, kNames[i], "expected a value >= 0, got " + quoted(f[6 + i]));
  }
  sigma = s;
  return {};
}

std::string parse_zda(const Fields& f, std::int64_t& tod, CivilDate& date) {
  if (auto e = need_fields(f, 4); !e.empty()) return e;
  if (auto e = parse_tod(f[1], tod); !e.empty()) return field_error(1, "time", e);
  if (!parse_int(f[2], date.day) || !parse_int(f[3], date.month) || f[4].size() != 4 ||
      !parse_int(f[4], date.year) || !is_valid_date(date)) {
    return field_error(2, "date",
                       "expected day,month,year (dd,mm,yyyy), got " +
                           quoted(std::string(f[2]) + "," + std::string(f[3]) + "," + std::string(f[4])));
  }
  // Later or earlier years would overflow the int64 ns of GPS time (nav/gps_time.hpp).
  if (!is_supported_year(date.year)) {
    return field_error(4, "year",
                       std::string("expected a year in ") + kYearRangeText + ", got " + quoted(f[4]));
  }
  return {};
}

// u-blox $PUBX,04: hhmmss.ss,ddmmyy,utcTow,utcWk,leapSec[D],clkBias,clkDrift,tpGran. utcTow and utcWk
// count UTC from the GPS epoch in weeks and seconds (no leap seconds), so they must agree with the
// date and time; leapSec is GPS - UTC, with a 'D' when it is the firmware's default (the receiver
// has not yet received it from the satellites). Fields numbered from the message id, "04", as 1.
struct Pubx04 {
  std::int64_t tod_ns = 0;
  CivilDate date;
  int leap_seconds = 0;
  bool leap_is_default = false;
};

std::string parse_pubx04(const Fields& f, Pubx04& p) {
  if (auto e = need_fields(f, 6); !e.empty()) return e;
  if (auto e = parse_tod(f[2], p.tod_ns); !e.empty()) return field_error(2, "time", e);
  const std::string_view d = f[3];
  if (d.size() != 6 || !all_digits(d)) return field_error(3, "date", "expected ddmmyy, got " + quoted(d));
  const auto two = [&](std::size_t i) { return (d[i] - '0') * 10 + (d[i + 1] - '0'); };
  const int yy = two(4);
  p.date = {yy < 80 ? 2000 + yy : 1900 + yy, two(2), two(0)};
  if (!is_valid_date(p.date)) return field_error(3, "date", "expected ddmmyy, got " + quoted(d));
  double tow = 0;
  int week = 0;
  if (!parse_double(f[4], tow) || tow < 0 || tow >= 604801)
    return field_error(4, "UTC time of week", "expected seconds in [0, 604801), got " + quoted(f[4]));
  if (!parse_int(f[5], week) || week < 0 || week > 10000)
    return field_error(5, "UTC week", "expected a week number 0..10000, got " + quoted(f[5]));
  std::string_view leap = f[6];
  p.leap_is_default = !leap.empty() && leap.back() == 'D';
  if (p.leap_is_default) leap.remove_suffix(1);
  if (!all_digits(leap) || leap.size() > 2 || !parse_int(leap, p.leap_seconds))
    return field_error(6, "leap seconds", "expected GPS - UTC in whole seconds (0..99, 'D' for the default), got " +
                                              quoted(f[6]));
  // Week and time of week against the date and time: the same UTC second count, to rounding.
  const double from_date = static_cast<double>((days_from_civil(p.date) - kGpsEpochUnixDays) * 86'400) +
                           static_cast<double>(p.tod_ns) * 1e-9;
  if (std::abs(from_date - (week * 604'800.0 + tow)) > 1.0) {
    return field_error(4, "UTC time of week",
                       "week " + std::to_string(week) + ", " + quoted(f[4]) + " s does not match the date and time " +
                           date_text(p.date) + " " + clock_text(p.tod_ns));
  }
  return {};
}

// ---------------------------------------------------------------------------------------------
// The parser state.

struct Epoch {
  std::int64_t tod_ns = 0;
  std::size_t line = 0;  // first line of the epoch
  std::optional<CivilDate> date;
  std::optional<Gga> gga;
  std::size_t gga_line = 0;
  TimestampNs gga_arrival_ns = 0;
  TimestampNs first_arrival_ns = 0;
  Velocity velocity;
  std::optional<double> heading_rad;
  std::optional<Eigen::Vector3d> sigma_ned_m;
};

FixQuality to_quality(int q) {
  return q >= 1 && q <= 6 ? static_cast<FixQuality>(q) : FixQuality::kInvalid;
}

// A fix made from a closed epoch, with the line of its GGA (for messages).
struct EmittedFix {
  GpsFix fix;
  std::size_t line = 0;
};

// The sentence code shared by the batch parser (parse_nmea) and the live NmeaStream: one line at a
// time in, epochs merged by time tag, fixes out through `out`. Line numbers count every line pushed.
class SentenceCore {
 public:
  SentenceCore(const std::string& name, const NmeaOptions& o) : name_(name), o_(o) {
    log_.leap_seconds.given = o.leap_seconds;
  }

  // `arrival_override` (!= 0) replaces the line's own "<arrival_ns> " prefix.
  void line(std::string_view s, TimestampNs arrival_override = 0) {
    ++log_.lines;
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ' || s.back() == '\t')) {
      s.remove_suffix(1);
    }
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    if (s.empty()) return;
    ++nonempty_;
    line_no_ = log_.lines;

    TimestampNs arrival_ns = 0;
    if (s.front() >= '0' && s.front() <= '9') {
      const std::size_t sp = s.find(' ');
      std::int64_t v = 0;
      const auto [p, ec] = std::from_chars(s.data(), s.data() + std::min(sp, s.size()), v);
      if (sp == std::string_view::npos || ec != std::errc() || p != s.data() + sp) {
        return malformed("expected '$...' or '<arrival_ns> $...', got " + quoted(s));
      }
      arrival_ns = v;
      s.remove_prefix(sp + 1);
      while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
    }
    if (arrival_override != 0) arrival_ns = arrival_override;
    if (arrival_ns != 0) last_arrival_ns_ = arrival_ns;
    if (s.size() > o_.max_line_length) {
      return malformed("line too long (" + std::to_string(s.size()) + " characters, at most " +
                       std::to_string(o_.max_line_length) + ")");
    }
    if (s.empty() || s.front() != '$')
      return malformed("expected a sentence starting with '$', got " + quoted(s));
    std::string_view body = s.substr(1);
    const std::size_t star = body.rfind('*');
    if (star == std::string_view::npos) {
      if (o_.require_checksum) return malformed("no checksum ('*HH' missing): " + quoted(s));
    } else {
      const std::string_view cs = body.substr(star + 1);
      body = body.substr(0, star);
      if (cs.size() != 2 || hex_value(cs[0]) < 0 || hex_value(cs[1]) < 0) {
        return malformed("expected 2 hex digits after '*', got " + quoted(cs));
      }
      const unsigned got = static_cast<unsigned>(hex_value(cs[0]) * 16 + hex_value(cs[1]));
      const unsigned computed = nmea_checksum(body);
      if (got != computed) {
        return malformed("bad checksum (got " + hex2(got) + ", computed " + hex2(computed) +
                         "): " + quoted(s));
      }
    }
    for (char c : body) {
      const auto u = static_cast<unsigned char>(c);
      if (u < 0x20 || u >= 0x7f || c == '$' || c == '*') {
        return malformed("unexpected character in the sentence: " + quoted(s));
      }
    }
    Fields f;
    for (std::size_t start = 0;;) {
      const std::size_t comma = body.find(',', start);
      f.push_back(
          body.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    const std::string_view address = f[0];
    const bool alnum = std::all_of(address.begin(), address.end(),
                                   [](char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'); });
    if (address.empty() || !alnum || (address[0] != 'P' && address.size() != 5)) {
      return malformed("expected an address field like GPGGA, got " + quoted(address));
    }
    const std::string type(address[0] == 'P' ? address : address.substr(2));
    ++log_.sentence_counts[type];
    sentence(type, f, arrival_ns);
  }

  // Closes the open epoch, if any: its fix (when it makes one) goes to `out`.
  void close() {
    if (epoch_) close_epoch();
  }
  bool epoch_open() const { return epoch_.has_value(); }
  TimestampNs last_arrival_ns() const { return last_arrival_ns_; }

  NmeaLog& log() { return log_; }
  const NmeaLog& log() const { return log_; }
  std::size_t nonempty_lines() const { return nonempty_; }
  const std::string& first_malformed() const { return first_malformed_; }
  const std::string& name() const { return name_; }
  const NmeaOptions& options() const { return o_; }
  std::string at(std::size_t line) const { return name_ + ":" + std::to_string(line) + ": "; }

  void report(const std::string& what) {
    auto& m = log_.issues.messages;
    if (m.size() < o_.max_messages) {
      m.push_back(what);
    } else if (m.size() == o_.max_messages) {
      m.push_back(name_ + ": further messages suppressed (the counts stay exact)");
    }
  }

  std::deque<EmittedFix> out;  // fixes of closed epochs, oldest first

 private:
  void malformed(const std::string& what) {
    ++log_.issues.malformed;
    if (first_malformed_.empty()) first_malformed_ = at(line_no_) + what;
    report(at(line_no_) + what);
  }

  // Starts a new epoch when the time tag differs from the current one.
  Epoch& epoch_for(std::int64_t tod_ns) {
    if (epoch_ && epoch_->tod_ns != tod_ns) close_epoch();
    if (!epoch_) {
      epoch_.emplace();
      epoch_->tod_ns = tod_ns;
      epoch_->line = line_no_;
    }
    return *epoch_;
  }

  void sentence(const std::string& type, const Fields& f, TimestampNs arrival_ns) {
    const auto bad = [&](const std::string& e) { malformed(type + " " + e); };
    std::int64_t tod = 0;
    Epoch* e = nullptr;
    if (type == "GGA") {
      Gga g;
      if (auto err = parse_gga(f, g); !err.empty()) return bad(err);
      e = &epoch_for(g.tod_ns);
      if (e->gga) {
        ++log_.issues.duplicates;
        report(at(line_no_) + "second GGA for " + clock_text(g.tod_ns) + " (line " +
               std::to_string(e->gga_line) + " has one): dropped");
        return;
      }
      e->gga = g;
      e->gga_line = line_no_;
      e->gga_arrival_ns = arrival_ns;
    } else if (type == "RMC") {
      std::optional<CivilDate> date;
      Velocity v;
      if (auto err = parse_rmc(f, tod, date, v); !err.empty()) return bad(err);
      e = &epoch_for(tod);
      if (date && !e->date) e->date = date;
      merge(*e, v);
    } else if (type == "ZDA") {
      CivilDate date;
      if (auto err = parse_zda(f, tod, date); !err.empty()) return bad(err);
      e = &epoch_for(tod);
      if (!e->date) e->date = date;
    } else if (type == "GST") {
      std::optional<Eigen::Vector3d> sigma;
      if (auto err = parse_gst(f, tod, sigma); !err.empty()) return bad(err);
      e = &epoch_for(tod);
      if (sigma && !e->sigma_ned_m) e->sigma_ned_m = sigma;
    } else if (type == "VTG" || type == "HDT") {
      Velocity v;
      std::optional<double> heading;
      if (auto err = type == "VTG" ? parse_vtg(f, v) : parse_hdt(f, heading); !err.empty()) return bad(err);
      if (!epoch_) {
        // A batch parse closes epochs only when the next one starts, so this happens there only
        // before the first epoch; a live stream also closes them when the sender goes quiet.
        report(at(line_no_) + type +
               (last_tod_ns_ ? " after its epoch was closed (the sender went quiet mid-epoch): dropped"
                             : " before any time-tagged sentence (it has no time of its own): dropped"));
        return;
      }
      e = &*epoch_;
      merge(*e, v);
      if (heading && !e->heading_rad) e->heading_rad = heading;
    } else if (type == "PUBX" && f.size() > 1 && f[1] == "04") {
      // The receiver's GPS - UTC: in force from this line on (from the open epoch on). Its time tag
      // does not open an epoch: it is the receiver's clock, which may lead the fixes'.
      Pubx04 p;
      if (auto err = parse_pubx04(f, p); !err.empty()) return bad(err);
      LeapSecondsUse& use = log_.leap_seconds;
      if (p.leap_is_default) {
        if (use.receiver_default_reports++ == 0) {
          report(at(line_no_) + "PUBX,04 gives the receiver's default leap seconds (" + std::string(f[6]) +
                 "), not yet received from the satellites: not used (further ones counted silently)");
        }
        return;
      }
      ++use.receiver_reports;
      use.receiver_value = p.leap_seconds;
      receiver_leap_line_ = line_no_;
      return;
    } else {
      ++log_.unused_sentences;
      if (unused_types_.insert(type).second) {
        report(at(line_no_) + "sentence type " + type + " is not read (further ones are counted silently)");
      }
      return;
    }
    if (arrival_ns != 0 && e->first_arrival_ns == 0) e->first_arrival_ns = arrival_ns;
  }

  static void merge(Epoch& e, const Velocity& v) {
    if (v.speed_mps && !e.velocity.speed_mps) e.velocity.speed_mps = v.speed_mps;
    if (v.course_rad && !e.velocity.course_rad) e.velocity.course_rad = v.course_rad;
  }

  void close_epoch() {
    Epoch e = std::move(*epoch_);
    epoch_.reset();
    // Date: explicit (ZDA/RMC) wins; else the last date, plus one day when the time of day jumped
    // back by more than 12 h (midnight); else the default date.
    if (e.date) {
      day_ = days_from_civil(*e.date);
    } else if (day_) {
      if (last_tod_ns_ && e.tod_ns < *last_tod_ns_ - kNsPerDay / 2) ++*day_;
    } else if (o_.default_date) {
      day_ = days_from_civil(*o_.default_date);
    }
    last_tod_ns_ = e.tod_ns;
    if (!e.gga) {
      if (log_.epochs_without_gga++ == 0) {
        report(at(e.line) + "time tag " + clock_text(e.tod_ns) +
               " has no GGA sentence: no fix (further such epochs are counted silently)");
      }
      return;
    }
    if (!day_) {
      ++log_.fixes_without_date;
      report(at(e.gga_line) + "GGA at " + clock_text(e.tod_ns) +
             " before any date (no ZDA/RMC yet and no NmeaOptions::default_date): dropped");
      return;
    }
    const Gga& g = *e.gga;
    GpsFix fix;
    // GPS - UTC: given, else the receiver's latest report, else the table's for the date.
    const LeapSecondsUse& use = log_.leap_seconds;
    const int table = leap_seconds_on_day(*day_);
    const int leap = o_.leap_seconds ? *o_.leap_seconds : use.receiver_value ? *use.receiver_value : table;
    // Checked: a default date, or a date carried past midnights, outside the supported years
    // would overflow the int64 ns (nav/gps_time.hpp).
    const auto t_ns = gps_ns_from_utc_checked(civil_from_days(*day_), e.tod_ns, leap);
    if (!t_ns) {
      ++log_.issues.malformed;
      const std::string what = at(e.gga_line) + "GGA at " + date_text(civil_from_days(*day_)) + " " +
                               clock_text(e.tod_ns) + ": expected a date in the years " + kYearRangeText +
                               " and leap seconds within +-1000 (got " + std::to_string(leap) +
                               "): dropped";
      if (first_malformed_.empty()) first_malformed_ = what;
      report(what);
      return;
    }
    fix.t_ns = *t_ns;
    fix.arrival_ns = e.gga_arrival_ns != 0 ? e.gga_arrival_ns : e.first_arrival_ns;
    fix.antenna = {deg_to_rad(g.lat_deg), deg_to_rad(g.lon_deg), g.alt_msl_m + g.separation_m};
    fix.quality = to_quality(g.quality);
    fix.satellites = g.satellites;
    fix.hdop = g.hdop;
    fix.geoid_separation_m = g.separation_m;
    fix.sigma_ned_m = e.sigma_ned_m;
    fix.ground_speed_mps = e.velocity.speed_mps;
    fix.course_rad = e.velocity.course_rad;
    fix.heading_rad = e.heading_rad;
    if (g.quality > 6) {
      report(at(e.gga_line) + "GGA quality " + std::to_string(g.quality) +
             " (manual/simulated) kept as invalid");
    }
    if (last_fix_t_ns_) {
      const TimestampNs prev = *last_fix_t_ns_;
      if (fix.t_ns <= prev) {
        const bool dup = fix.t_ns == prev;
        ++(dup ? log_.issues.duplicates : log_.issues.out_of_order);
        report(at(e.gga_line) + "fix at " + date_text(civil_from_days(*day_)) + " " + clock_text(e.tod_ns) +
               (dup ? " repeats the previous fix's time"
                    : " is older than the previous fix (line " + std::to_string(last_fix_line_) + ")") +
               ": dropped");
        return;
      }
    }
    last_fix_t_ns_ = fix.t_ns;
    last_fix_line_ = e.gga_line;
    note_leap(leap, table, e.gga_line);
    out.push_back({fix, e.gga_line});
  }

  // Counts the value a kept fix was converted with against what the receiver and the table say.
  void note_leap(int leap, int table, std::size_t line) {
    LeapSecondsUse& use = log_.leap_seconds;
    ++use.applied[leap];
    if (!o_.leap_seconds) ++(use.receiver_value ? use.from_receiver : use.from_table);
    const CivilDate date = civil_from_days(*day_);
    if (!use.first_date) use.first_date = date;
    use.last_date = date;
    const int expected = use.receiver_value ? *use.receiver_value : table;
    std::string what;
    if (leap != expected) {
      const int late = leap - expected;
      what = at(line) + "GPS-UTC " + std::to_string(leap) + " s given, but " +
             (use.receiver_value ? "the receiver reports " + std::to_string(expected) + " s (PUBX,04, line " +
                                       std::to_string(receiver_leap_line_) + ")"
                                 : "it was " + std::to_string(expected) + " s on " + date_text(date) +
                                       " (the leap-second table)") +
             ": the fix times are " + std::to_string(std::abs(late)) + " s " + (late > 0 ? "late" : "early");
    } else if (use.receiver_value && *use.receiver_value != table) {
      what = at(line) + "the receiver reports GPS-UTC " + std::to_string(*use.receiver_value) + " s (PUBX,04, line " +
             std::to_string(receiver_leap_line_) + ") where the leap-second table gives " + std::to_string(table) +
             " s for " + date_text(date) + ": the receiver's value is used";
    }
    if (what.empty()) return;
    if (use.disagreements++ == 0) {
      use.first_disagreement = what;
      report(what + " (further such fixes counted silently)");
    }
  }

  std::string name_;
  NmeaOptions o_;
  NmeaLog log_;  // counters and messages; `fixes` stays empty here
  std::optional<Epoch> epoch_;
  std::optional<std::int64_t> day_;  // UTC day (days since 1970-01-01) of the current epoch
  std::optional<std::int64_t> last_tod_ns_;
  std::optional<TimestampNs> last_fix_t_ns_;
  std::size_t last_fix_line_ = 0;
  std::size_t receiver_leap_line_ = 0;  // of the PUBX,04 that gave LeapSecondsUse::receiver_value
  TimestampNs last_arrival_ns_ = 0;
  std::set<std::string> unused_types_;
  std::size_t nonempty_ = 0;
  std::size_t line_no_ = 0;
  std::string first_malformed_;
};

// The batch parser: every line through the core, then the whole-log checks (gaps, the
// malformed fraction, no usable fix).
class Parser {
 public:
  Parser(const std::string& prefix, const std::string& name, const NmeaOptions& o)
      : prefix_(prefix), core_(name, o) {}

  void line(std::string_view s) { core_.line(s); }

  Expected<NmeaLog> finish() {
    core_.close();
    NmeaLog& log = core_.log();
    for (EmittedFix& f : core_.out) {
      log.fixes.push_back(f.fix);
      fix_lines_.push_back(f.line);
    }
    core_.out.clear();
    count_gaps(log);
    const NmeaOptions& o = core_.options();
    const std::string prefix = prefix_ + core_.name() + ": ";
    const std::size_t malformed = log.issues.malformed;
    const std::size_t nonempty = core_.nonempty_lines();
    const std::string& first_malformed = core_.first_malformed();
    if (nonempty > 0 && static_cast<double>(malformed) > o.max_malformed_fraction * nonempty) {
      return make_error(prefix, malformed, " of ", nonempty,
                        " lines malformed (more than max_malformed_fraction ",
                        fixed(o.max_malformed_fraction, 3), "); first: ", first_malformed);
    }
    if (log.fixes.empty()) {
      const auto it = log.sentence_counts.find("GGA");
      if (it == log.sentence_counts.end()) {
        return make_error(prefix, "no valid GGA sentence (", log.lines, " lines, ", malformed, " malformed",
                          first_malformed.empty() ? "" : "; first: " + first_malformed, ")");
      }
      return make_error(prefix, "no usable GGA fix among ", it->second, " GGA sentences (",
                        log.fixes_without_date, " before any date: set NmeaOptions::default_date; ",
                        malformed, " malformed lines",
                        log.issues.messages.empty() ? "" : "; first: " + log.issues.messages.front(), ")");
    }
    return std::move(log);
  }

 private:
  void count_gaps(NmeaLog& log) {
    const auto& fx = log.fixes;
    if (fx.size() < 3) return;
    std::vector<TimestampNs> d;
    for (std::size_t i = 1; i < fx.size(); ++i) d.push_back(fx[i].t_ns - fx[i - 1].t_ns);
    std::vector<TimestampNs> sorted = d;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const TimestampNs median = sorted[sorted.size() / 2];
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (d[i] - median > median) {  // d[i] > 2 * median without overflowing
        ++log.issues.gaps;
        core_.report(core_.at(fix_lines_[i + 1]) + "gap of " + fixed(ns_to_s(d[i]), 3) +
                     " s before this fix (median period " + fixed(ns_to_s(median), 3) + " s)");
      }
    }
  }

  std::string prefix_;
  SentenceCore core_;
  std::vector<std::size_t> fix_lines_;
};

// ---------------------------------------------------------------------------------------------
// Writer helpers.

// ddmm.mmmmmmmm (latitude) / dddmm.mmmmmmmm (longitude) and the hemisphere, rounded in integer
// units of 1e-8 arc minutes so that 59.999999999 never prints as "60".
std::string angle_fields(double deg, bool latitude) {
  if (!std::isfinite(deg)) return ",";
  constexpr std::int64_t kUnitsPerMinute = 100'000'000;
  const std::int64_t units = std::llround(std::abs(deg) * 60.0 * kUnitsPerMinute);
  const std::int64_t d = units / (60 * kUnitsPerMinute);
  const std::int64_t rem = units % (60 * kUnitsPerMinute);
  char buf[48];
  std::snprintf(buf, sizeof buf, latitude ? "%02lld%02lld.%08lld" : "%03lld%02lld.%08lld",
                static_cast<long long>(d), static_cast<long long>(rem / kUnitsPerMinute),
                static_cast<long long>(rem % kUnitsPerMinute));
  const bool negative = deg < 0 && units != 0;
  return std::string(buf) + "," + (latitude ? (negative ? "S" : "N") : (negative ? "W" : "E"));
}

// Degrees in [0, 360) with 4 decimals.
std::string course_text(double rad) {
  double deg = std::fmod(rad_to_deg(rad), 360.0);
  if (deg < 0) deg += 360.0;
  if (std::round(deg * 1e4) >= 360.0 * 1e4) deg = 0;
  return fixed(deg, 4);
}

char mode_indicator(FixQuality q) {
  switch (q) {
    case FixQuality::kSingle:
      return 'A';
    case FixQuality::kDgps:
      return 'D';
    case FixQuality::kPps:
      return 'P';
    case FixQuality::kRtkFixed:
      return 'R';
    case FixQuality::kRtkFloat:
      return 'F';
    case FixQuality::kDeadReckoning:
      return 'E';
    case FixQuality::kInvalid:
      break;
  }
  return 'N';
}

std::string opt_fixed(const std::optional<double>& v, double scale, int decimals) {
  return v && std::isfinite(*v) ? fixed(*v * scale, decimals) : std::string();
}

}  // namespace

std::string describe(const LeapSecondsUse& use) {
  if (use.applied.empty()) return "GPS-UTC: no fix converted";
  std::string text = "GPS-UTC ";
  std::size_t k = 0;
  for (const auto& [value, fixes] : use.applied) {
    if (k++) text += k == use.applied.size() ? " and " : ", ";
    text += std::to_string(value) + " s";
    if (use.applied.size() > 1) text += " (" + std::to_string(fixes) + " fixes)";
  }
  std::string dates;
  if (use.first_date) {
    dates = date_text(*use.first_date);
    if (use.last_date && !(*use.last_date == *use.first_date)) dates += " to " + date_text(*use.last_date);
  }
  if (use.given) {
    text += " (given)";
  } else if (use.from_receiver && use.from_table) {
    text += " (reported by the receiver, PUBX,04; before its first report the leap-second table for " + dates + ")";
  } else if (use.from_receiver) {
    text += " (reported by the receiver, PUBX,04)";
  } else {
    text += " (the leap-second table for the UTC date" + std::string(dates.find(" to ") == std::string::npos ? " " : "s ") +
            dates + ")";
  }
  return text;
}

std::uint8_t nmea_checksum(std::string_view body) {
  std::uint8_t x = 0;
  for (char c : body) x ^= static_cast<std::uint8_t>(c);
  return x;
}

std::string nmea_sentence(std::string_view body) {
  return "$" + std::string(body) + "*" + hex2(nmea_checksum(body));
}

std::vector<std::string> nmea_sentences(const GpsFix& fix, const NmeaWriterOptions& o) {
  const int decimals = std::clamp(o.time_decimals, 0, 9);
  std::int64_t q = 1;
  for (int i = decimals; i < 9; ++i) q *= 10;
  // Round to the written resolution first, so that the time and the date agree.
  std::int64_t t = fix.t_ns + q / 2;
  t -= ((t % q) + q) % q;
  const UtcTime utc = o.leap_seconds ? utc_from_gps_ns(t, *o.leap_seconds) : utc_from_gps_ns_by_table(t);
  std::string time = format_tod(utc.ns_of_day);
  if (decimals > 0) {
    char buf[16];
    std::snprintf(buf, sizeof buf, ".%0*lld", decimals,
                  static_cast<long long>(utc.ns_of_day % kNsPerSecond / q));
    time += buf;
  }
  const CivilDate& date = utc.date;
  const std::string lat = angle_fields(rad_to_deg(fix.antenna.lat_rad), true);
  const std::string lon = angle_fields(rad_to_deg(fix.antenna.lon_rad), false);
  const bool valid = fix.quality != FixQuality::kInvalid;
  const char mode = mode_indicator(fix.quality);

  std::vector<std::string> out;
  {
    // Altitude = h - separation, with the separation rounded first so that the reader's
    // altitude + separation recovers h to within one rounding of the altitude (0.05 mm).
    const double sep = std::round(fix.geoid_separation_m * 1e4) / 1e4;
    const bool have_h = std::isfinite(fix.antenna.h_m);
    char sats[16];
    std::snprintf(sats, sizeof sats, "%02d", std::max(fix.satellites, 0));
    out.push_back(nmea_sentence(o.talker + "GGA," + time + "," + lat + "," + lon + "," +
                                std::to_string(static_cast<int>(fix.quality)) + "," + sats + "," +
                                fixed(fix.hdop, 2) + "," + (have_h ? fixed(fix.antenna.h_m - sep, 4) : "") +
                                ",M," + fixed(sep, 4) + ",M,,"));
  }
  if (o.gst && fix.sigma_ned_m) {
    const Eigen::Vector3d& s = *fix.sigma_ned_m;
    const bool north_major = s.x() >= s.y();
    out.push_back(nmea_sentence(o.talker + "GST," + time + ",," + fixed(std::max(s.x(), s.y()), 4) + "," +
                                fixed(std::min(s.x(), s.y()), 4) + "," + (north_major ? "0.0" : "90.0") +
                                "," + fixed(s.x(), 4) + "," + fixed(s.y(), 4) + "," + fixed(s.z(), 4)));
  }
  const std::string knots = opt_fixed(fix.ground_speed_mps, 1.0 / kMpsPerKnot, 4);
  const std::string course =
      fix.course_rad && std::isfinite(*fix.course_rad) ? course_text(*fix.course_rad) : "";
  if (o.rmc) {
    const std::string ddmmyy = two_digits(date.day) + two_digits(date.month) + two_digits(date.year % 100);
    out.push_back(nmea_sentence(o.talker + "RMC," + time + "," + (valid ? "A" : "V") + "," + lat + "," + lon +
                                "," + knots + "," + course + "," + ddmmyy + ",,," + mode));
  }
  if (o.vtg && fix.ground_speed_mps) {
    out.push_back(nmea_sentence(o.talker + "VTG," + course + ",T,,M," + knots + ",N," +
                                opt_fixed(fix.ground_speed_mps, 1.0 / kMpsPerKmh, 4) + ",K," + mode));
  }
  if (o.hdt && fix.heading_rad && std::isfinite(*fix.heading_rad)) {
    out.push_back(nmea_sentence(o.heading_talker + "HDT," + course_text(*fix.heading_rad) + ",T"));
  }
  if (o.zda) {
    char year[8];
    std::snprintf(year, sizeof year, "%04d", date.year);
    out.push_back(nmea_sentence(o.talker + "ZDA," + time + "," + two_digits(date.day) + "," +
                                two_digits(date.month) + "," + year + ",00,00"));
  }
  if (o.pubx04) {
    const std::int64_t days = days_from_civil(date) - kGpsEpochUnixDays;
    const double tow = static_cast<double>(days % 7 * 86'400) + static_cast<double>(utc.ns_of_day) * 1e-9;
    const int leap = o.leap_seconds ? *o.leap_seconds : leap_seconds_at_gps(t);
    out.push_back(nmea_sentence("PUBX,04," + time + "," + two_digits(date.day) + two_digits(date.month) +
                                two_digits(date.year % 100) + "," + fixed(tow, 2) + "," + std::to_string(days / 7) +
                                "," + std::to_string(leap) + ",,,"));
  }
  return out;
}

std::string write_nmea(const std::vector<GpsFix>& fixes, const NmeaWriterOptions& o) {
  std::string text;
  for (const GpsFix& fix : fixes) {
    const std::string prefix =
        o.write_arrival_prefix && fix.arrival_ns != 0 ? std::to_string(fix.arrival_ns) + " " : std::string();
    for (const std::string& s : nmea_sentences(fix, o)) text += prefix + s + o.line_ending;
  }
  return text;
}

Status write_nmea_file(const std::string& path, const std::vector<GpsFix>& fixes,
                       const NmeaWriterOptions& o) {
  std::ofstream out(path, std::ios::binary);
  if (!out)
    return make_error("nav::write_nmea_file(): ", path, ": cannot create the file (", std::strerror(errno),
                      ")");
  out << write_nmea(fixes, o);
  out.close();
  if (!out) return make_error("nav::write_nmea_file(): ", path, ": write failed");
  return {};
}

namespace {

Expected<NmeaLog> parse(std::istream& in, const std::string& name, const NmeaOptions& options,
                        const std::string& prefix) {
  try {
    Parser parser(prefix, name, options);
    std::string line;
    std::size_t n = 0;
    while (std::getline(in, line)) {
      ++n;
      parser.line(line);
    }
    if (in.bad()) return make_error(prefix, name, ":", n, ": read error");
    return parser.finish();
  } catch (const std::exception& e) {  // std::bad_alloc on absurd input: still no exception escapes
    return make_error(prefix, name, ": ", e.what());
  }
}

}  // namespace

Expected<NmeaLog> parse_nmea(std::istream& in, const std::string& name, const NmeaOptions& options) {
  return parse(in, name, options, "nav::parse_nmea(): ");
}

Expected<NmeaLog> read_nmea_file(const std::string& path, const NmeaOptions& options) {
  if (auto d = check_not_directory("nav::read_nmea_file(): ", path); !d) return d.error();
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return make_error("nav::read_nmea_file(): ", path, ": cannot open the NMEA log (", std::strerror(errno),
                      ")");
  }
  return parse(in, path, options, "nav::read_nmea_file(): ");
}

// ---------------------------------------------------------------------------------------------
// NmeaStream

struct NmeaStream::Impl {
  Impl(const std::string& name, const NmeaOptions& o) : core(name, o) {}
  SentenceCore core;
};

NmeaStream::NmeaStream(const std::string& name, const NmeaOptions& options)
    : impl_(std::make_unique<Impl>(name, options)) {}
NmeaStream::~NmeaStream() = default;
NmeaStream::NmeaStream(NmeaStream&&) noexcept = default;
NmeaStream& NmeaStream::operator=(NmeaStream&&) noexcept = default;

void NmeaStream::push_line(std::string_view line, TimestampNs arrival_ns) {
  try {
    impl_->core.line(line, arrival_ns);
  } catch (const std::exception& e) {  // std::bad_alloc: count the line, never throw at a live input
    impl_->core.report(impl_->core.name() + ": " + e.what());
    ++impl_->core.log().issues.malformed;
  }
}

void NmeaStream::flush() {
  impl_->core.close();
}

bool NmeaStream::flush_if_quiet(TimestampNs now_ns, TimestampNs quiet_ns) {
  const TimestampNs last = impl_->core.last_arrival_ns();
  if (!impl_->core.epoch_open() || last == 0 || now_ns - last < quiet_ns) return false;
  impl_->core.close();
  return true;
}

bool NmeaStream::epoch_open() const {
  return impl_->core.epoch_open();
}

TimestampNs NmeaStream::last_arrival_ns() const {
  return impl_->core.last_arrival_ns();
}

std::size_t NmeaStream::ready() const {
  return impl_->core.out.size();
}

std::optional<GpsFix> NmeaStream::pop() {
  auto& out = impl_->core.out;
  if (out.empty()) return std::nullopt;
  GpsFix fix = out.front().fix;
  out.pop_front();
  return fix;
}

const NmeaLog& NmeaStream::counters() const {
  return impl_->core.log();
}

std::vector<std::string> NmeaStream::take_messages() {
  return std::exchange(impl_->core.log().issues.messages, {});
}

}  // namespace augrig::nav
