// parse_imu_csv (nav/logs.hpp): IMU increment logs.
#include <sstream>

#include "nav/logs.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  (void)augrig::nav::parse_imu_csv(in, "fuzz.csv");
  return 0;
}
