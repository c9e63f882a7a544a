// What the pipeline's file sinks write, shared with the batch commands: the per-frame images
// (augmented, masks, visualisations: docs/CLI.md gives the layout), stats.csv, and the recorder's
// FrameRecord made from an augmented frame. Also the models a rig asks for, loaded once.
#pragma once

#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>

#include <Eigen/Core>

#include "core/expected.hpp"
#include "core/frame.hpp"
#include "recorder/record.hpp"
#include "render/augmenter.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

namespace augrig::pipeline {

// The rig's models, loaded once before anything is opened, so that a model file that cannot be
// read fails the command before a camera, a recording or a window is touched (and the augmenter
// does not load it again). The built-in receiver knows its own receptacle; a model file relies on
// the rig's receiver.receptacle_m.
struct RigModels {
  std::shared_ptr<const Model> receiver_model;  // null: let the Augmenter load the rig's file
  std::shared_ptr<const BoomModel> boom_model;  // null: the Augmenter's built-in boom
  Eigen::Vector3d receptacle_m = Eigen::Vector3d::Zero();
};
Expected<RigModels> load_rig_models(const Rig& rig);
// Only where the receptacle is (no model file read).
Eigen::Vector3d receptacle_of(const Rig& rig);

// Per-frame file names: left/right keep their own stems, the visualisations use the left one.
struct FrameNames {
  std::string left, right;
};
// Per-frame image files: every `every`-th augmented pair, named by `names` when given (e.g. after
// the input files), else by pair sequence (for a replayed recording: recorded index and pass).
struct FrameFiles {
  std::filesystem::path dir;
  int every = 1;
  std::function<FrameNames(const StereoFrame&)> names;
  bool ground_truth = false;  // also the depth, correspondence and class files (write_ground_truth)
};

// Everything written for one stereo frame; `raw` is the frame `r` was made from (its augmented
// images may be the changed boxes only). Creates the folders.
Status write_frame_images(const std::filesystem::path& out, const FrameNames& n, const StereoFrame& raw,
                          const StereoResult& r);

// The frame's ground truth for stereo research (docs/GROUND_TRUTH.md), beside the images:
//   {left,right}/depth/NAME.npy     float32 H x W: receiver depth, metres along z, NaN where none
//   {left,right}/depth_mm/NAME.png  16-bit: the same in whole mm, 0 where none, 65535 = 65.535 m+
//   left/right_px/NAME.npy          float32 H x W x 2: (u, v) in the right image of the receiver
//                                   point on each left pixel, NaN where none
//   left/stereo_class/NAME.png      8-bit StereoClass per left pixel (when the classes were made)
// `rig` is the one `r` was augmented with. Creates the folders.
Status write_ground_truth(const std::filesystem::path& out, const FrameNames& n, const StereoResult& r,
                          const Rig& rig);

// A frame for the recorder from what the augmenter made: the augmented images as made (whole, or
// only their changed boxes: AugmentedOutput), the masks and the statistics, and with `ground_truth`
// each camera's receiver depth (its box only: recorder::DepthRecord). The caller adds the raw
// frame, the poses and the boom.
recorder::FrameRecord frame_record(const StereoResult& r, bool ground_truth = false);

// stats.csv, one row per stereo frame, flushed per row so a failed run keeps what it counted.
class StatsCsvWriter {
 public:
  static Expected<std::unique_ptr<StatsCsvWriter>> create(const std::filesystem::path& path);
  Status add(const OcclusionStats& s);
  const std::filesystem::path& path() const { return path_; }

 private:
  StatsCsvWriter() = default;
  std::filesystem::path path_;
  std::ofstream out_;
};

}  // namespace augrig::pipeline
