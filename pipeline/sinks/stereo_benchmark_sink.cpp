// The stereo benchmarks' layouts as sinks (`--sink kitti:DIR`, `--sink middlebury:DIR`; `augrig
// export IN OUT --format kitti|middlebury`): each augmented pair rectified (eval::rectify_rig, the
// rig's calibration) and written twice, raw and augmented, with the receiver's true disparity
// (from the augmenter's receiver depth, eval::true_disparity), the calibration as the benchmark
// defines it (eval/benchmark_layout.hpp) and, in the augmented tree, the boom masks and stereo
// classes carried into the rectified images, so that a matcher's error is split by boom and stereo
// class with the benchmark's own tools (docs/BENCHMARKS.md):
//   kitti:       DIR/{raw,augmented}/training/image_2, image_3, disp_occ_0, disp_noc_0 (NNNNNN_10.png),
//                calib_cam_to_cam/NNNNNN.txt; augmented/training/boom_mask_0, boom_mask_1,
//                stereo_class_0; DIR/calib_cam_to_cam.txt;
//   middlebury:  DIR/{raw,augmented}/NNNNNN/im0.png, im1.png, calib.txt, disp0GT.pfm, mask0nocc.png;
//                augmented/NNNNNN/boom_mask0.png, boom_mask1.png, stereo_class0.png.
// Both: DIR/frames.csv (the file index, the pair's key time, its index in its source). The truth
// is the receiver's (unknown elsewhere); "non-occluded" (disp_noc_0, mask0nocc 255) are the
// receiver pixels both cameras see in the augmented pair (stereo class "both"), the same pixels in
// both trees. Files the two trees share are hard links. Pairs without an augmentation (no pose)
// are left out and counted. DIR/INCOMPLETE stays until the run closes the sink cleanly.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "eval/benchmark_layout.hpp"
#include "eval/stereo_eval.hpp"
#include "pipeline/report.hpp"
#include "pipeline/sinks/registry.hpp"
#include "pipeline/sinks/sink_folder.hpp"

namespace augrig::pipeline {

namespace {

namespace fs = std::filesystem;

enum class Layout { kKitti, kMiddlebury };

const char* name_of(Layout l) {
  return l == Layout::kKitti ? "kitti" : "middlebury";
}

// One pair's images in the rectified left (or right) frame.
struct RectifiedPair {
  cv::Mat raw[2], augmented[2];
  cv::Mat truth;  // CV_32FC1, NaN off the receiver
  cv::Mat mask[2], classes;
  double vmin = std::numeric_limits<double>::infinity(), vmax = -std::numeric_limits<double>::infinity();
  std::int64_t receiver_px = 0, noc_px = 0;
};

class StereoBenchmarkSink final : public FrameSink {
 public:
  StereoBenchmarkSink(Layout layout, std::string dir, const Rig& rig)
      : layout_(layout),
        dir_(std::move(dir)),
        out_(std::string(name_of(layout)) + " sink", dir_),
        rig_(rig) {}

  Status open() {
    const std::string where = std::string(name_of(layout_)) + " sink: " + dir_;
    if (rig_.cameras.size() != 2) return make_error(where, ": the rig needs 2 cameras");
    auto r = eval::rectify_rig(rig_.left().model, rig_.right().model, rig_.T_right_left());
    if (!r) return make_error(where, ": ", rig_.source, ": ", r.error().message);
    rect_ = std::move(*r);
    std::error_code ec;
    if (fs::exists(fs::path(dir_) / "frames.csv", ec))
      return make_error(where, ": holds a benchmark export already (frames.csv); expected a new folder");
    if (Status s = out_.create({}, "removed when the export has finished"); !s) return s;
    if (layout_ == Layout::kKitti) {
      calib_ = "calib_cam_to_cam.txt";
      if (Status s =
              out_.write_text(calib_, eval::kitti_calib_cam_to_cam(rect_, rig_.left().model,
                                                                   rig_.right().model, rig_.T_right_left()));
          !s)
        return s;
    }
    frames_csv_.open(fs::path(dir_) / "frames.csv", std::ios::binary);
    frames_csv_ << "# index: the files' number; t_ns: the pair's key time; source_index: its index in its "
                   "source\nindex,t_ns,source_index,receiver_px,noc_px\n";
    if (!frames_csv_) return make_error(where, "/frames.csv: cannot write the file");
    return {};
  }

  SinkNeeds needs() const override { return {.whole_images = true}; }

  Status consume(PairContext& pair) override {
    Status s = write_pair(pair);
    failed_ = failed_ || !s;
    return s;
  }

  // One pair rectified and written in the layout.
  Status write_pair(PairContext& pair) {
    if (!pair.result) {
      ++left_out_;
      return {};
    }
    pair.make_whole();
    auto p = rectify(pair.raw, *pair.result);
    if (!p) return make_error(name_of(layout_), " sink: ", dir_, ": ", p.error().message);
    char id[32];
    std::snprintf(id, sizeof id, "%06zu", written_);
    Status s = layout_ == Layout::kKitti ? write_kitti(id, *p) : write_middlebury(id, *p);
    if (!s) return s;
    frames_csv_ << written_ << "," << pair.raw.t_key_ns << ","
                << (pair.position ? std::to_string(pair.position->index) : std::to_string(pair.pair - 1))
                << "," << p->receiver_px << "," << p->noc_px << "\n";
    frames_csv_.flush();
    if (!frames_csv_) return make_error(name_of(layout_), " sink: ", dir_, "/frames.csv: write failed");
    ++written_;
    return {};
  }

  Status close(PipelineReport& report) override {
    if (!frames_csv_.is_open() || failed_) return {};  // a failed run's folder stays INCOMPLETE
    frames_csv_.close();
    if (!frames_csv_) return make_error(name_of(layout_), " sink: ", dir_, "/frames.csv: write failed");
    out_.complete();
    std::ostringstream line;
    line << dir_ << ": " << written_ << " stereo pair(s) in the "
         << (layout_ == Layout::kKitti ? "KITTI" : "Middlebury") << " layout (raw and augmented, rectified "
         << rect_.width << "x" << rect_.height << ", f " << rect_.f_px << " px, baseline " << rect_.baseline_m
         << " m)";
    if (left_out_) line << "; " << left_out_ << " pair(s) without an augmentation left out";
    report.outputs.push_back(line.str());
    return {};
  }

 private:
  // The pair rectified: images, the truth over the receiver's box, masks and classes (nearest).
  Expected<RectifiedPair> rectify(const StereoFrame& raw, const StereoResult& result) const {
    const int w = rect_.width, h = rect_.height;
    for (const Image* im : {&raw.left.image, &raw.right.image, &result.left.augmented,
                            &result.right.augmented, &result.left.mask, &result.right.mask})
      if (im->width() != w || im->height() != h)
        return make_error("an image is ", im->width(), "x", im->height(), ", the rig's cameras ", w, "x", h);
    if (result.left.receiver_depth.width != w || result.left.receiver_depth.height != h)
      return make_error("the augmentation has no left receiver depth (the receiver is not drawn)");
    RectifiedPair p;
    eval::rectify_images(rect_, bgr_of(raw.left.image.view()), bgr_of(raw.right.image.view()),
                         p.raw[0], p.raw[1]);
    eval::rectify_images(rect_, bgr_of(result.left.augmented.view()),
                         bgr_of(result.right.augmented.view()), p.augmented[0], p.augmented[1]);
    const cv::Rect near = eval::rectified_box(rect_, rig_.left().model, result.left.receiver_box);
    p.truth = near.empty() ? cv::Mat(h, w, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()))
                           : eval::true_disparity(rect_, result.left.receiver_depth, near);
    for (int c = 0; c < 2; ++c) {
      cv::remap(cv_view((c ? result.right.mask : result.left.mask).view()), p.mask[c], rect_.map_x[c], rect_.map_y[c], cv::INTER_NEAREST, cv::BORDER_CONSTANT,
                cv::Scalar(0));
    }
    cv::Mat classes(h, w, CV_8UC1, cv::Scalar(0));
    if (result.stereo_classes.size() == static_cast<std::size_t>(w) * h)
      classes = cv::Mat(h, w, CV_8UC1, const_cast<std::uint8_t*>(result.stereo_classes.data()));
    p.classes = eval::rectify_labels(rect_, classes);
    for (int y = 0; y < h; ++y) {
      const float* t = p.truth.ptr<float>(y);
      const std::uint8_t* k = p.classes.ptr<std::uint8_t>(y);
      for (int x = 0; x < w; ++x)
        if (std::isfinite(t[x])) {
          ++p.receiver_px;
          p.noc_px += k[x] == static_cast<std::uint8_t>(StereoClass::kBoth);
          p.vmin = std::min<double>(p.vmin, t[x]);
          p.vmax = std::max<double>(p.vmax, t[x]);
        }
    }
    return p;
  }

  // The truth where the receiver is seen by both cameras in the augmented pair; NaN elsewhere.
  static cv::Mat non_occluded(const RectifiedPair& p) {
    cv::Mat noc = p.truth.clone();
    noc.setTo(std::numeric_limits<float>::quiet_NaN(), p.classes != static_cast<int>(StereoClass::kBoth));
    return noc;  // (NaN where the truth is NaN already: kitti_disparity() writes 0 there)
  }

  Status write_kitti(const std::string& id, const RectifiedPair& p) {
    const std::string png = id + "_10.png";
    for (const char* tree : {"augmented", "raw"}) {
      const bool aug = tree[0] == 'a';
      const std::string t = std::string(tree) + "/training/";
      for (int c = 0; c < 2; ++c)
        if (Status s =
                out_.write_image(t + (c ? "image_3/" : "image_2/") + png, aug ? p.augmented[c] : p.raw[c]);
            !s)
          return s;
      if (aug) {
        if (Status s = out_.write_image(t + "disp_occ_0/" + png, eval::kitti_disparity(p.truth)); !s)
          return s;
        if (Status s = out_.write_image(t + "disp_noc_0/" + png, eval::kitti_disparity(non_occluded(p))); !s)
          return s;
        for (int c = 0; c < 2; ++c)
          if (Status s = out_.write_image(t + "boom_mask_" + std::to_string(c) + "/" + png, p.mask[c]); !s)
            return s;
        if (Status s = out_.write_image(t + "stereo_class_0/" + png, p.classes); !s) return s;
        if (Status s = out_.link(calib_, t + "calib_cam_to_cam/" + id + ".txt"); !s) return s;
      } else {
        for (const char* d : {"disp_occ_0/", "disp_noc_0/"})
          if (Status s = out_.link("augmented/training/" + std::string(d) + png, t + d + png); !s) return s;
        if (Status s = out_.link(calib_, t + "calib_cam_to_cam/" + id + ".txt"); !s) return s;
      }
    }
    return {};
  }

  Status write_middlebury(const std::string& id, const RectifiedPair& p) {
    const std::string a = "augmented/" + id + "/", r = "raw/" + id + "/";
    for (int c = 0; c < 2; ++c) {
      const std::string im = c ? "im1.png" : "im0.png";
      if (Status s = out_.write_image(a + im, p.augmented[c]); !s) return s;
      if (Status s = out_.write_image(r + im, p.raw[c]); !s) return s;
      if (Status s = out_.write_image(a + "boom_mask" + std::to_string(c) + ".png", p.mask[c]); !s) return s;
    }
    if (Status s = out_.write_image(a + "stereo_class0.png", p.classes); !s) return s;
    if (Status s = out_.write_text(a + "calib.txt", eval::middlebury_calib(rect_, p.vmin, p.vmax)); !s)
      return s;
    // Unknown is inf in Middlebury's files; MiddEval3's mask: 255 non-occluded, 128 occluded, 0 no
    // truth. (Loops: OpenCV's comparisons do not see NaN as IEEE does.)
    cv::Mat gt = p.truth.clone();
    cv::Mat nocc(p.truth.size(), CV_8UC1, cv::Scalar(0));
    for (int y = 0; y < gt.rows; ++y) {
      float* g = gt.ptr<float>(y);
      const std::uint8_t* k = p.classes.ptr<std::uint8_t>(y);
      std::uint8_t* n = nocc.ptr<std::uint8_t>(y);
      for (int x = 0; x < gt.cols; ++x) {
        if (!std::isfinite(g[x])) {
          g[x] = std::numeric_limits<float>::infinity();
          continue;
        }
        n[x] = k[x] == static_cast<std::uint8_t>(StereoClass::kBoth) ? 255 : 128;
      }
    }
    if (Status s = out_.ensure_parent(a + "disp0GT.pfm"); !s) return s;
    if (Status s = eval::write_pfm((fs::path(dir_) / a / "disp0GT.pfm").string(), gt); !s)
      return make_error("middlebury sink: ", s.error().message);
    if (Status s = out_.write_image(a + "mask0nocc.png", nocc); !s) return s;
    for (const char* f : {"calib.txt", "disp0GT.pfm", "mask0nocc.png"})
      if (Status s = out_.link(a + f, r + f); !s) return s;
    return {};
  }

  Layout layout_;
  std::string dir_;
  SinkFolder out_;  // dir_: made, marked INCOMPLETE until the close, the files written
  const Rig rig_;  // a copy: the setup's rig moves into the pipeline
  eval::Rectification rect_;
  std::string calib_;  // KITTI: the calibration every frame's file links to (relative to DIR)
  std::ofstream frames_csv_;
  std::size_t written_ = 0, left_out_ = 0;
  bool failed_ = false;  // a pair could not be written: the run stops, DIR stays INCOMPLETE
};

Expected<std::unique_ptr<FrameSink>> make(Layout layout, const std::string& arg, const SinkSetup& setup) {
  if (arg.find(',') != std::string::npos)
    return make_error("--sink ", name_of(layout), ":", arg, ": expected ", name_of(layout),
                      ":DIR (no options)");
  auto sink = std::make_unique<StereoBenchmarkSink>(layout, arg, setup.rig);
  if (Status s = sink->open(); !s) return s.error();
  return std::unique_ptr<FrameSink>(std::move(sink));
}

}  // namespace

Expected<std::unique_ptr<FrameSink>> make_kitti_sink(const std::string& arg, const SinkSetup& setup) {
  return make(Layout::kKitti, arg, setup);
}

Expected<std::unique_ptr<FrameSink>> make_middlebury_sink(const std::string& arg, const SinkSetup& setup) {
  return make(Layout::kMiddlebury, arg, setup);
}

}  // namespace augrig::pipeline
