// NmeaStream (nav/nmea.hpp), the live form of the NMEA parser: lines pushed one at a time with
// arrival times, quiet flushes and pops in between, as a UDP or serial input drives it.
#include <string_view>

#include "nav/nmea.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view text(reinterpret_cast<const char*>(data), size);
  augrig::nav::NmeaOptions options;
  options.require_checksum = size % 2 == 0;
  augrig::nav::NmeaStream stream("fuzz", options);
  augrig::TimestampNs now = 1'000'000'000;
  std::size_t k = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view() : text.substr(nl + 1);
    // Every third line without an arrival time (the line's own prefix, if any, is used).
    stream.push_line(line, k % 3 == 2 ? 0 : now);
    now += 10'000'000 * static_cast<augrig::TimestampNs>(line.size() % 7);
    (void)stream.flush_if_quiet(now, 25'000'000);
    while (stream.pop()) {
    }
    if (++k % 16 == 0) (void)stream.take_messages();
  }
  stream.flush();
  while (stream.pop()) {
  }
  (void)stream.counters();
  (void)stream.take_messages();
  return 0;
}
