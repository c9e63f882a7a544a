// The EuRoC readers (recorder/euroc_source.hpp): a camera's data.csv or imu0/data.csv (first byte), read
// from a temp file; IMU rows that read are also turned into increments.
#include "fuzz/fuzz_common.hpp"
#include "recorder/euroc_source.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  augrig::fuzz::Input input(data, size);
  const std::uint8_t which = input.byte();
  const std::string path = augrig::fuzz::write_temp("data.csv", input.rest());
  if (which % 2 == 0) {
    (void)augrig::recorder::read_euroc_camera_csv(path);
  } else if (auto rows = augrig::recorder::read_euroc_imu_csv(path)) {
    (void)augrig::recorder::imu_increments(*rows);
  }
  return 0;
}
