#include "recorder/nav_inputs.hpp"

#include <charconv>
#include <span>
#include <vector>

#include "nav/imu_stream.hpp"
#include "nav/nmea.hpp"

namespace augrig::recorder {

namespace {

bool parse_uint(std::string_view s, int& v) {
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && v >= 0;
}

// "hhmmss[.fff...]" -> ns since midnight (second 60: a leap second).
std::optional<std::int64_t> parse_time_of_day(std::string_view s) {
  if (s.size() < 6) return std::nullopt;
  int hh = 0, mm = 0, ss = 0;
  if (!parse_uint(s.substr(0, 2), hh) || !parse_uint(s.substr(2, 2), mm) || !parse_uint(s.substr(4, 2), ss) ||
      hh > 23 || mm > 59 || ss > 60)
    return std::nullopt;
  std::int64_t frac_ns = 0;
  if (s.size() > 6) {
    if (s[6] != '.' || s.size() == 7) return std::nullopt;
    std::int64_t scale = 100'000'000;
    for (char c : s.substr(7)) {
      if (c < '0' || c > '9') return std::nullopt;
      frac_ns += (c - '0') * scale;
      scale /= 10;
    }
  }
  return ((hh * 60LL + mm) * 60LL + ss) * nav::kNsPerSecond + frac_ns;
}

// The fields of "$TTSSS,f1,f2,...*HH" (address first), or empty when the line is not a sentence
// whose checksum holds. A sentence without a checksum is refused too: nothing vouches for its time.
std::vector<std::string_view> sentence_fields(std::string_view line) {
  while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.remove_suffix(1);
  // An arrival prefix "<arrival_ns> $..." (as logs hold it) is skipped.
  if (const auto dollar = line.find('$'); dollar != std::string_view::npos && dollar > 0)
    line.remove_prefix(dollar);
  if (line.size() < 10 || line.front() != '$') return {};
  const auto star = line.rfind('*');
  if (star == std::string_view::npos || star + 3 != line.size()) return {};
  unsigned sum = 0;
  if (std::from_chars(line.data() + star + 1, line.data() + line.size(), sum, 16).ec != std::errc()) return {};
  const std::string_view body = line.substr(1, star - 1);
  if (nav::nmea_checksum(body) != sum) return {};
  std::vector<std::string_view> f;
  std::size_t pos = 0;
  for (;;) {
    const auto c = body.find(',', pos);
    f.push_back(body.substr(pos, c == std::string_view::npos ? std::string_view::npos : c - pos));
    if (c == std::string_view::npos) break;
    pos = c + 1;
  }
  return f;
}

}  // namespace

std::optional<std::pair<TimestampNs, ClockDomain>> imu_datagram_time(std::string_view bytes) {
  auto d = nav::decode_imu_datagram(
      std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
  if (!d || d->samples.empty()) return std::nullopt;
  return std::pair{d->samples.back().t_ns, d->clock};
}

std::optional<nav::CivilDate> NavInputStamper::date(const std::string& stream) const {
  const auto it = streams_.find(stream);
  return it == streams_.end() ? std::nullopt : it->second.date;
}

NavInputTimeSource NavInputStamper::stamp(NavInputRecord& r) {
  r.t_ns = 0;
  r.clock = ClockDomain::kUnknown;
  if (r.binary) {
    const auto t = imu_datagram_time(r.data);
    if (!t) return NavInputTimeSource::kNone;
    r.t_ns = t->first;
    r.clock = t->second;
    return NavInputTimeSource::kImuDatagram;
  }
  const auto f = sentence_fields(r.data);
  if (f.size() < 2 || f[0].size() < 5) return NavInputTimeSource::kNone;
  const std::string_view type = f[0].substr(f[0].size() - 3);
  StreamState& st = streams_[r.stream];
  std::size_t time_field = 1;
  if (type == "GLL") {
    time_field = 5;
  } else if (type != "GGA" && type != "GNS" && type != "GST" && type != "RMC" && type != "ZDA") {
    return NavInputTimeSource::kNone;  // VTG, HDT, GSA, GSV, ...: no time tag
  }
  if (f.size() <= time_field) return NavInputTimeSource::kNone;
  const auto tod = parse_time_of_day(f[time_field]);
  if (!tod) return NavInputTimeSource::kNone;
  // The date this sentence brings, if any.
  std::optional<nav::CivilDate> date;
  if (type == "ZDA" && f.size() > 4) {
    nav::CivilDate d;
    if (parse_uint(f[2], d.day) && parse_uint(f[3], d.month) && parse_uint(f[4], d.year) &&
        nav::is_valid_date(d))
      date = d;
  } else if (type == "RMC" && f.size() > 9 && f[9].size() == 6) {
    nav::CivilDate d;
    int yy = 0;
    if (parse_uint(f[9].substr(0, 2), d.day) && parse_uint(f[9].substr(2, 2), d.month) &&
        parse_uint(f[9].substr(4, 2), yy)) {
      d.year = yy < 80 ? 2000 + yy : 1900 + yy;  // NMEA's two-digit year
      if (nav::is_valid_date(d)) date = d;
    }
  }
  if (date) {
    st.date = date;
  } else if (st.date && st.last_ns_of_day >= 0 && *tod + nav::kNsPerDay / 2 < st.last_ns_of_day) {
    // Midnight passed since the last time tag and no sentence has brought the new date yet.
    st.date = nav::civil_from_days(nav::days_from_civil(*st.date) + 1);
  }
  st.last_ns_of_day = *tod;
  if (!st.date) return NavInputTimeSource::kNoDateYet;
  const auto t = nav::gps_ns_from_utc_checked(*st.date, *tod, leap_seconds_);
  if (!t) return NavInputTimeSource::kNone;
  r.t_ns = *t;
  r.clock = ClockDomain::kGps;
  return NavInputTimeSource::kNmeaTimeTag;
}

}  // namespace augrig::recorder
