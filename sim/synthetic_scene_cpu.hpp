// The CPU back end of SyntheticSceneRenderer (SceneBackend::kCpu, sim/synthetic_scene.hpp): sky and
// ground shaded per raw pixel from rays precomputed through the lens model, the receiver rasterised
// by render/soft_raster, Bayer pixels computed in their own channel only, counter-based noise.
// Internal to sim/: use SyntheticSceneRenderer::create().
#pragma once

#include <memory>

#include "sim/synthetic_scene.hpp"

namespace augrig {

Expected<std::unique_ptr<SyntheticSceneRenderer>> make_cpu_scene_renderer(const Rig& rig,
                                                                          std::shared_ptr<const Model> receiver,
                                                                          const SceneRendererOptions& options);

// For tests: whether the ground blocks may take the AVX2 path where the CPU has it (the default)
// or must take the SSE2 one; both give the same bytes. Returns whether AVX2 is now used.
bool set_cpu_scene_avx2_for_testing(bool allowed);

// The receiver both scene renderers draw: the one given, else the rig's model file, else the
// built-in one (then `builtin` is set: its meshes are consistently wound, so they can be culled).
Expected<Model> load_scene_receiver(const Rig& rig, std::shared_ptr<const Model> given, bool& builtin);

}  // namespace augrig
