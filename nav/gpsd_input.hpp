// gpsd_input: GPS fixes from a gpsd daemon through libgps (gpsd://HOST[:PORT][?device=PATH]).
// The client watches gpsd's JSON reports (gps_stream WATCH_ENABLE | WATCH_JSON, WATCH_DEVICE with
// device=) and merges those of one epoch, by their time, into one GpsFix:
//   TPV  time (UTC -> GPS time with gpsd's leap seconds when it reports them, else the configured
//        ones), lat/lon, altHAE (else altMSL + geoidSep), geoidSep, mode/status -> FixQuality
//        (RTK fixed/float, DGPS, dead reckoning, PPS), speed and track, velN/velE/velD;
//   GST  lat/lon/alt 1-sigma errors -> sigma_ned_m;
//   ATT  heading -> heading_rad (gpsd 3.22 writes ATT reports with a time as broken JSON; the
//        heading and time are then read from the report text);
//   SKY  satellites used and HDOP, applied to the fixes that follow.
// An epoch's fix is emitted when a report of a later time arrives or after quiet_ns without
// reports. docs/NAV_LIVE.md has the details.
// Every report must be one well-formed JSON object with a string "class" before libgps sees it
// (libgps 3.22 never returns from gps_unpack() on some malformed ones, e.g. {s"class":"TPV"}), so
// the client reads gpsd's socket itself rather than through gps_read(); others are counted as
// malformed and dropped. Times outside the years 1980..2099 (nav/gps_time.hpp) are dropped too.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "nav/gps_time.hpp"
#include "nav/live_input.hpp"
#include "nav/types.hpp"

namespace augrig::nav {

struct GpsdOptions {
  std::string host = "localhost";
  std::uint16_t port = 2947;
  std::string device;                      // only this device's reports (and WATCH_DEVICE); empty: all
  TimestampNs quiet_ns = 20'000'000;       // an epoch closes after this long without a report
  // GPS - UTC when gpsd does not report it; unset: the table's value for the report's UTC date
  // (leap_seconds_on_day(), nav/gps_time.hpp).
  std::optional<int> leap_seconds;
  std::chrono::milliseconds connect_timeout{3000};
};

// The report logic without a connection: gpsd JSON reports in (one object per call, as gpsd sends
// them), fixes out. Checked as JSON, then parsed with libgps (gps_unpack), so tests can feed
// reports gpsd would send.
class GpsdReportMerger {
 public:
  GpsdReportMerger(std::string name, const GpsdOptions& options);
  ~GpsdReportMerger();
  GpsdReportMerger(const GpsdReportMerger&) = delete;
  GpsdReportMerger& operator=(const GpsdReportMerger&) = delete;

  void push_report(std::string_view json, TimestampNs arrival_ns);
  void poll_quiet(TimestampNs now_ns);
  std::optional<TimestampNs> quiet_deadline_ns() const;
  void flush();  // end of stream: emits the open epoch
  bool pop(NavEvent& out);
  NavInputStats& stats() { return stats_; }
  const NavInputStats& stats() const { return stats_; }

 private:
  struct Pending {
    TimestampNs t_ns = 0;
    TimestampNs arrival_ns = 0;      // of the epoch's first TPV
    TimestampNs last_report_ns = 0;  // arrival of its last report
    std::optional<GpsFix> fix;       // from the TPV
    std::optional<Eigen::Vector3d> velocity_ned_mps;
    std::optional<Eigen::Vector3d> sigma_ned_m;
    std::optional<double> heading_rad;
  };
  struct Libgps;  // the gps_data_t that reports are unpacked into

  Pending& epoch_at(TimestampNs t_ns, TimestampNs arrival_ns);
  void emit();
  void on_tpv(std::string_view json, TimestampNs arrival_ns);
  void on_gst(TimestampNs arrival_ns);
  void on_att(std::string_view json, TimestampNs arrival_ns);
  void on_sky();
  // GPS ns of a report's UTC time, or nullopt (counted as malformed, with a note naming the class)
  // outside the supported years (nav/gps_time.hpp).
  std::optional<TimestampNs> gps_time(std::int64_t unix_s, std::int64_t ns, const char* cls);

  std::string name_;
  GpsdOptions options_;
  std::unique_ptr<Libgps> gps_;
  NavInputStats stats_;
  std::optional<Pending> pending_;
  std::optional<TimestampNs> last_emitted_t_ns_;
  int satellites_ = 0;
  double hdop_ = 0;
  std::uint64_t untimed_tpv_ = 0;
  std::deque<NavEvent> ready_;
};

class GpsdInput : public NavInput {
 public:
  // Connects (within connect_timeout) and starts watching. An Error when gpsd cannot be reached.
  static Expected<std::unique_ptr<GpsdInput>> open(const GpsdOptions& options, std::string uri = {});
  ~GpsdInput() override;
  std::string uri() const override { return uri_; }
  Expected<NavReadStatus> read(NavEvent& out, std::chrono::nanoseconds timeout) override;
  NavInputStats stats() const override { return merger_.stats(); }

 private:
  struct Connection;
  GpsdInput(std::unique_ptr<Connection> connection, std::string uri, const GpsdOptions& options);
  // The next whole report line received (without its '\n'); false when none is buffered yet.
  bool next_line(std::string& line);

  std::unique_ptr<Connection> connection_;
  std::string uri_;
  GpsdReportMerger merger_;
  bool ended_ = false;
};

}  // namespace augrig::nav
