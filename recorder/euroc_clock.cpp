// The EuRoC export's clock (docs/REPLAY.md): every exported timestamp on one clock, GPS time
// where the recording gives a way to it, so that imu0, the nav logs and the images line up.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <iomanip>
#include <limits>
#include <span>
#include <sstream>

#include "core/csv.hpp"
#include "nav/imu_stream.hpp"
#include "recorder/euroc_export_detail.hpp"
#include "recorder/nav_inputs.hpp"

namespace augrig::recorder::euroc_detail {

void LowerEnvelope::finish() {
  std::sort(points_.begin(), points_.end());
  knots_.clear();
  constexpr TimestampNs kWindowNs = 10'000'000'000;
  for (std::size_t i = 0; i < points_.size();) {
    const TimestampNs start = points_[i].first;
    TimestampNs lo = points_[i].second, last = start;
    for (; i < points_.size() && points_[i].first < start + kWindowNs; ++i) {
      lo = std::min(lo, points_[i].second);
      last = points_[i].first;
    }
    knots_.emplace_back(start + (last - start) / 2, lo);
  }
}

TimestampNs LowerEnvelope::at(TimestampNs x) const {
  if (knots_.empty()) return 0;
  if (x <= knots_.front().first) return knots_.front().second;
  if (x >= knots_.back().first) return knots_.back().second;
  const auto it =
      std::upper_bound(knots_.begin(), knots_.end(), std::pair{x, std::numeric_limits<TimestampNs>::min()});
  const auto& [x1, d1] = *it;
  const auto& [x0, d0] = *(it - 1);
  const double f = static_cast<double>(x - x0) / static_cast<double>(x1 - x0);
  return d0 + static_cast<TimestampNs>(std::llround(f * static_cast<double>(d1 - d0)));
}

TimestampNs ExportClock::map(int camera, TimestampNs t_ns) const {
  switch (mode) {
    case Mode::kIdentity:
      return t_ns;
    case Mode::kConstant:
      return t_ns - constant_ns[camera];
    case Mode::kThroughHost: {
      const TimestampNs host = frames_on_host ? t_ns : t_ns + device_to_host[camera].at(t_ns);
      const TimestampNs guess = host - host_to_gps.at(std::numeric_limits<TimestampNs>::max());
      return host - host_to_gps.at(guess);
    }
  }
  return t_ns;
}

FrameInfos read_frame_infos(const RecordingReader& reader, EurocExportReport& report) {
  const std::size_t n = reader.frame_count();
  FrameInfos out;
  out.frames.resize(n);
  out.all_gps = out.all_device = out.all_host = n > 0;
  std::vector<TimestampNs> t;
  for (std::size_t i = 0; i < n; ++i) {
    auto info = reader.read_frame_info(i);
    if (!info) continue;
    t.push_back(info->raw.t_key_ns);
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      const ClockDomain c = info->raw[id].clock;
      out.all_gps &= c == ClockDomain::kGps;
      out.all_device &= c == ClockDomain::kDevice;
      out.all_host &= c == ClockDomain::kHostMonotonic;
    }
    out.frames[i] = std::move(*info);
  }
  report.rate_hz = median_rate_hz(std::move(t));
  return out;
}

void read_nav_streams(const RecordingReader& reader, NavStreams& nav, EurocExportReport& report) {
  nav.rows = reader.nav_inputs();
  if (!nav.rows)
    report.problems.push_back(strip_function(nav.rows.error().message) + "; no nav input exported");
  else
    for (const NavInputRecord& r : *nav.rows) nav.by_stream[r.stream].push_back(&r);
}

namespace {

// "offsets to gps A, B ns" in the recording's clock_domains meta (augrig demo writes it).
std::optional<std::array<TimestampNs, 2>> stated_gps_offsets(const std::string& clock_domains) {
  const std::string key = "offsets to gps ";
  const auto p = clock_domains.find(key);
  if (p == std::string::npos) return std::nullopt;
  std::array<TimestampNs, 2> o{};
  const char* s = clock_domains.data() + p + key.size();
  const char* end = clock_domains.data() + clock_domains.size();
  auto r = std::from_chars(s, end, o[0]);
  if (r.ec != std::errc() || r.ptr + 2 > end || r.ptr[0] != ',' || r.ptr[1] != ' ') return std::nullopt;
  r = std::from_chars(r.ptr + 2, end, o[1]);
  if (r.ec != std::errc()) return std::nullopt;
  return o;
}

// "clock_offset camera=left t_device_ns=... offset_ns=..." events (augrig run): host - device.
void add_clock_offset_events(const std::vector<EventRecord>& events, LowerEnvelope (&device_to_host)[2]) {
  for (const EventRecord& e : events) {
    if (e.text.rfind("clock_offset ", 0) != 0) continue;
    auto field = [&](const std::string& k) -> std::string {
      const auto p = e.text.find(" " + k + "=");
      if (p == std::string::npos) return {};
      const auto v = p + k.size() + 2;
      return e.text.substr(v, e.text.find(' ', v) - v);
    };
    const std::string cam = field("camera");
    TimestampNs t = 0, off = 0;
    if ((cam != "left" && cam != "right") || !parse_csv_int64(field("t_device_ns"), t) ||
        !parse_csv_int64(field("offset_ns"), off))
      continue;
    device_to_host[cam == "left" ? 0 : 1].add(t, off);
  }
}

std::string fmt_offset_ms(TimestampNs ns) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(3) << static_cast<double>(ns) / 1e6 << " ms";
  return o.str();
}

// Host arrival against GPS time of every nav input that says its own time (IMU datagrams in GPS
// time, NMEA sentences with a time tag).
void add_nav_arrivals(const NavStreams& nav, LowerEnvelope& host_to_gps) {
  NavInputStamper stamper;
  for (const auto& [name, rows] : nav.by_stream)
    for (const NavInputRecord* r : rows) {
      if (r->arrival_ns == 0) continue;
      if (r->binary) {
        auto d = nav::decode_imu_datagram(std::span<const std::uint8_t>(
            reinterpret_cast<const std::uint8_t*>(r->data.data()), r->data.size()));
        if (d && d->clock == ClockDomain::kGps)
          for (const nav::ImuSample& s : d->samples) host_to_gps.add(s.t_ns, r->arrival_ns - s.t_ns);
      } else if (is_nmea_line(r->data)) {
        NavInputRecord copy = *r;
        if (stamper.stamp(copy) == NavInputTimeSource::kNmeaTimeTag)
          host_to_gps.add(copy.t_ns, r->arrival_ns - copy.t_ns);
      }
    }
}

// Each camera's device clock -> host: the recording's clock_offset events, else the frames'
// own t_host_ns.
void add_device_to_host(const RecordingReader& reader, const FrameInfos& infos, ExportClock& clk) {
  if (auto ev = reader.events()) add_clock_offset_events(*ev, clk.device_to_host);
  for (int c = 0; c < 2; ++c) {
    if (!clk.device_to_host[c].empty()) continue;
    for (const auto& info : infos.frames)
      if (info && info->raw[static_cast<CameraId>(c)].t_host_ns != 0) {
        const Frame& f = info->raw[static_cast<CameraId>(c)];
        clk.device_to_host[c].add(f.t_ns, f.t_host_ns - f.t_ns);
      }
  }
}

// Frames on a device or the host clock -> host -> GPS time through the nav inputs' arrivals;
// leaves `clk` as it was when the recording gives no way.
void try_through_host(const RecordingReader& reader, const FrameInfos& infos, const NavStreams& nav,
                      ExportClock& clk) {
  add_nav_arrivals(nav, clk.host_to_gps);
  clk.frames_on_host = infos.all_host;
  if (!infos.all_host) add_device_to_host(reader, infos, clk);
  const bool cameras_ok =
      infos.all_host || (!clk.device_to_host[0].empty() && !clk.device_to_host[1].empty());
  if (clk.host_to_gps.empty() || !cameras_ok) return;
  clk.host_to_gps.finish();
  for (auto& e : clk.device_to_host) e.finish();
  clk.mode = ExportClock::Mode::kThroughHost;
  clk.clock = ClockDomain::kGps;
  clk.note = std::string("frames: ") +
             (infos.all_host
                  ? "host CLOCK_MONOTONIC"
                  : "each camera's device clock -> host CLOCK_MONOTONIC (lower envelope of t_host_ns - t_ns, "
                    "or the recording's clock_offset events)") +
             " -> GPS time (lower envelope of the nav inputs' host arrival minus their own time, " +
             std::to_string(clk.host_to_gps.size()) + " samples; host - GPS " +
             fmt_offset_ms(clk.host_to_gps.at(0)) + " at the start)";
}

}  // namespace

ExportClock choose_export_clock(const RecordingReader& reader, const FrameInfos& infos, const NavStreams& nav,
                                EurocExportReport& report) {
  ExportClock clk;
  if (infos.all_gps) {
    clk.clock = ClockDomain::kGps;
    clk.note = "the frames were recorded in GPS time";
  } else if (const auto off = stated_gps_offsets(reader.meta("clock_domains")); off && infos.all_device) {
    clk.mode = ExportClock::Mode::kConstant;
    clk.constant_ns[0] = (*off)[0];
    clk.constant_ns[1] = (*off)[1];
    clk.clock = ClockDomain::kGps;
    clk.note = "frames: device clock minus the camera offsets to GPS time the recording states (" +
               std::to_string((*off)[0]) + ", " + std::to_string((*off)[1]) + " ns)";
  } else if (infos.all_device || infos.all_host) {
    try_through_host(reader, infos, nav, clk);
  }
  if (clk.clock == ClockDomain::kUnknown) {
    const bool first = !infos.frames.empty() && infos.frames[0];
    clk.clock = first ? infos.frames[0]->raw.left.clock : ClockDomain::kUnknown;
    clk.note = "the frames' recorded clock (" + std::string(to_string(clk.clock)) +
               "): the recording gives no way to GPS time";
    if (!nav.by_stream.empty())
      report.notes.push_back(
          "the frames could not be put on GPS time (no camera offsets and no nav input with "
          "both its own time and its host arrival): imu0 and the nav logs keep their own clock");
  }
  report.clock = clk.clock;
  report.clock_note = clk.note;
  return clk;
}

}  // namespace augrig::recorder::euroc_detail
