// StereoEvaluator: one stereo pair evaluated end to end (issue 18 §3), as `augrig evaluate` does
// for every pair of a run. From the raw pair and what the augmenter made of it (augmented images,
// masks, receiver depth, stereo classes):
//
//   1. the true disparity at each rectified left pixel (true_disparity()) and from it the receiver's
//      box in the rectified left image: only that box, widened by the matcher's search range, its
//      block and some context, is rectified and matched (the receiver rarely fills the frame);
//   2. the raw and the augmented pair made gray (Bayer demosaiced) and rectified over that box;
//   3. both pairs matched (StereoSGBM or StereoBM), on two threads at once;
//   4. both disparities scored per stereo class, with the boom's pixels kept and left out.
//
// Matching a crop instead of the whole frame changes only where SGBM's paths start (at the crop's
// edge, `context_px` beyond the block and search range, instead of the frame's edge);
// EvaluatorOptions::full_frame matches whole frames.
#pragma once

#include <cstdint>
#include <memory>

#include <opencv2/core.hpp>

#include "core/expected.hpp"
#include "core/frame.hpp"
#include "render/cv_image.hpp"  // gray_of
#include "eval/matcher.hpp"
#include "eval/stereo_eval.hpp"
#include "render/augmenter.hpp"
#include "render/rig.hpp"

namespace augrig::eval {

struct EvaluatorOptions {
  MatcherParams matcher;
  // Image matched around the receiver beyond the block and search range: SGBM's paths start this
  // far out (128 px: the same scores as whole frames on the simulated flights, tests/eval).
  int context_px = 128;
  bool full_frame = false;  // match whole rectified frames (slower; no crop)
  // Match the raw and the augmented pair on two threads when the matcher itself runs on one
  // (SGBM modes sgbm and hh); 3-way SGBM and BM are already parallel inside OpenCV, and two of
  // them at once are slower on 2 cores (bench_evaluate).
  bool parallel = true;
};

// One pair's evaluation.
struct FrameEvaluation {
  PairScore raw, augmented;      // the raw pair's disparity and the augmented pair's, scored
  cv::Rect matched;              // the rectified region matched (empty: no receiver in the left view)
  std::int64_t receiver_px = 0;  // rectified left pixels with a true disparity
  // Of them, with a true disparity outside the matcher's search range [min, min + num): the
  // matcher cannot find those (num_disparities too small for the rig and range).
  std::int64_t out_of_range_px = 0;
  // Wall time of each step (ms): gray + rectification, matching (both pairs), truth + scoring.
  double prepare_ms = 0, match_ms = 0, score_ms = 0;
};

// Images of the last evaluated pair, for files a user looks at (rectified left frame, full size).
struct EvaluationImages {
  cv::Mat true_disparity;                // CV_32FC1, NaN off the receiver
  cv::Mat raw_disparity, aug_disparity;  // CV_32FC1, NaN where none (or not matched)
};

class StereoEvaluator {
 public:
  // Rectifies the rig's two cameras (rectify_rig()); errors name the rig.
  static Expected<std::unique_ptr<StereoEvaluator>> create(const Rig& rig, const EvaluatorOptions& options);

  // Evaluates one pair: `raw` as read, `result` the augmenter's output for it (whole or changed-box
  // augmented images, masks, receiver depth; stereo classes needed). `images` (optional) receives the
  // disparities. Errors: sizes that are not the rig's, no stereo classes, a matcher failure.
  Expected<FrameEvaluation> evaluate(const StereoFrame& raw, const StereoResult& result,
                                     EvaluationImages* images = nullptr);

  const Rectification& rectification() const { return rect_; }
  const EvaluatorOptions& options() const { return options_; }

 private:
  StereoEvaluator() = default;
  Rectification rect_;
  CameraModel left_model_;
  EvaluatorOptions options_;
};

}  // namespace augrig::eval
