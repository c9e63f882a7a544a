// parse_rig (render/rig.hpp): rig YAML; a rig that loads is also written back and reparsed.
#include <string>

#include "render/rig.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto rig = augrig::parse_rig(text, "fuzz.yaml");
  if (rig) (void)augrig::parse_rig(augrig::rig_to_yaml(*rig), "fuzz-written.yaml");
  return 0;
}
