// nmea: NMEA 0183 GPS logs, read into GpsFix epochs and written from them. Format, field meanings,
// precision and the warning rules: docs/NAV_FORMATS.md.
//
// Read: GGA (position, quality, satellites, HDOP, geoid separation), RMC (date, ground speed,
// course), VTG (ground speed, course), HDT (true heading), GST (position error sigmas), ZDA (date),
// and u-blox's $PUBX,04 (the receiver's own GPS - UTC leap seconds).
// Sentences sharing a UTC time tag merge into one GpsFix; VTG and HDT carry no time and join the
// epoch of the last time tag seen. Ellipsoidal height = GGA altitude (MSL) + GGA geoid separation.
// Every line may start with a host arrival time, "<arrival_ns> $GNGGA,...".
//
// Malformed lines never throw and never stop the parse: each is counted in LogIssues with a
// "file:line: what" message and skipped. An Error comes back only when the file cannot be read,
// when no GGA sentence could be used, or when malformed lines exceed max_malformed_fraction.
//
// Live inputs (nav/live_input.hpp) use NmeaStream, the same sentence code one line at a time: an
// epoch becomes a fix as soon as the next time tag arrives, or when the caller says the sender has
// gone quiet (flush_if_quiet), so no fix is held back longer than that.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/expected.hpp"
#include "nav/gps_time.hpp"
#include "nav/types.hpp"

namespace augrig::nav {

struct NmeaOptions {
  // GPS - UTC in seconds. Unset (the default): the receiver's own report ($PUBX,04) from the epoch it
  // comes in on, and for fixes before any report the value that applied on the fix's UTC date
  // (leap_seconds_on(), nav/gps_time.hpp). Set: this value for every fix, checked against the
  // receiver's reports and the table (LeapSecondsUse). docs/NAV_FORMATS.md, "Leap seconds".
  std::optional<int> leap_seconds;
  // Date for fixes seen before any ZDA/RMC date; without it such fixes are reported and dropped.
  std::optional<CivilDate> default_date;
  // Fraction of non-empty lines that may be malformed (bad checksum, garbage, bad fields) before
  // the parse fails with an Error. 1.0: never fail for malformed lines.
  double max_malformed_fraction = 1.0;
  // Lines longer than this (after the optional arrival prefix) are malformed.
  std::size_t max_line_length = 1024;
  // A sentence without "*HH" is malformed when true; when false it is accepted unchecked.
  bool require_checksum = true;
  // At most this many messages are kept in LogIssues (the counters stay exact).
  std::size_t max_messages = 1000;
};

// GPS - UTC as a log's fixes were converted with, where it came from, and what the log itself says.
struct LeapSecondsUse {
  std::optional<int> given;            // NmeaOptions::leap_seconds
  std::map<int, std::size_t> applied;  // value -> fixes converted with it
  std::size_t from_receiver = 0;       // fixes converted with the receiver's report (none given)
  std::size_t from_table = 0;          // fixes converted with the table's value for their date (none given)
  std::optional<CivilDate> first_date, last_date;  // UTC dates of the first and the last fix
  std::size_t receiver_reports = 0;          // $PUBX,04 with the count the receiver knows
  std::size_t receiver_default_reports = 0;  // $PUBX,04 with its firmware default ("15D"): not used
  std::optional<int> receiver_value;         // the last one reported (not a default)
  // Fixes whose value differs from the receiver's report or, before any, from the table: with a
  // value given, those the given value gets wrong; without, those where the receiver contradicts the
  // table (its value is used). The first is described, "file:line: ...".
  std::size_t disagreements = 0;
  std::string first_disagreement;
};
// One line: the value(s) applied and where they came from, e.g. "GPS-UTC 17 s (the leap-second
// table for the UTC date 2016-06-01)".
std::string describe(const LeapSecondsUse& use);

struct NmeaLog {
  std::vector<GpsFix> fixes;  // sorted by t_ns, strictly increasing
  LogIssues issues;
  // Sentences with a valid checksum, per sentence type ("GGA", "RMC", ..., also unused types).
  std::map<std::string, std::size_t> sentence_counts;
  std::size_t lines = 0;               // lines read, including empty ones
  std::size_t epochs_without_gga = 0;  // time tags seen only in RMC/GST/ZDA (no fix made)
  std::size_t fixes_without_date = 0;  // fixes before any date and no default_date (dropped)
  std::size_t unused_sentences = 0;    // valid sentences of types not read (GSV, GSA, ...)
  LeapSecondsUse leap_seconds;
};

// Parses an NMEA log; `name` is used in messages ("tanker.nmea:12: bad checksum ...").
Expected<NmeaLog> parse_nmea(std::istream& in, const std::string& name, const NmeaOptions& options = {});
Expected<NmeaLog> read_nmea_file(const std::string& path, const NmeaOptions& options = {});

// The incremental form of parse_nmea for live streams: lines in, GpsFix epochs out, with the same
// sentence parsing, epoch merging, date tracking and ordering rules (the fixes it yields, pushed the
// lines of a log, are those parse_nmea gives for the log). Not checked here, being whole-log
// properties: max_malformed_fraction, gaps, the "no usable fix" error. Line numbers in messages
// count the lines pushed. Never throws.
class NmeaStream {
 public:
  // `name` is used in messages ("udp://0.0.0.0:10110:12: bad checksum ...").
  explicit NmeaStream(const std::string& name, const NmeaOptions& options = {});
  ~NmeaStream();
  NmeaStream(NmeaStream&&) noexcept;
  NmeaStream& operator=(NmeaStream&&) noexcept;

  // One line, with or without its line ending. arrival_ns != 0 (the host time the line arrived)
  // replaces the line's own "<arrival_ns> " prefix, which is accepted and stripped either way.
  // When the line's time tag differs from the open epoch's, that epoch is closed first.
  void push_line(std::string_view line, TimestampNs arrival_ns = 0);
  // Closes the open epoch, if any (end of stream): its fix, if it makes one, becomes ready.
  void flush();
  // flush() if an epoch is open and its last line arrived at least quiet_ns before now_ns (both on
  // the arrival clock); true when it flushed. Never flushes while arrival times are unknown (0).
  bool flush_if_quiet(TimestampNs now_ns, TimestampNs quiet_ns);
  bool epoch_open() const;
  TimestampNs last_arrival_ns() const;  // of the last non-empty line with a known arrival time; 0: none

  // Fixes ready, oldest first (strictly increasing t_ns).
  std::size_t ready() const;
  std::optional<GpsFix> pop();

  // The counters so far, as parse_nmea counts them (`fixes` stays empty: fixes leave by pop(),
  // and `issues.gaps` is not counted); issues.messages holds the messages not yet taken.
  const NmeaLog& counters() const;
  // The messages since the last call (at most NmeaOptions::max_messages between two calls).
  std::vector<std::string> take_messages();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct NmeaWriterOptions {
  // GPS - UTC. Unset: the table's value in force at each fix's GPS time, as a receiver would output
  // it (an inserted leap second is written 23:59:60).
  std::optional<int> leap_seconds;
  std::string talker = "GN";          // GGA, RMC, VTG, GST, ZDA
  std::string heading_talker = "GN";  // HDT
  int time_decimals = 3;              // hhmmss.sss; 0..9
  bool write_arrival_prefix = false;  // "<arrival_ns> " before each sentence when arrival_ns != 0
  const char* line_ending = "\r\n";
  bool rmc = true;  // RMC with the date (and speed/course when known)
  bool vtg = true;  // VTG when ground_speed_mps is set
  bool hdt = true;  // HDT when heading_rad is set
  bool gst = true;  // GST when sigma_ned_m is set
  bool zda = true;  // ZDA with the date
  // u-blox $PUBX,04 after the epoch's sentences: date, time, UTC week and time of week, and the
  // leap seconds applied (clock bias, drift and time-pulse granularity left empty).
  bool pubx04 = false;
};

// XOR of the characters between '$' and '*' (pass them without either).
std::uint8_t nmea_checksum(std::string_view body);
// "$" + body + "*HH" (no line ending).
std::string nmea_sentence(std::string_view body);

// The sentences of one epoch, in the order GGA, GST, RMC, VTG, HDT, ZDA (PUBX,04), each as "$...*HH"
// without line ending or arrival prefix. Position: 8 decimals of arc minutes (< 0.02 mm), heights
// 4 decimals, GGA altitude = antenna.h_m - geoid_separation_m. A fix with quality kInvalid is
// written with quality 0 (and RMC status V); NaN coordinates are written as empty fields.
std::vector<std::string> nmea_sentences(const GpsFix& fix, const NmeaWriterOptions& options = {});
// All epochs as text, each sentence ended by options.line_ending.
std::string write_nmea(const std::vector<GpsFix>& fixes, const NmeaWriterOptions& options = {});
Status write_nmea_file(const std::string& path, const std::vector<GpsFix>& fixes,
                       const NmeaWriterOptions& options = {});

}  // namespace augrig::nav
