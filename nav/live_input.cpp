#include "nav/live_input.hpp"

#include <algorithm>
#include <charconv>
#include <ctime>

#include "nav/gpsd_input.hpp"
#include "nav/imu_stream.hpp"
#include "nav/serial_port.hpp"
#include "nav/ubx_input.hpp"

namespace augrig::nav {

void NavInputStats::note(std::string message) {
  if (last_errors.size() >= kMaxErrors) last_errors.erase(last_errors.begin());
  last_errors.push_back(std::move(message));
}

// ---- URIs -----------------------------------------------------------------------------------------

namespace {

constexpr const char* kUriForms =
    "udp://BIND_ADDR:PORT?format=nmea|imu, serial:///dev/DEVICE?baud=RATE or "
    "gpsd://HOST[:PORT][?device=PATH]";

}  // namespace

Expected<NavUri> parse_nav_uri(std::string_view text) {
  const std::string prefix = "nav::parse_nav_uri(): '" + std::string(text) + "': ";
  NavUri u;
  u.text = std::string(text);
  const std::size_t sep = text.find("://");
  if (sep == std::string_view::npos || sep == 0) {
    return make_error(prefix, "expected SCHEME://..., one of ", kUriForms);
  }
  u.scheme = std::string(text.substr(0, sep));
  std::string_view rest = text.substr(sep + 3);
  std::string_view query;
  if (const std::size_t q = rest.find('?'); q != std::string_view::npos) {
    query = rest.substr(q + 1);
    rest = rest.substr(0, q);
  }
  std::string_view authority = rest;
  if (const std::size_t slash = rest.find('/'); slash != std::string_view::npos) {
    authority = rest.substr(0, slash);
    u.path = std::string(rest.substr(slash));
  }
  if (!authority.empty()) {
    std::string_view port_text;
    if (authority.front() == '[') {
      const std::size_t close = authority.find(']');
      if (close == std::string_view::npos) return make_error(prefix, "no ']' after the IPv6 address");
      u.host = std::string(authority.substr(1, close - 1));
      const std::string_view after = authority.substr(close + 1);
      if (!after.empty()) {
        if (after.front() != ':')
          return make_error(prefix, "expected ':PORT' after ']', got '", std::string(after), "'");
        port_text = after.substr(1);
        if (port_text.empty()) return make_error(prefix, "expected a port number after ':'");
      }
    } else {
      const std::size_t colon = authority.find(':');
      u.host = std::string(authority.substr(0, colon));
      if (colon != std::string_view::npos) {
        port_text = authority.substr(colon + 1);
        if (port_text.find(':') != std::string_view::npos) {
          return make_error(prefix, "an IPv6 address must be written in [brackets], as udp://[::1]:10110");
        }
        if (port_text.empty()) return make_error(prefix, "expected a port number after ':'");
      }
    }
    if (!port_text.empty()) {
      unsigned port = 0;
      const auto [p, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
      if (ec != std::errc() || p != port_text.data() + port_text.size() || port > 65535) {
        return make_error(prefix, "expected a port number 0..65535, got '", std::string(port_text), "'");
      }
      u.port = static_cast<std::uint16_t>(port);
    }
  }
  while (!query.empty()) {
    const std::size_t amp = query.find('&');
    const std::string_view item = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view() : query.substr(amp + 1);
    if (item.empty()) continue;
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos || eq == 0) {
      return make_error(prefix, "expected an option KEY=VALUE, got '", std::string(item), "'");
    }
    std::string key(item.substr(0, eq));
    for (const auto& [k, v] : u.options) {
      if (k == key) return make_error(prefix, "option '", key, "' given twice");
    }
    u.options.emplace_back(std::move(key), std::string(item.substr(eq + 1)));
  }
  return u;
}

NavUriOptions::NavUriOptions(const NavUri& uri, std::string function)
    : uri_(uri), function_(std::move(function)), used_(uri.options.size(), false) {}

std::string NavUriOptions::prefix() const {
  return function_ + ": " + uri_.text + ": ";
}

Expected<std::optional<std::string>> NavUriOptions::text(const std::string& key) {
  known_.push_back(key);
  for (std::size_t i = 0; i < uri_.options.size(); ++i) {
    if (uri_.options[i].first == key) {
      used_[i] = true;
      return std::optional<std::string>(uri_.options[i].second);
    }
  }
  return std::optional<std::string>();
}

Expected<std::optional<std::int64_t>> NavUriOptions::integer(const std::string& key, std::int64_t min,
                                                             std::int64_t max, const std::string& what) {
  auto t = text(key);
  if (!t) return t.error();
  if (!*t) return std::optional<std::int64_t>();
  const std::string& s = **t;
  std::int64_t v = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || p != s.data() + s.size() || v < min || v > max) {
    return make_error(prefix(), "option ", key, ": expected ", what, " (", min, "..", max, "), got '", s,
                      "'");
  }
  return std::optional<std::int64_t>(v);
}

Expected<std::optional<CivilDate>> NavUriOptions::date(const std::string& key) {
  auto t = text(key);
  if (!t) return t.error();
  if (!*t) return std::optional<CivilDate>();
  const std::string& s = **t;
  CivilDate d;
  const auto num = [&](std::size_t at, std::size_t len, int& v) {
    const auto [p, ec] = std::from_chars(s.data() + at, s.data() + at + len, v);
    return ec == std::errc() && p == s.data() + at + len;
  };
  if (s.size() != 10 || s[4] != '-' || s[7] != '-' || !num(0, 4, d.year) || !num(5, 2, d.month) ||
      !num(8, 2, d.day) || !is_valid_date(d)) {
    return make_error(prefix(), "option ", key, ": expected a date YYYY-MM-DD, got '", s, "'");
  }
  return std::optional<CivilDate>(d);
}

Status NavUriOptions::finish() const {
  for (std::size_t i = 0; i < used_.size(); ++i) {
    if (used_[i]) continue;
    std::string known;
    for (const std::string& k : known_) known += (known.empty() ? "" : ", ") + k;
    return make_error(prefix(), "unknown option '", uri_.options[i].first, "' (", uri_.scheme,
                      known.empty() ? " takes no options" : " options: " + known, ")");
  }
  return {};
}

bool udp_datagram_usable(NavInputStats& st, const UdpDatagram& d, const std::string& uri,
                         std::size_t max_datagram_bytes) {
  if (d.overflow_drops > 0) {
    st.socket_overflows += d.overflow_drops;
    st.note(uri + ": the kernel dropped " + std::to_string(d.overflow_drops) +
            " datagrams (receive buffer full: read faster or raise rcvbuf)");
  }
  if (!d.oversized) return true;
  ++st.oversized;
  st.note(uri + ": datagram " + std::to_string(st.datagrams) + " from " + d.source + ": " + std::to_string(d.size) +
          " bytes, more than max_datagram " + std::to_string(max_datagram_bytes) + ": dropped");
  return false;
}

Status read_nmea_uri_options(NavUriOptions& o, TimestampNs& quiet_ns, NmeaOptions& nmea) {
  auto quiet = o.integer("quiet_ms", 1, 10'000, "the quiet gap that closes an epoch, in ms");
  if (!quiet) return quiet.error();
  if (*quiet) quiet_ns = **quiet * 1'000'000;
  auto leap = o.integer("leap_seconds", 0, 100, "GPS - UTC in seconds");
  if (!leap) return leap.error();
  if (*leap) nmea.leap_seconds = static_cast<int>(**leap);
  auto date = o.date("date");
  if (!date) return date.error();
  if (*date) nmea.default_date = **date;
  return {};
}

// ---- NmeaEventSource ------------------------------------------------------------------------------

NmeaEventSource::NmeaEventSource(const std::string& name, const NmeaOptions& options, TimestampNs quiet_ns)
    : stream_(name, options), quiet_ns_(quiet_ns) {}

void NmeaEventSource::push_line(std::string_view line, TimestampNs arrival_ns) {
  stream_.push_line(line, arrival_ns);
  sync();
}

void NmeaEventSource::poll_quiet(TimestampNs now_ns) {
  if (stream_.flush_if_quiet(now_ns, quiet_ns_)) sync();
}

std::optional<TimestampNs> NmeaEventSource::quiet_deadline_ns() const {
  if (!stream_.epoch_open() || stream_.last_arrival_ns() == 0) return std::nullopt;
  return stream_.last_arrival_ns() + quiet_ns_;
}

void NmeaEventSource::flush() {
  stream_.flush();
  sync();
}

bool NmeaEventSource::pop(NavEvent& out) {
  std::optional<GpsFix> fix = stream_.pop();
  if (!fix) return false;
  out.sample = std::move(*fix);
  out.sensor_clock = ClockDomain::kGps;
  out.velocity_ned_mps.reset();
  ++stats_.events;
  return true;
}

void NmeaEventSource::sync() {
  const NmeaLog& c = stream_.counters();
  stats_.lines = c.lines;
  stats_.malformed += c.issues.malformed - seen_malformed_;
  seen_malformed_ = c.issues.malformed;
  const std::size_t late = c.issues.out_of_order + c.issues.duplicates;
  stats_.out_of_order += late - seen_out_of_order_;
  seen_out_of_order_ = late;
  const std::size_t dropped = late + c.fixes_without_date;
  stats_.dropped += dropped - seen_dropped_;
  seen_dropped_ = dropped;
  for (std::string& m : stream_.take_messages()) stats_.note(std::move(m));
}

// ---- UdpNmeaInput ---------------------------------------------------------------------------------

UdpNmeaInput::UdpNmeaInput(UdpReceiver socket, std::string uri, const UdpNmeaOptions& options)
    : socket_(std::move(socket)), uri_(std::move(uri)), source_(uri_, options.nmea, options.quiet_ns) {}

Expected<std::unique_ptr<UdpNmeaInput>> UdpNmeaInput::open(const std::string& bind_host, std::uint16_t port,
                                                           const UdpNmeaOptions& options, std::string uri) {
  if (uri.empty()) uri = "udp://" + bind_host + ":" + std::to_string(port) + "?format=nmea";
  UdpReceiverOptions ro;
  ro.max_datagram_bytes = options.max_datagram_bytes;
  ro.receive_buffer_bytes = options.receive_buffer_bytes;
  auto socket = UdpReceiver::bind(bind_host, port, ro);
  if (!socket) return socket.error();
  return std::unique_ptr<UdpNmeaInput>(new UdpNmeaInput(std::move(*socket), std::move(uri), options));
}

Expected<NavReadStatus> UdpNmeaInput::read(NavEvent& out, std::chrono::nanoseconds timeout) {
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  for (;;) {
    if (source_.pop(out)) return NavReadStatus::kEvent;
    TimestampNs now = monotonic_now_ns();
    source_.poll_quiet(now);
    if (source_.pop(out)) return NavReadStatus::kEvent;
    TimestampNs wait = std::max<TimestampNs>(deadline - now, 0);
    if (const auto q = source_.quiet_deadline_ns()) wait = std::min(wait, std::max<TimestampNs>(*q - now, 0));
    auto got = socket_.receive(datagram_, std::chrono::nanoseconds(wait));
    if (!got) return got.error();
    if (*got) {
      NavInputStats& st = source_.stats();
      ++st.datagrams;
      st.bytes += datagram_.size;
      if (!udp_datagram_usable(st, datagram_, uri_, socket_.options().max_datagram_bytes)) continue;
      // One or more lines; the datagram's end also ends its last line.
      const std::string_view text(reinterpret_cast<const char*>(datagram_.bytes.data()),
                                  datagram_.bytes.size());
      for (std::size_t start = 0; start < text.size();) {
        const std::size_t nl = std::min(text.find('\n', start), text.size());
        std::string_view line = text.substr(start, nl - start);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        if (!line.empty()) {
          tap(line, datagram_.arrival_ns, false);
          source_.push_line(line, datagram_.arrival_ns);
        }
        start = nl + 1;
      }
      continue;
    }
    now = monotonic_now_ns();
    if (now >= deadline) {
      source_.poll_quiet(now);
      return source_.pop(out) ? NavReadStatus::kEvent : NavReadStatus::kTimeout;
    }
  }
}

// ---- The factory ----------------------------------------------------------------------------------

namespace {

Expected<std::unique_ptr<NavInput>> open_udp(const NavUri& u) {
  NavUriOptions o(u, "nav::open_nav_input()");
  if (u.host.empty() || !u.port) {
    return make_error(o.prefix(),
                      "expected udp://BIND_ADDR:PORT?format=nmea|imu (e.g. udp://0.0.0.0:10110?format=nmea)");
  }
  if (!u.path.empty() && u.path != "/") {
    return make_error(o.prefix(), "expected no path after the port, got '", u.path, "'");
  }
  auto format = o.text("format");
  if (!format) return format.error();
  if (!*format || (**format != "nmea" && **format != "imu" && **format != "ubx")) {
    return make_error(o.prefix(), "expected the option format=nmea, format=imu or format=ubx",
                      *format ? ", got format=" + **format : std::string());
  }
  auto max_datagram = o.integer("max_datagram", 1, 65507, "the largest datagram kept, in bytes");
  if (!max_datagram) return max_datagram.error();
  auto rcvbuf = o.integer("rcvbuf", 0, 1 << 30, "the socket receive buffer, in bytes");
  if (!rcvbuf) return rcvbuf.error();
  if (**format == "ubx") {
    UdpReceiverOptions ro;
    if (*max_datagram) ro.max_datagram_bytes = static_cast<std::size_t>(**max_datagram);
    if (*rcvbuf) ro.receive_buffer_bytes = static_cast<int>(**rcvbuf);
    UbxInputOptions uo;
    auto fixes = o.integer("fixes", 0, 1, "1 (NAV-PVT as GPS fixes, the default) or 0");
    if (!fixes) return fixes.error();
    if (*fixes) uo.fixes = **fixes == 1;
    if (auto s = o.finish(); !s) return s.error();
    auto in = UdpUbxInput::open(u.host, *u.port, ro, uo, u.text);
    if (!in) return make_error(o.prefix(), in.error().message);
    return std::unique_ptr<NavInput>(std::move(*in));
  }
  if (**format == "imu") {
    UdpImuOptions io;
    if (*max_datagram) io.max_datagram_bytes = static_cast<std::size_t>(**max_datagram);
    if (*rcvbuf) io.receive_buffer_bytes = static_cast<int>(**rcvbuf);
    if (auto s = o.finish(); !s) return s.error();
    auto in = UdpImuInput::open(u.host, *u.port, io, u.text);
    if (!in) return make_error(o.prefix(), in.error().message);
    return std::unique_ptr<NavInput>(std::move(*in));
  }
  UdpNmeaOptions no;
  if (*max_datagram) no.max_datagram_bytes = static_cast<std::size_t>(**max_datagram);
  if (*rcvbuf) no.receive_buffer_bytes = static_cast<int>(**rcvbuf);
  if (auto s = read_nmea_uri_options(o, no.quiet_ns, no.nmea); !s) return s.error();
  if (auto s = o.finish(); !s) return s.error();
  auto in = UdpNmeaInput::open(u.host, *u.port, no, u.text);
  if (!in) return make_error(o.prefix(), in.error().message);
  return std::unique_ptr<NavInput>(std::move(*in));
}

Expected<std::unique_ptr<NavInput>> open_serial(const NavUri& u) {
  NavUriOptions o(u, "nav::open_nav_input()");
  if (!u.host.empty() || u.port || u.path.size() < 2) {
    return make_error(o.prefix(),
                      "expected serial:///dev/DEVICE?baud=RATE (three slashes: an empty host and the "
                      "device path), e.g. serial:///dev/ttyUSB0?baud=115200");
  }
  SerialNmeaOptions so;
  auto baud = o.text("baud");
  if (!baud) return baud.error();
  if (!*baud) return make_error(o.prefix(), "expected the option baud=RATE (e.g. baud=115200)");
  auto rate = parse_baud(**baud);
  if (!rate) return make_error(o.prefix(), "option baud: ", rate.error().message);
  so.baud = *rate;
  auto format = o.text("format");
  if (!format) return format.error();
  if (*format && **format != "nmea" && **format != "ubx")
    return make_error(o.prefix(), "expected format=nmea (the default) or format=ubx, got format=", **format);
  if (*format && **format == "ubx") {
    UbxInputOptions uo;
    auto fixes = o.integer("fixes", 0, 1, "1 (NAV-PVT as GPS fixes, the default) or 0");
    if (!fixes) return fixes.error();
    if (*fixes) uo.fixes = **fixes == 1;
    if (auto s = o.finish(); !s) return s.error();
    auto in = SerialUbxInput::open(u.path, so.baud, uo, u.text);
    if (!in) return make_error(o.prefix(), in.error().message);
    return std::unique_ptr<NavInput>(std::move(*in));
  }
  auto max_line = o.integer("max_line", 16, 65536, "the longest line kept, in bytes");
  if (!max_line) return max_line.error();
  if (*max_line) so.max_line_bytes = static_cast<std::size_t>(**max_line);
  if (auto s = read_nmea_uri_options(o, so.quiet_ns, so.nmea); !s) return s.error();
  if (auto s = o.finish(); !s) return s.error();
  auto in = SerialNmeaInput::open(u.path, so, u.text);
  if (!in) return make_error(o.prefix(), in.error().message);
  return std::unique_ptr<NavInput>(std::move(*in));
}

Expected<std::unique_ptr<NavInput>> open_gpsd(const NavUri& u) {
  NavUriOptions o(u, "nav::open_nav_input()");
  if (!u.path.empty() && u.path != "/") {
    return make_error(
        o.prefix(), "expected gpsd://HOST[:PORT][?device=PATH] (the device goes in device=), got the path '",
        u.path, "'");
  }
  GpsdOptions go;
  if (!u.host.empty()) go.host = u.host;
  if (u.port) {
    if (*u.port == 0)
      return make_error(o.prefix(), "expected a gpsd port 1..65535 (gpsd's default: 2947), got 0");
    go.port = *u.port;
  }
  auto device = o.text("device");
  if (!device) return device.error();
  if (*device) go.device = **device;
  auto quiet = o.integer("quiet_ms", 1, 10'000, "the quiet gap that closes an epoch, in ms");
  if (!quiet) return quiet.error();
  if (*quiet) go.quiet_ns = **quiet * 1'000'000;
  auto leap = o.integer("leap_seconds", 0, 100, "GPS - UTC in seconds");
  if (!leap) return leap.error();
  if (*leap) go.leap_seconds = static_cast<int>(**leap);
  auto connect = o.integer("connect_timeout_ms", 1, 600'000, "the connection timeout in ms");
  if (!connect) return connect.error();
  if (*connect) go.connect_timeout = std::chrono::milliseconds(**connect);
  if (auto s = o.finish(); !s) return s.error();
  auto in = GpsdInput::open(go, u.text);
  if (!in) return in.error();
  return std::unique_ptr<NavInput>(std::move(*in));
}

}  // namespace

Expected<std::unique_ptr<NavInput>> open_nav_input(std::string_view uri) {
  auto u = parse_nav_uri(uri);
  if (!u) return u.error();
  if (u->scheme == "udp") return open_udp(*u);
  if (u->scheme == "serial") return open_serial(*u);
  if (u->scheme == "gpsd") return open_gpsd(*u);
  return make_error("nav::open_nav_input(): ", std::string(uri), ": unknown scheme '", u->scheme,
                    "': expected ", kUriForms);
}

}  // namespace augrig::nav
