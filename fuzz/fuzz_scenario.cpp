// parse_scenario (sim/scenario.hpp): scenario YAML, and gps_ns_from_utc on the same text.
#include <string>

#include "sim/scenario.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  (void)augrig::sim::parse_scenario(text, "fuzz.yaml");
  if (size < 64) (void)augrig::sim::gps_ns_from_utc(text);
  return 0;
}
