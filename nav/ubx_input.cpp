#include "nav/ubx_input.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/conventions.hpp"
#include "nav/gps_time.hpp"

namespace augrig::nav {

namespace {

constexpr TimestampNs kWeekNs = 604800LL * kNsPerSecond;

// The host's UTC clock as GPS time (leap seconds by the table): good to the host clock's seconds,
// which is all a week needs.
TimestampNs host_gps_now_ns() {
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const std::int64_t unix_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
  const std::int64_t days = unix_ns / kNsPerDay;
  const std::chrono::year_month_day ymd{std::chrono::sys_days{std::chrono::days{days}}};
  const CivilDate date{static_cast<int>(ymd.year()), static_cast<int>(static_cast<unsigned>(ymd.month())),
                       static_cast<int>(static_cast<unsigned>(ymd.day()))};
  return gps_ns_from_utc_by_table(date, unix_ns - days * kNsPerDay).value_or(0);
}

}  // namespace

GpsFix fix_of(const UbxNavPvt& m, TimestampNs t_gps_ns) {
  GpsFix f;
  f.t_ns = t_gps_ns;
  f.antenna = {deg_to_rad(m.lat_deg), deg_to_rad(m.lon_deg), m.height_m};
  const bool fix3d = m.gnss_fix_ok && (m.fix_type == 3 || m.fix_type == 4);
  f.quality = !fix3d                ? FixQuality::kInvalid
              : m.carr_soln == 2    ? FixQuality::kRtkFixed
              : m.carr_soln == 1    ? FixQuality::kRtkFloat
              : m.diff_soln         ? FixQuality::kDgps
                                    : FixQuality::kSingle;
  f.satellites = m.satellites;
  f.hdop = m.pdop;  // NAV-PVT has the position DOP only
  f.geoid_separation_m = m.height_m - m.height_msl_m;
  if (std::isfinite(m.h_acc_m) && std::isfinite(m.v_acc_m) && m.h_acc_m > 0 && m.v_acc_m > 0)
    f.sigma_ned_m = Eigen::Vector3d(m.h_acc_m / std::sqrt(2.0), m.h_acc_m / std::sqrt(2.0), m.v_acc_m);
  f.ground_speed_mps = m.vel_ned_mps.head<2>().norm();
  f.course_rad = std::fmod(std::atan2(m.vel_ned_mps.y(), m.vel_ned_mps.x()) + 2 * kPi, 2 * kPi);
  return f;
}

UbxEventSource::UbxEventSource(std::string name, const UbxInputOptions& options)
    : name_(std::move(name)), options_(options), stream_(name_) {}

TimestampNs UbxEventSource::gps_time_of(std::uint32_t itow_ms) const {
  const TimestampNs near_ns = reference_gps_ns_ ? *reference_gps_ns_ : host_gps_now_ns();
  const TimestampNs tow_ns = static_cast<TimestampNs>(itow_ms) * 1'000'000;
  const double weeks = std::round(static_cast<double>(near_ns - tow_ns) / static_cast<double>(kWeekNs));
  return static_cast<TimestampNs>(weeks) * kWeekNs + tow_ns;
}

void UbxEventSource::take(const UbxFrame& f, TimestampNs arrival_ns) {
  if (f.cls != kUbxClassNav || (f.id != kUbxIdNavPvt && f.id != kUbxIdNavRelPosNed)) return;  // not ours
  if (f.id == kUbxIdNavPvt) {
    auto m = decode_nav_pvt(f);
    if (!m) {
      ++stats_.malformed;
      stats_.note(name_ + ": " + m.error().message);
      return;
    }
    // Its UTC date and time put later times of week in their week.
    if (m->valid_date && m->valid_time) {
      const CivilDate d{m->year, m->month, m->day};
      const std::int64_t ns_of_day =
          ((m->hour * 60LL + m->minute) * 60 + m->second) * kNsPerSecond + m->nano_ns;
      if (const auto t = gps_ns_from_utc_by_table(d, ns_of_day)) reference_gps_ns_ = *t;
    }
    if (!options_.fixes) return;
    const TimestampNs t = gps_time_of(m->itow_ms);
    if (t <= last_fix_ns_) {
      ++stats_.dropped, ++stats_.out_of_order;
      stats_.note(name_ + ": NAV-PVT at iTOW " + std::to_string(m->itow_ms) + " ms not after the previous: dropped");
      return;
    }
    last_fix_ns_ = t;
    GpsFix fix = fix_of(*m, t);
    fix.arrival_ns = arrival_ns;
    NavEvent e;
    e.sample = fix;
    e.sensor_clock = ClockDomain::kGps;
    e.velocity_ned_mps = m->vel_ned_mps;
    ready_.push_back(std::move(e));
    return;
  }
  auto m = decode_nav_relposned(f);
  if (!m) {
    ++stats_.malformed;
    stats_.note(name_ + ": " + m.error().message);
    return;
  }
  const TimestampNs t = gps_time_of(m->itow_ms);
  if (t <= last_baseline_ns_) {
    ++stats_.dropped, ++stats_.out_of_order;
    stats_.note(name_ + ": NAV-RELPOSNED at iTOW " + std::to_string(m->itow_ms) +
                " ms not after the previous: dropped");
    return;
  }
  last_baseline_ns_ = t;
  BaselineMeasurement b;
  b.t_ns = t;
  b.arrival_ns = arrival_ns;
  b.ned_m = m->rel_pos_ned_m;
  b.sigma_ned_m = m->acc_ned_m;
  b.carr_soln = m->carr_soln;
  b.valid = m->rel_pos_valid && m->gnss_fix_ok;
  NavEvent e;
  e.sample = b;
  e.sensor_clock = ClockDomain::kGps;
  ready_.push_back(std::move(e));
}

void UbxEventSource::sync() {
  const UbxStreamCounts& c = stream_.counts();
  stats_.malformed += c.bad_checksums - seen_bad_;
  stats_.oversized += c.oversized - seen_oversized_;
  seen_bad_ = c.bad_checksums, seen_oversized_ = c.oversized;
  const auto& messages = stream_.messages();
  for (; seen_messages_ < messages.size(); ++seen_messages_) stats_.note(messages[seen_messages_]);
}

bool UbxEventSource::pop(NavEvent& out) {
  if (ready_.empty()) return false;
  out = std::move(ready_.front());
  ready_.pop_front();
  ++stats_.events;
  return true;
}

// ---- UDP ------------------------------------------------------------------------------------------

UdpUbxInput::UdpUbxInput(UdpReceiver socket, std::string uri, const UbxInputOptions& options)
    : socket_(std::move(socket)), uri_(std::move(uri)), source_(uri_, options) {}

Expected<std::unique_ptr<UdpUbxInput>> UdpUbxInput::open(const std::string& bind_host, std::uint16_t port,
                                                         const UdpReceiverOptions& socket_options,
                                                         const UbxInputOptions& options, std::string uri) {
  if (uri.empty()) uri = "udp://" + bind_host + ":" + std::to_string(port) + "?format=ubx";
  auto socket = UdpReceiver::bind(bind_host, port, socket_options);
  if (!socket) return socket.error();
  return std::unique_ptr<UdpUbxInput>(new UdpUbxInput(std::move(*socket), std::move(uri), options));
}

Expected<NavReadStatus> UdpUbxInput::read(NavEvent& out, std::chrono::nanoseconds timeout) {
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  for (;;) {
    if (source_.pop(out)) return NavReadStatus::kEvent;
    const TimestampNs now = monotonic_now_ns();
    auto got = socket_.receive(datagram_, std::chrono::nanoseconds(std::max<TimestampNs>(deadline - now, 0)));
    if (!got) return got.error();
    if (!*got) return source_.pop(out) ? NavReadStatus::kEvent : NavReadStatus::kTimeout;
    NavInputStats& st = source_.stats();
    ++st.datagrams;
    if (datagram_.oversized) st.bytes += datagram_.size;  // the source counts the others
    if (!udp_datagram_usable(st, datagram_, uri_, socket_.options().max_datagram_bytes)) continue;
    source_.push(datagram_.bytes.data(), datagram_.bytes.size(), datagram_.arrival_ns,
                 [this](const UbxFrame& f, TimestampNs arrival_ns) {
                   const auto bytes = encode_ubx(f.cls, f.id, f.payload);
                   tap(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), arrival_ns, true);
                 });
  }
}

// ---- Serial ---------------------------------------------------------------------------------------

SerialUbxInput::SerialUbxInput(SerialPort port, std::string uri, const UbxInputOptions& options)
    : port_(std::move(port)), uri_(std::move(uri)), source_(uri_, options) {}

Expected<std::unique_ptr<SerialUbxInput>> SerialUbxInput::open(const std::string& path, int baud,
                                                               const UbxInputOptions& options, std::string uri) {
  if (uri.empty()) uri = "serial://" + path + "?baud=" + std::to_string(baud) + "&format=ubx";
  auto port = SerialPort::open(path, baud);
  if (!port) return port.error();
  return std::unique_ptr<SerialUbxInput>(new SerialUbxInput(std::move(*port), std::move(uri), options));
}

Expected<NavReadStatus> SerialUbxInput::read(NavEvent& out, std::chrono::nanoseconds timeout) {
  const TimestampNs deadline = monotonic_now_ns() + std::max<std::int64_t>(timeout.count(), 0);
  std::uint8_t buffer[4096];
  for (;;) {
    if (source_.pop(out)) return NavReadStatus::kEvent;
    if (hung_up_) return NavReadStatus::kEnd;
    const TimestampNs now = monotonic_now_ns();
    auto r = port_.read(buffer, std::chrono::nanoseconds(std::max<TimestampNs>(deadline - now, 0)));
    if (!r) return r.error();
    if (r->bytes > 0) {
      source_.push(buffer, r->bytes, r->arrival_ns, [this](const UbxFrame& f, TimestampNs arrival_ns) {
        const auto bytes = encode_ubx(f.cls, f.id, f.payload);
        tap(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), arrival_ns, true);
      });
      continue;
    }
    if (r->hung_up) {
      hung_up_ = true;
      source_.stats().note(uri_ + ": the serial port hung up (device unplugged or the other side closed)");
      continue;
    }
    if (monotonic_now_ns() >= deadline) return source_.pop(out) ? NavReadStatus::kEvent : NavReadStatus::kTimeout;
  }
}

}  // namespace augrig::nav
