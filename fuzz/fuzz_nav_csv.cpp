// The other CSV readers of nav/logs.hpp: navigation solutions, the frame index and camera poses.
// The first byte picks the reader; the rest is the file.
#include <sstream>

#include "fuzz/fuzz_common.hpp"
#include "nav/logs.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  augrig::fuzz::Input input(data, size);
  const std::uint8_t which = input.byte();
  std::istringstream in{std::string(input.rest())};
  switch (which % 3) {
    case 0:
      (void)augrig::nav::parse_nav_solution_csv(in, "fuzz.csv");
      break;
    case 1:
      (void)augrig::nav::parse_frame_index_csv(in, "fuzz.csv");
      break;
    default:
      (void)augrig::nav::parse_camera_pose_csv(in, "fuzz.csv");
      break;
  }
  return 0;
}
