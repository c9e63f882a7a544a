// The calibration importers (render/calib_import.hpp), which read files: the input is written to
// temp files. First byte: which importer; for ROS the input is the left file, "\n---8<---\n", the
// right file.
#include "fuzz/fuzz_common.hpp"
#include "render/calib_import.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  augrig::fuzz::Input input(data, size);
  const std::uint8_t which = input.byte();
  switch (which % 4) {
    case 0: {
      const std::string path = augrig::fuzz::write_temp("opencv.yml", input.rest());
      (void)augrig::import_opencv_stereo(path, which & 0x80 ? 1280 : 0, which & 0x80 ? 960 : 0);
      break;
    }
    case 1: {
      const std::string left = augrig::fuzz::write_temp("ros_left.yaml", input.until("\n---8<---\n"));
      const std::string right = augrig::fuzz::write_temp("ros_right.yaml", input.rest());
      (void)augrig::import_ros_camera_info(left, right);
      break;
    }
    case 2: {
      const std::string path = augrig::fuzz::write_temp("camchain.yaml", input.rest());
      (void)augrig::import_kalibr_camchain(path);
      break;
    }
    default: {
      const std::string path = augrig::fuzz::write_temp("calib.yaml", input.rest());
      (void)augrig::import_calibration("auto", path);
      break;
    }
  }
  return 0;
}
