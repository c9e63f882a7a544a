// Nav inputs as recorded (record.hpp NavInputRecord): their sensor time read from the data itself.
//
// A live nav input is recorded as received (`augrig run --nav`): an NMEA line or a gpsd report as
// TEXT, an augrig IMU datagram (nav/imu_stream.hpp) as a BLOB, with the host arrival time. The
// sensor's time of validity is inside the data; NavInputStamper reads it out so that the row's
// t_ns and clock say it (the `nav_input` table is indexed by stream and t_ns):
//   - IMU datagram: the newest (last) sample's t_ns, in the clock domain the datagram names;
//   - NMEA sentence with a UTC time tag (GGA, GLL, GNS, GST, RMC, ZDA): GPS time, once the date is
//     known (ZDA and RMC carry it; a sentence before any date stays unknown), with the given
//     leap seconds; a time of day that falls more than 12 h before the previous one of the stream
//     is taken as the next day (midnight passed before the next RMC or ZDA);
//   - anything else (VTG and HDT, which carry no time; gpsd reports; a line whose checksum fails;
//     a datagram that does not decode): t_ns 0, clock unknown.
// The date is kept per stream. Not thread-safe: one stamper per thread (or per input).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>

#include "core/conventions.hpp"
#include "nav/gps_time.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder {

// What stamp() found in one input.
enum class NavInputTimeSource : std::uint8_t {
  kNone,          // no time in the data (or unreadable): t_ns 0, clock unknown
  kNoDateYet,     // an NMEA time tag before the stream's first date: t_ns 0, clock unknown
  kImuDatagram,   // the datagram's last sample
  kNmeaTimeTag,   // an NMEA UTC time tag and the stream's date, as GPS time
};

class NavInputStamper {
 public:
  explicit NavInputStamper(int leap_seconds = nav::kDefaultLeapSeconds) : leap_seconds_(leap_seconds) {}

  // Sets `record.t_ns` and `record.clock` from `record.data` (record.binary: an IMU datagram; else
  // a text line), or to 0 and ClockDomain::kUnknown when the data does not say them.
  NavInputTimeSource stamp(NavInputRecord& record);

  // The date an NMEA stream has reached (nullopt: none seen yet).
  std::optional<nav::CivilDate> date(const std::string& stream) const;

 private:
  struct StreamState {
    std::optional<nav::CivilDate> date;
    std::int64_t last_ns_of_day = -1;
  };
  int leap_seconds_;
  std::map<std::string, StreamState> streams_;
};

// The sensor time of one augrig IMU datagram: its last sample's t_ns and the datagram's clock;
// nullopt when it does not decode.
std::optional<std::pair<TimestampNs, ClockDomain>> imu_datagram_time(std::string_view bytes);

}  // namespace augrig::recorder
