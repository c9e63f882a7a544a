// LookUpdates: the camera look's updates as recording rows (recorder::LookRecord, the `look` table,
// docs/RECORDING.md): each camera's noise level function when the augmenter is given a new one (an
// estimate from the frames, or the rig's at the first pair), and the light measured on the
// receiver each time LookStage makes a new fit. Per pair it only compares what it last gave; rows
// come only with a change, so a run's recording holds every update and nothing per frame.
#pragma once

#include <optional>
#include <vector>

#include "core/frame.hpp"
#include "pipeline/look_stage.hpp"
#include "recorder/record.hpp"
#include "render/augmenter.hpp"
#include "render/light_probe.hpp"

namespace augrig::pipeline {

class LookUpdates {
 public:
  // After `frame` was augmented and look.after_augment() ran: the updates this pair brought, stamped
  // with its t_key_ns and its left camera's clock. `light` is the scene's light the pair was
  // augmented under (its sun's source, direction and whether it is up go with a light fit). None
  // with the plain look.
  std::vector<recorder::LookRecord> take(const LookStage& look, const Augmenter& augmenter,
                                         const StereoFrame& frame, const SceneLight& light);

 private:
  std::vector<NoiseLevelFunction> noise_;  // per camera, the last one given
  std::optional<LightFit> light_;          // the last one given
};

}  // namespace augrig::pipeline
