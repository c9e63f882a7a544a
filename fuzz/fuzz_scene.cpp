// parse_scene (app/scene_file.hpp): scene YAML against the paper's default rig.
#include <string>

#include "pipeline/scene_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const augrig::Rig rig = augrig::Rig::paper_default();
  const std::string text(reinterpret_cast<const char*>(data), size);
  augrig::SceneExtras extras;
  (void)augrig::parse_scene(text, "fuzz.yaml", rig, augrig::BoomDimensions{}, Eigen::Vector3d(6.0, 0.0, -1.2),
                            &extras);
  return 0;
}
