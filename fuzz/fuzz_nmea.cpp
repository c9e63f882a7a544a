// parse_nmea (nav/nmea.hpp) on arbitrary log text: never throws, never crashes.
#include <sstream>

#include "nav/nmea.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  augrig::nav::NmeaOptions options;
  options.require_checksum = size % 2 == 0;  // both modes; a checksum is 2 hex digits to find
  if (size % 3 == 0) options.default_date = augrig::nav::CivilDate{2024, 5, 17};
  (void)augrig::nav::parse_nmea(in, "fuzz.nmea", options);
  return 0;
}
