#include "pipeline/sinks/registry.hpp"

namespace augrig::pipeline {

namespace {

using Factory = Expected<std::unique_ptr<FrameSink>> (*)(const std::string&, const SinkSetup&);
struct SinkEntry {
  const char* scheme;
  const char* usage;
  Factory make;
};

// One line per sink.
constexpr SinkEntry kSinks[] = {
    {"video",
     "video:FILE.mp4[,masks][,crf=N]  the augmented views side by side in H.264 (masks: their colours)",
     make_video_sink},
    {"tum", "tum:FILE.txt  the receiver's pose in the left camera per pair (TUM trajectory format)",
     make_tum_sink},
    {"mcap",
     "mcap:FILE.mcap[,no-augmented][,no-masks][,jpeg[=Q]|,h264[=CRF][,gop=N]]  each pair as ROS 2 messages, as "
     "export --format mcap writes them (jpeg: the images as JPEG, quality Q, default 90; h264: as H.264, x264's "
     "CRF default 23, a keyframe every N frames, default 30)",
     make_mcap_sink},
    {"euroc",
     "euroc:DIR[,no-augmented][,no-masks][,no-plot][,ground-truth][,nav]  each pair in the EuRoC/ASL layout, "
     "as "
     "export writes a recording (nav: a replay's on the recording's clock, with its nav inputs)",
     make_euroc_sink},
    {"kitti",
     "kitti:DIR  each pair rectified, raw and augmented, in KITTI stereo 2015's layout with the receiver's "
     "true disparity, calib_cam_to_cam.txt and the boom masks (docs/BENCHMARKS.md)",
     make_kitti_sink},
    {"middlebury",
     "middlebury:DIR  each pair rectified, raw and augmented, in Middlebury's (MiddEval3) layout: im0, im1, "
     "disp0GT.pfm, mask0nocc, calib.txt and the boom masks (docs/BENCHMARKS.md)",
     make_middlebury_sink},
    {"coco",
     "coco:DIR[,jpeg]  each camera's augmented image with the receiver's keypoints (visible, hidden by the "
     "boom or by the receiver), boxes and RLE masks of receiver and boom: COCO's keypoint format "
     "(docs/LABELS.md)",
     make_coco_sink},
    {"yolo",
     "yolo:DIR[,jpeg]  the same labels in Ultralytics' YOLO pose format: images/, labels/, dataset.yaml "
     "(docs/LABELS.md)",
     make_yolo_sink},
};

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_sink(const std::string& spec, const SinkSetup& setup) {
  const std::size_t colon = spec.find(':');
  const std::string scheme = spec.substr(0, colon);
  for (const SinkEntry& e : kSinks)
    if (scheme == e.scheme) {
      if (colon == std::string::npos || colon + 1 == spec.size())
        return make_error("--sink ", spec, ": expected ", e.usage);
      return e.make(spec.substr(colon + 1), setup);
    }
  std::string known;
  for (const SinkEntry& e : kSinks) known += std::string(known.empty() ? "" : ", ") + e.scheme + ":";
  return make_error("--sink ", spec, ": unknown sink (known: ", known, ")");
}

std::vector<std::string> sink_usages() {
  std::vector<std::string> v;
  for (const SinkEntry& e : kSinks) v.emplace_back(e.usage);
  return v;
}

}  // namespace augrig::pipeline
