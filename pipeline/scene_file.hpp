// Scene files: where the boom and the receiver are for one stereo frame of `augrig augment`
// (YAML, format in docs/CLI.md). Loading never prints: it returns the SceneState or an Error naming
// the file, line, column and key, and what was expected, in the style of the rig loader.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "render/augmenter.hpp"
#include "render/boom_control.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"

namespace augrig {

// What a scene file says beyond the SceneState.
struct SceneExtras {
  std::optional<TimestampNs> t_ns;  // the frame's timestamp, when the file gives one
};

// Reads a scene file. The boom articulation is checked against rig.boom.limits; a camera-relative
// receiver pose is turned into T_body_receiver with the rig's cameras; `at_contact` places the
// receiver's `receptacle_m` (receiver body frame) at the nozzle tip of a boom of size `boom`.
Expected<SceneState> load_scene(const std::string& path, const Rig& rig, const BoomDimensions& boom,
                                const Eigen::Vector3d& receptacle_m, SceneExtras* extras = nullptr);
// Parses scene YAML text; `name` is used in error messages (a path, or "<string>").
Expected<SceneState> parse_scene(const std::string& yaml_text, const std::string& name, const Rig& rig,
                                 const BoomDimensions& boom, const Eigen::Vector3d& receptacle_m,
                                 SceneExtras* extras = nullptr);

}  // namespace augrig
