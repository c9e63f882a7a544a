// load_model (render/mesh.hpp), which reads files by extension: the input is written to a temp
// .obj, .gltf or .glb (first byte) and loaded with the first byte's axes and scale.
#include "fuzz/fuzz_common.hpp"
#include "render/mesh.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  augrig::fuzz::Input input(data, size);
  const std::uint8_t which = input.byte();
  static const char* const kNames[] = {"model.obj", "model.gltf", "model.glb"};
  augrig::ModelSource source;
  source.path = augrig::fuzz::write_temp(kNames[which % 3], input.rest());
  if (which & 0x80) source.scale = 0.001;
  (void)augrig::load_model(source);
  return 0;
}
