#include "eval/evaluator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <limits>

#include <opencv2/imgproc.hpp>

namespace augrig::eval {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// A label image (CV_8UC1) carried into the rectified region `roi` by the nearest raw pixel.
cv::Mat rectify_labels_in(const Rectification& r, const cv::Mat& labels, const cv::Rect& roi) {
  cv::Mat out;
  cv::remap(labels, out, r.map_x[0](roi), r.map_y[0](roi), cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(0));
  return out;
}

}  // namespace

Expected<std::unique_ptr<StereoEvaluator>> StereoEvaluator::create(const Rig& rig,
                                                                   const EvaluatorOptions& options) {
  if (rig.cameras.size() != 2)
    return make_error("eval::StereoEvaluator::create(): ", rig.source, ": the rig needs 2 cameras, has ",
                      rig.cameras.size());
  auto rect = rectify_rig(rig.left().model, rig.right().model, rig.T_right_left());
  if (!rect) return make_error(rig.source, ": ", rect.error().message);
  std::unique_ptr<StereoEvaluator> e(new StereoEvaluator());
  e->rect_ = std::move(*rect);
  e->left_model_ = rig.left().model;
  e->options_ = options;
  return e;
}

Expected<FrameEvaluation> StereoEvaluator::evaluate(const StereoFrame& raw, const StereoResult& result,
                                                    EvaluationImages* images) {
  const char* where = "eval::StereoEvaluator::evaluate(): ";
  const int w = rect_.width, h = rect_.height;
  for (const Frame* f : {&raw.left, &raw.right})
    if (f->image.width() != w || f->image.height() != h)
      return make_error(where, to_string(f->camera), " image is ", f->image.width(), "x", f->image.height(),
                        ", the rig's cameras ", w, "x", h);
  if (result.left.receiver_depth.width != w || result.left.receiver_depth.height != h ||
      result.left.mask.width() != w || result.left.mask.height() != h)
    return make_error(where, "the augmentation has no left receiver depth or mask of the image's size");

  FrameEvaluation fe;
  // 1. The truth, and the region worth matching: the receiver's rectified box, widened by the
  //    search range (to its left: where its right-image matches lie), the block and the context.
  auto t0 = Clock::now();
  // Only where the receiver may be: the left view's receiver box carried into the rectified image.
  const cv::Rect near = rectified_box(rect_, left_model_, result.left.receiver_box);
  const cv::Mat truth = near.empty()
                            ? cv::Mat(h, w, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()))
                            : true_disparity(rect_, result.left.receiver_depth, near);
  const MatcherParams& mp = options_.matcher;
  const float d_lo = static_cast<float>(mp.min_disparity),
              d_hi = static_cast<float>(mp.min_disparity + mp.num_disparities - 1);
  int bx0 = w, by0 = h, bx1 = 0, by1 = 0;
  for (int y = near.y; y < near.y + near.height; ++y) {
    const float* t = truth.ptr<float>(y);
    for (int x = near.x; x < near.x + near.width; ++x)
      if (std::isfinite(t[x])) {
        bx0 = std::min(bx0, x), bx1 = std::max(bx1, x + 1);
        by0 = std::min(by0, y), by1 = std::max(by1, y + 1);
        ++fe.receiver_px;
        fe.out_of_range_px += t[x] < d_lo || t[x] > d_hi;
      }
  }
  double truth_ms = ms_since(t0);
  if (fe.receiver_px == 0) {
    fe.score_ms = truth_ms;
    if (images) {
      images->true_disparity = truth;
      images->raw_disparity = cv::Mat(h, w, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
      images->aug_disparity = images->raw_disparity.clone();
    }
    return fe;
  }
  // Without the receiver the augmenter computes no classes; with it they are needed.
  if (result.stereo_classes.size() != static_cast<std::size_t>(w) * static_cast<std::size_t>(h))
    return make_error(where, "the augmentation has no stereo classes (AugmentOptions::stereo_classes)");
  cv::Rect roi(0, 0, w, h);
  if (!options_.full_frame) {
    const int m = mp.block_size / 2 + options_.context_px;
    const int x0 = std::max(0, bx0 - std::max(0, mp.min_disparity + mp.num_disparities) - m);
    const int x1 = std::min(w, bx1 + std::max(0, -mp.min_disparity) + m);
    const int y0 = std::max(0, by0 - m), y1 = std::min(h, by1 + m);
    roi = cv::Rect(x0, y0, x1 - x0, y1 - y0);
  }
  fe.matched = roi;

  // 2. Gray and rectified over the region, both pairs.
  t0 = Clock::now();
  const Image aug_left = whole_augmented(raw.left.image, result.left);
  const Image aug_right = whole_augmented(raw.right.image, result.right);
  cv::Mat rect[2][2];  // [raw, augmented][left, right]
  const ConstImageView src[2][2] = {{raw.left.image.view(), raw.right.image.view()},
                                    {aug_left.view(), aug_right.view()}};
  for (int k = 0; k < 2; ++k)
    for (int c = 0; c < 2; ++c)
      cv::remap(gray_of(src[k][c]), rect[k][c], rect_.map_x[c](roi), rect_.map_y[c](roi), cv::INTER_LINEAR,
                cv::BORDER_CONSTANT);
  fe.prepare_ms = ms_since(t0);

  // 3. Both pairs matched; the raw one on a second thread when the matcher itself uses one.
  t0 = Clock::now();
  Expected<cv::Mat> disp_raw = make_error("not matched");
  std::future<Expected<cv::Mat>> raw_job;
  const bool single_threaded = mp.algorithm == "sgbm" && (mp.mode == "sgbm" || mp.mode == "hh");
  if (options_.parallel && single_threaded)
    raw_job = std::async(std::launch::async, [&] { return match_disparity(mp, rect[0][0], rect[0][1]); });
  else
    disp_raw = match_disparity(mp, rect[0][0], rect[0][1]);
  Expected<cv::Mat> disp_aug = match_disparity(mp, rect[1][0], rect[1][1]);
  if (raw_job.valid()) disp_raw = raw_job.get();
  fe.match_ms = ms_since(t0);
  if (!disp_raw) return make_error(where, "raw pair: ", disp_raw.error().message);
  if (!disp_aug) return make_error(where, "augmented pair: ", disp_aug.error().message);

  // 4. Scored per stereo class, over the region (the receiver lies inside it).
  t0 = Clock::now();
  const cv::Mat classes(h, w, CV_8UC1, const_cast<std::uint8_t*>(result.stereo_classes.data()));
  const cv::Mat mask = cv_view(result.left.mask.view());
  const cv::Mat classes_r = rectify_labels_in(rect_, classes, roi);
  const cv::Mat mask_r = rectify_labels_in(rect_, mask, roi);
  const double fb = rect_.f_px * rect_.baseline_m;
  fe.raw = score_disparity(truth(roi), *disp_raw, classes_r, mask_r, fb);
  fe.augmented = score_disparity(truth(roi), *disp_aug, classes_r, mask_r, fb);
  fe.score_ms = truth_ms + ms_since(t0);
  if (images) {
    images->true_disparity = truth;
    for (auto [from, to] :
         {std::pair{&*disp_raw, &images->raw_disparity}, std::pair{&*disp_aug, &images->aug_disparity}}) {
      *to = cv::Mat(h, w, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
      from->copyTo((*to)(roi));
    }
  }
  return fe;
}

}  // namespace augrig::eval
