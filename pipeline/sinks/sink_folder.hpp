// SinkFolder: the output folder of a sink that writes a dataset of files (the stereo benchmark
// layouts, the pose labels): the folder made, an INCOMPLETE marker there until the sink finishes
// cleanly (a failed or killed run leaves it, so no one takes half a dataset for a whole one), and
// files written under it by relative path, their folders made on the way. Every error names the
// sink and the file: "kitti sink: OUT/training/image_2/000001_10.png: cannot write the file".
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/expected.hpp"

namespace augrig::pipeline {

class SinkFolder {
 public:
  // `who`: the sink's name in errors ("kitti sink").
  SinkFolder(std::string who, std::string dir) : who_(std::move(who)), dir_(std::move(dir)) {}

  // Makes the folder (and `subfolders` in it) and writes the INCOMPLETE marker saying `until`
  // ("removed when the export has finished").
  Status create(const std::vector<std::string>& subfolders, const std::string& until) const;
  // Removes the marker: the dataset is whole.
  void complete() const;

  Status write_text(const std::string& rel, const std::string& text) const;
  // Through cv::imwrite (the format by the name's extension; `params` as imwrite's).
  Status write_image(const std::string& rel, const cv::Mat& image, const std::vector<int>& params = {}) const;
  // `to` the same file as `from` (both under the folder): a hard link, a copy where links are refused.
  Status link(const std::string& from, const std::string& to) const;
  // Makes the folder that `rel` goes into.
  Status ensure_parent(const std::string& rel) const;

  const std::string& dir() const { return dir_; }
  std::string path(const std::string& rel) const;

 private:
  std::string who_, dir_;
};

}  // namespace augrig::pipeline
