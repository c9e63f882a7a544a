#include "pipeline/scene_folder_poses.hpp"

#include <algorithm>
#include <filesystem>

namespace augrig::pipeline {

namespace fs = std::filesystem;

Expected<std::unique_ptr<SceneFolderPoses>> SceneFolderPoses::load(const std::string& dir, const Rig& rig,
                                                                   const Eigen::Vector3d& receptacle_m) {
  std::unique_ptr<SceneFolderPoses> p(new SceneFolderPoses());
  p->dir_ = dir;
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (entry.is_regular_file() && (entry.path().extension() == ".yaml" || entry.path().extension() == ".yml"))
      files.push_back(entry.path());
  if (ec) return make_error("pipeline::SceneFolderPoses::load(): ", dir, ": cannot list the folder (", ec.message(), ")");
  if (files.empty()) return make_error("pipeline::SceneFolderPoses::load(): ", dir, ": no scene files (.yaml, .yml)");
  std::sort(files.begin(), files.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename().string() < b.filename().string(); });
  for (const fs::path& f : files) {
    SceneExtras extras;
    auto scene = load_scene(f.string(), rig, BoomDimensions{}, receptacle_m, &extras);
    if (!scene) return scene.error();
    p->files_.push_back(f.string());
    p->scenes_.push_back(*scene);
    p->extras_.push_back(extras);
  }
  return p;
}

std::string SceneFolderPoses::describe() const {
  return "the scene files of " + dir_ + " (" + std::to_string(scenes_.size()) + ", one per pair)";
}

FramePoses SceneFolderPoses::at(const StereoFrame& frame, TimestampNs) {
  FramePoses p;
  const std::uint64_t k = frame.pair_sequence;
  if (k >= scenes_.size()) {
    p.problems.push_back(dir_ + ": no scene file for pair " + std::to_string(k) + " (the folder has " +
                         std::to_string(scenes_.size()) + ")");
    p.hud.status = "no pose: " + p.problems.back();
    return p;
  }
  p.scene = scenes_[k];
  p.boom_given = true;
  p.hud.status = "scene " + files_[k];
  return p;
}

}  // namespace augrig::pipeline
