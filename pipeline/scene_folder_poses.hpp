// SceneFolderPoses: a pose provider with one scene file per stereo pair (`augrig augment --scene DIR`):
// the folder's scene files (.yaml, .yml) sorted by name, the k-th for the k-th pair the source
// delivers (StereoFrame::pair_sequence, 0 first). A pair beyond the last file has no pose, and says
// so. Every file is read and checked when the provider is made, so a bad one fails before any frame.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "pipeline/poses.hpp"
#include "pipeline/scene_file.hpp"
#include "render/rig.hpp"

namespace augrig::pipeline {

class SceneFolderPoses final : public PoseProvider {
 public:
  // Errors: the folder cannot be listed, holds no scene file, or a file's own error (file:line:column).
  static Expected<std::unique_ptr<SceneFolderPoses>> load(const std::string& dir, const Rig& rig,
                                                          const Eigen::Vector3d& receptacle_m);
  std::string describe() const override;
  FramePoses at(const StereoFrame& frame, TimestampNs mid_host_left_ns) override;

  std::size_t size() const { return scenes_.size(); }
  const std::string& file(std::size_t k) const { return files_[k]; }
  const SceneExtras& extras(std::size_t k) const { return extras_[k]; }

 private:
  SceneFolderPoses() = default;
  std::string dir_;
  std::vector<std::string> files_;
  std::vector<SceneState> scenes_;
  std::vector<SceneExtras> extras_;
};

}  // namespace augrig::pipeline
