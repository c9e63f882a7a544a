#include "nav/gpsd_input.hpp"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>

#include <fcntl.h>
#include <netdb.h>
#include <nlohmann/json.hpp>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

// gps.h last: it defines plain macro names (STATUS_FIX, MODE_2D, ...).
#include <gps.h>

namespace augrig::nav {
namespace {

// ---- Reading fields from a report's text (for what libgps 3.22 does not parse, and for the broken
// ATT reports of gpsd 3.22). Top-level keys only: good enough for flat reports like TPV and ATT.

std::optional<std::string_view> json_string(std::string_view json, std::string_view key) {
  const std::string pattern = "\"" + std::string(key) + "\":\"";
  const std::size_t at = json.find(pattern);
  if (at == std::string_view::npos) return std::nullopt;
  const std::size_t start = at + pattern.size();
  const std::size_t end = json.find('"', start);
  if (end == std::string_view::npos) return std::nullopt;
  return json.substr(start, end - start);
}

std::optional<double> json_number(std::string_view json, std::string_view key) {
  const std::string pattern = "\"" + std::string(key) + "\":";
  const std::size_t at = json.find(pattern);
  if (at == std::string_view::npos) return std::nullopt;
  const std::string rest(json.substr(at + pattern.size(), 40));
  char* end = nullptr;
  const double v = std::strtod(rest.c_str(), &end);
  if (end == rest.c_str() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// A UTC time as seconds and nanoseconds since 1970-01-01 (kept apart: the ns of year 9999 overflow
// int64; gps_ns_from_unix_checked() bounds them).
struct UnixTime {
  std::int64_t s = 0;
  std::int64_t ns = 0;
};

// "2024-06-01T12:00:00.800Z" (UTC) -> seconds and ns since 1970-01-01.
std::optional<UnixTime> parse_iso8601_utc(std::string_view s) {
  const auto num = [&](std::size_t at, std::size_t len, int& v) {
    if (at + len > s.size()) return false;
    v = 0;
    for (std::size_t i = at; i < at + len; ++i) {
      if (s[i] < '0' || s[i] > '9') return false;
      v = v * 10 + (s[i] - '0');
    }
    return true;
  };
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, se = 0;
  if (!num(0, 4, y) || s.size() < 20 || s[4] != '-' || !num(5, 2, mo) || s[7] != '-' || !num(8, 2, d) ||
      s[10] != 'T' || !num(11, 2, h) || s[13] != ':' || !num(14, 2, mi) || s[16] != ':' || !num(17, 2, se)) {
    return std::nullopt;
  }
  if (!is_valid_date({y, mo, d}) || h > 23 || mi > 59 || se > 60) return std::nullopt;
  std::size_t i = 19;
  std::int64_t frac_ns = 0;
  if (s[i] == '.') {
    std::int64_t scale = 100'000'000;
    for (++i; i < s.size() && s[i] >= '0' && s[i] <= '9'; ++i) {
      frac_ns += (s[i] - '0') * scale;
      scale /= 10;
    }
  }
  if (i >= s.size() || s[i] != 'Z') return std::nullopt;
  return UnixTime{days_from_civil(y, mo, d) * 86'400 + (h * 60 + mi) * 60 + se, frac_ns};
}

UnixTime unix_time(const timespec& t) {
  return {static_cast<std::int64_t>(t.tv_sec), static_cast<std::int64_t>(t.tv_nsec)};
}

// The report's "class" when it is one well-formed JSON object with a string "class" and no key
// repeated within an object; else nullopt. Checked before libgps sees a report: libgps 3.22 loops
// forever in gps_unpack() on some malformed ones (the 16 bytes {s"class":"TPV"}, and
// {"class":"TPV","class":"VERSION"}, found by fuzz/fuzz_gpsd), and a gpsd peer must not be able to
// stall the input.
std::optional<std::string> report_class(std::string_view json, std::optional<std::string>* device) {
  // nlohmann keeps the last of repeated keys silently: its parse callback sees every key, per object.
  std::vector<std::vector<std::string>> keys;  // per open object
  bool repeated = false;
  const nlohmann::json::parser_callback_t watch = [&](int, nlohmann::json::parse_event_t event,
                                                      nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    if (event == E::object_start) keys.emplace_back();
    if (event == E::object_end && !keys.empty()) keys.pop_back();
    if (event == E::key && !keys.empty() && parsed.is_string()) {
      std::vector<std::string>& k = keys.back();
      const std::string& name = parsed.get_ref<const std::string&>();
      repeated = repeated || std::find(k.begin(), k.end(), name) != k.end();
      k.push_back(name);
    }
    return true;
  };
  const nlohmann::json j = nlohmann::json::parse(json.begin(), json.end(), watch, false);
  if (repeated || j.is_discarded() || !j.is_object()) return std::nullopt;
  const auto cls = j.find("class");
  if (cls == j.end() || !cls->is_string()) return std::nullopt;
  if (const auto dev = j.find("device"); dev != j.end() && dev->is_string())
    *device = dev->get<std::string>();
  return cls->get<std::string>();
}

FixQuality quality_of(int mode, int status) {
  if (mode < MODE_2D) return FixQuality::kInvalid;
  switch (status) {
    case STATUS_DGPS_FIX:
      return FixQuality::kDgps;
    case STATUS_RTK_FIX:
      return FixQuality::kRtkFixed;
    case STATUS_RTK_FLT:
      return FixQuality::kRtkFloat;
    case STATUS_DR:
    case STATUS_GNSSDR:
      return FixQuality::kDeadReckoning;
    case STATUS_PPS_FIX:
      return FixQuality::kPps;
    case STATUS_TIME:  // surveyed/manual time only
    case STATUS_SIM:   // simulated: as GGA quality 8, not a fix to navigate with
      return FixQuality::kInvalid;
    default:
      return FixQuality::kSingle;
  }
}

}  // namespace

// ---- GpsdReportMerger -----------------------------------------------------------------------------

struct GpsdReportMerger::Libgps {
  gps_data_t data{};
};

GpsdReportMerger::GpsdReportMerger(std::string name, const GpsdOptions& options)
    : name_(std::move(name)), options_(options), gps_(std::make_unique<Libgps>()) {}

GpsdReportMerger::~GpsdReportMerger() = default;

void GpsdReportMerger::push_report(std::string_view json, TimestampNs arrival_ns) {
  ++stats_.lines;
  stats_.bytes += json.size();
  while (!json.empty() && (json.back() == '\n' || json.back() == '\r')) json.remove_suffix(1);
  std::optional<std::string> device;
  std::optional<std::string> cls = report_class(json, &device);
  // gpsd 3.22 writes ATT reports that carry a time as broken JSON (",," and a missing comma):
  // those alone are read from the text, without libgps.
  bool text_only = false;
  if (!cls && json.size() > 1 && json.front() == '{' && json.back() == '}' &&
      json_string(json, "class") == std::string_view("ATT")) {
    cls = "ATT";
    if (const auto dev = json_string(json, "device")) device = std::string(*dev);
    text_only = true;
  }
  if (!cls) {
    ++stats_.malformed;
    stats_.note(name_ + ": report " + std::to_string(stats_.lines) +
                ": expected a JSON object with a string \"class\" and no key repeated, got '" +
                std::string(json.substr(0, 60)) + "': dropped");
    return;
  }
  if (!options_.device.empty() && device && *device != options_.device) return;  // another device's report
  gps_->data.set = 0;
  if (!text_only) {
    std::string buffer(json);
    gps_unpack(buffer.data(), &gps_->data);  // never fails on its own: see the checks per class
  }
  if (*cls == "TPV") {
    on_tpv(json, arrival_ns);
  } else if (*cls == "GST") {
    on_gst(arrival_ns);
  } else if (*cls == "ATT") {
    on_att(json, arrival_ns);
  } else if (*cls == "SKY") {
    on_sky();
  } else if (*cls == "ERROR") {
    stats_.note(name_ + ": gpsd says: " + std::string(json_string(json, "message").value_or(json)));
  } else if (*cls == "DEVICE" && json_number(json, "activated") == 0.0) {
    stats_.note(name_ + ": gpsd closed the device " + std::string(json_string(json, "path").value_or("?")));
  }
  // VERSION, DEVICES, WATCH, PPS, TOFF, ...: nothing for the fixes.
}

GpsdReportMerger::Pending& GpsdReportMerger::epoch_at(TimestampNs t_ns, TimestampNs arrival_ns) {
  if (pending_ && pending_->t_ns != t_ns) emit();
  if (!pending_) {
    // Assigned, not emplace()d: clang 14 decides is_constructible<Pending> while the enclosing
    // class is incomplete (Pending has default member initialisers) and rejects emplace().
    pending_ = Pending{};
    pending_->t_ns = t_ns;
  }
  pending_->last_report_ns = arrival_ns;
  return *pending_;
}

void GpsdReportMerger::on_tpv(std::string_view json, TimestampNs arrival_ns) {
  const gps_fix_t& f = gps_->data.fix;
  if (f.mode == MODE_NOT_SEEN) {  // libgps could not read the report (or it carries no mode)
    ++stats_.malformed;
    stats_.note(name_ + ": report " + std::to_string(stats_.lines) + ": a TPV without a readable mode: '" +
                std::string(json.substr(0, 80)) + "'");
    return;
  }
  if (f.time.tv_sec == 0) {
    // gpsd reports fixes before it knows the date (NMEA GGA before any RMC/ZDA): no time, no fix.
    ++stats_.dropped;
    if (untimed_tpv_++ == 0) {
      stats_.note(name_ +
                  ": a TPV without time (gpsd does not know the date yet): dropped, and so are further ones");
    }
    return;
  }
  const auto t = gps_time(f.time.tv_sec, f.time.tv_nsec, "TPV");
  if (!t) return;
  const TimestampNs t_ns = *t;
  Pending& p = epoch_at(t_ns, arrival_ns);
  if (!p.fix) p.arrival_ns = arrival_ns;
  GpsFix fix;
  fix.t_ns = t_ns;
  fix.arrival_ns = p.arrival_ns;
  fix.quality = quality_of(f.mode, f.status);
  const bool horizontal = f.mode >= MODE_2D && std::isfinite(f.latitude) && std::isfinite(f.longitude);
  fix.antenna.lat_rad = horizontal ? deg_to_rad(f.latitude) : NAN;
  fix.antenna.lon_rad = horizontal ? deg_to_rad(f.longitude) : NAN;
  fix.antenna.h_m = NAN;
  if (f.mode >= MODE_3D) {
    if (std::isfinite(f.altHAE)) {
      fix.antenna.h_m = f.altHAE;
    } else if (std::isfinite(f.altMSL) && std::isfinite(f.geoid_sep)) {
      fix.antenna.h_m = f.altMSL + f.geoid_sep;
    }
  }
  fix.geoid_separation_m = std::isfinite(f.geoid_sep) ? f.geoid_sep : 0.0;
  if (std::isfinite(f.speed)) fix.ground_speed_mps = f.speed;
  if (std::isfinite(f.track)) fix.course_rad = deg_to_rad(f.track);
  p.fix = fix;
  // libgps 3.22 does not read velN/velE/velD: take them from the text.
  const auto vn = json_number(json, "velN"), ve = json_number(json, "velE"), vd = json_number(json, "velD");
  if (vn && ve && vd) p.velocity_ned_mps = Eigen::Vector3d(*vn, *ve, *vd);
}

void GpsdReportMerger::on_gst(TimestampNs arrival_ns) {
  const gst_t& g = gps_->data.gst;
  if (!std::isfinite(g.lat_err_deviation) || !std::isfinite(g.lon_err_deviation) ||
      !std::isfinite(g.alt_err_deviation)) {
    return;  // no estimate
  }
  const Eigen::Vector3d sigma(g.lat_err_deviation, g.lon_err_deviation, g.alt_err_deviation);
  if (g.utctime.tv_sec == 0) {  // no time (no date yet): the open epoch's, if any
    if (pending_) {
      pending_->sigma_ned_m = sigma;
      pending_->last_report_ns = arrival_ns;
    }
    return;
  }
  const auto t_ns = gps_time(g.utctime.tv_sec, g.utctime.tv_nsec, "GST");
  if (!t_ns) return;
  epoch_at(*t_ns, arrival_ns).sigma_ned_m = sigma;
}

void GpsdReportMerger::on_att(std::string_view json, TimestampNs arrival_ns) {
  // libgps first; gpsd 3.22 writes ATT reports that have a time as broken JSON
  // ({..."device":"x",,"time":"...""heading":...}), which libgps drops: read the text then.
  std::optional<double> heading_deg;
  std::optional<UnixTime> utc;
  const attitude_t& a = gps_->data.attitude;
  if ((gps_->data.set & ATTITUDE_SET) && std::isfinite(a.heading)) {
    heading_deg = a.heading;
    if (a.mtime.tv_sec != 0) utc = unix_time(a.mtime);
  } else {
    heading_deg = json_number(json, "heading");
    if (const auto t = json_string(json, "time")) utc = parse_iso8601_utc(*t);
  }
  if (!heading_deg) return;  // an ATT without heading (a compass, a tilt sensor)
  const double heading_rad = deg_to_rad(*heading_deg);
  if (!utc) {  // the open epoch's, if any
    if (pending_) {
      pending_->heading_rad = heading_rad;
      pending_->last_report_ns = arrival_ns;
    }
    return;
  }
  const auto t_ns = gps_time(utc->s, utc->ns, "ATT");
  if (!t_ns) return;
  epoch_at(*t_ns, arrival_ns).heading_rad = heading_rad;
}

std::optional<TimestampNs> GpsdReportMerger::gps_time(std::int64_t unix_s, std::int64_t ns, const char* cls) {
  const std::int64_t day = unix_s >= 0 ? unix_s / 86'400 : (unix_s - 86'399) / 86'400;
  const int leap = gps_->data.leap_seconds > 0 ? gps_->data.leap_seconds
                   : options_.leap_seconds     ? *options_.leap_seconds
                                               : leap_seconds_on_day(day);
  // Checked: the ns of a year like 9999 overflow int64 (nav/gps_time.hpp).
  const auto t_ns = gps_ns_from_unix_checked(unix_s, ns, leap);
  if (!t_ns) {
    ++stats_.malformed;
    stats_.note(name_ + ": report " + std::to_string(stats_.lines) + ": a " + cls +
                " time outside the years " + kYearRangeText + " (or leap seconds " + std::to_string(leap) +
                " outside +-1000): dropped");
  }
  return t_ns;
}

void GpsdReportMerger::on_sky() {
  const gps_data_t& d = gps_->data;
  if (d.set & SATELLITE_SET) satellites_ = d.satellites_used;
  if (std::isfinite(d.dop.hdop) && d.dop.hdop > 0) hdop_ = d.dop.hdop;
}

void GpsdReportMerger::emit() {
  Pending& p = *pending_;
  if (p.fix) {  // (GST/ATT without a TPV make no fix)
    if (last_emitted_t_ns_ && p.fix->t_ns <= *last_emitted_t_ns_) {
      ++stats_.out_of_order;
      ++stats_.dropped;
      stats_.note(name_ + ": fix at t_ns " + std::to_string(p.fix->t_ns) +
                  " is not after the previous fix's " + std::to_string(*last_emitted_t_ns_) + ": dropped");
    } else {
      last_emitted_t_ns_ = p.fix->t_ns;
      NavEvent& e = ready_.emplace_back();
      GpsFix& fix = e.sample.emplace<GpsFix>(*p.fix);
      fix.sigma_ned_m = p.sigma_ned_m;
      fix.heading_rad = p.heading_rad;
      fix.satellites = satellites_;
      fix.hdop = hdop_;
      e.sensor_clock = ClockDomain::kGps;
      e.velocity_ned_mps = p.velocity_ned_mps;
    }
  }
  pending_.reset();
}

void GpsdReportMerger::poll_quiet(TimestampNs now_ns) {
  if (pending_ && now_ns - pending_->last_report_ns >= options_.quiet_ns) emit();
}

std::optional<TimestampNs> GpsdReportMerger::quiet_deadline_ns() const {
  if (!pending_) return std::nullopt;
  return pending_->last_report_ns + options_.quiet_ns;
}

void GpsdReportMerger::flush() {
  if (pending_) emit();
}

bool GpsdReportMerger::pop(NavEvent& out) {
  if (ready_.empty()) return false;
  out = std::move(ready_.front());
  ready_.pop_front();
  ++stats_.events;
  return true;
}

// ---- GpsdInput ------------------------------------------------------------------------------------

// Larger than any report gpsd sends (its GPS_JSON_RESPONSE_MAX is 4096).
constexpr int kGpsdMessageBytes = 16384;

struct GpsdInput::Connection {
  gps_data_t data{};
  // Reports are read from the socket here, not with gps_read(): gps_read() hands every line to
  // gps_unpack(), which libgps 3.22 never returns from on some malformed reports. push_report()
  // checks each line first.
  std::string buffer;     // bytes received, not yet a whole line
  bool overlong = false;  // dropping the rest of a line longer than kGpsdMessageBytes
  bool open = false;
  ~Connection() {
    if (open) {
      gps_stream(&data, WATCH_DISABLE, nullptr);
      gps_close(&data);
    }
  }
};

namespace {

// gps_open() connects without a timeout: first make sure, within `timeout`, that something
// accepts connections there.
Status probe_tcp(const std::string& host, std::uint16_t port, std::chrono::milliseconds timeout,
                 const std::string& prefix) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICSERV;
  addrinfo* list = nullptr;
  const std::string service = std::to_string(port);
  if (const int rc = getaddrinfo(host.c_str(), service.c_str(), &hints, &list); rc != 0) {
    return make_error(prefix, "cannot resolve '", host, "' (", gai_strerror(rc), ")");
  }
  std::string why = "no address";
  for (addrinfo* a = list; a != nullptr; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    int err = 0;
    if (::connect(fd, a->ai_addr, a->ai_addrlen) != 0) {
      err = errno;
      if (err == EINPROGRESS) {
        pollfd p{fd, POLLOUT, 0};
        const int rc = ::poll(&p, 1, static_cast<int>(timeout.count()));
        socklen_t len = sizeof err;
        if (rc <= 0) {
          err = ETIMEDOUT;
        } else if (getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) != 0) {
          err = errno;
        }
      }
    }
    ::close(fd);
    if (err == 0) {
      freeaddrinfo(list);
      return {};
    }
    why = std::strerror(err);
  }
  freeaddrinfo(list);
  return make_error(prefix, "cannot connect to gpsd at ", host, ":", port, " (", why,
                    "): is gpsd running and listening there? (gpsd -N -D 2 -S PORT DEVICE)");
}

}  // namespace

GpsdInput::GpsdInput(std::unique_ptr<Connection> connection, std::string uri, const GpsdOptions& options)
    : connection_(std::move(connection)), uri_(std::move(uri)), merger_(uri_, options) {}

GpsdInput::~GpsdInput() = default;

Expected<std::unique_ptr<GpsdInput>> GpsdInput::open(const GpsdOptions& options, std::string uri) {
  if (uri.empty()) {
    uri = "gpsd://" + options.host + ":" + std::to_string(options.port) +
          (options.device.empty() ? "" : "?device=" + options.device);
  }
  const std::string prefix = "nav::GpsdInput::open(): " + uri + ": ";
  if (auto s = probe_tcp(options.host, options.port, options.connect_timeout, prefix); !s) return s.error();
  auto c = std::make_unique<Connection>();
  const std::string port = std::to_string(options.port);
  if (gps_open(options.host.c_str(), port.c_str(), &c->data) != 0) {
    return make_error(prefix, "gps_open() failed: ", gps_errstr(errno));
  }
  c->open = true;
  unsigned flags = WATCH_ENABLE | WATCH_JSON;
  if (!options.device.empty()) flags |= WATCH_DEVICE;
  if (gps_stream(&c->data, flags,
                 options.device.empty() ? nullptr : const_cast<char*>(options.device.c_str())) != 0) {
    return make_error(prefix, "gps_stream() failed: ", gps_errstr(errno));
  }
  return std::unique_ptr<GpsdInput>(new GpsdInput(std::move(c), std::move(uri), options));
}

bool GpsdInput::next_line(std::string& line) {
  std::string& b = connection_->buffer;
  for (;;) {
    const std::size_t nl = b.find('\n');
    if (nl == std::string::npos) {
      if (b.size() > static_cast<std::size_t>(kGpsdMessageBytes)) {  // no report is this long
        if (!connection_->overlong) {
          ++merger_.stats().malformed;
          merger_.stats().note(uri_ + ": a report longer than " + std::to_string(kGpsdMessageBytes) +
                               " bytes: dropped");
        }
        connection_->overlong = true;
        b.clear();
      }
      return false;
    }
    const bool skip = connection_->overlong;  // the tail of an overlong report
    connection_->overlong = false;
    line.assign(b, 0, nl);
    b.erase(0, nl + 1);
    if (!skip) return true;
  }
}

Expected<NavReadStatus> GpsdInput::read(NavEvent& out, std::chrono::nanoseconds timeout) {
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  std::string line;
  for (;;) {
    if (merger_.pop(out)) return NavReadStatus::kEvent;
    if (ended_) return NavReadStatus::kEnd;
    TimestampNs now = monotonic_now_ns();
    merger_.poll_quiet(now);
    if (merger_.pop(out)) return NavReadStatus::kEvent;
    if (next_line(line)) {
      if (!line.empty() && line != "\r") {
        const TimestampNs arrival_ns = monotonic_now_ns();
        tap(line, arrival_ns, false);
        merger_.push_report(line, arrival_ns);
      }
      continue;
    }
    TimestampNs wait = std::max<TimestampNs>(deadline - now, 0);
    if (const auto q = merger_.quiet_deadline_ns()) wait = std::min(wait, std::max<TimestampNs>(*q - now, 0));
    pollfd p{connection_->data.gps_fd, POLLIN, 0};
    const timespec ts{static_cast<time_t>(wait / kNsPerSecond), static_cast<long>(wait % kNsPerSecond)};
    const int rc = ::ppoll(&p, 1, &ts, nullptr);
    if (rc > 0) {
      char chunk[4096];
      const ssize_t n = ::recv(connection_->data.gps_fd, chunk, sizeof chunk, MSG_DONTWAIT);
      if (n > 0) {
        connection_->buffer.append(chunk, static_cast<std::size_t>(n));
      } else if (n == 0 || (errno != EINTR && errno != EAGAIN && errno != EWOULDBLOCK)) {
        ended_ = true;
        merger_.flush();
        merger_.stats().note(
            uri_ + (n == 0 ? ": gpsd closed the connection"
                           : ": reading from gpsd failed (" + std::string(std::strerror(errno)) + ")"));
      }
      continue;
    }
    if (rc < 0 && errno != EINTR) {
      ended_ = true;
      merger_.flush();
      merger_.stats().note(uri_ + ": waiting for gpsd failed (" + std::string(std::strerror(errno)) + ")");
      continue;
    }
    now = monotonic_now_ns();
    if (now >= deadline) {
      merger_.poll_quiet(now);
      return merger_.pop(out) ? NavReadStatus::kEvent : NavReadStatus::kTimeout;
    }
  }
}

}  // namespace augrig::nav
