// Stereo matchers for the evaluation (issue 18 §3): OpenCV's StereoSGBM and StereoBM on a
// rectified pair, with their parameters from a YAML file (docs/EVALUATE.md lists the keys), and
// only over the rows that hold ground truth when asked (the receiver rarely fills the frame).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "core/expected.hpp"

namespace augrig::eval {

struct MatcherParams {
  std::string algorithm = "sgbm";  // sgbm | bm
  int min_disparity = 0;
  int num_disparities = 64;  // a positive multiple of 16 (the paper rig's receiver: <= 44 px)
  int block_size = 5;         // odd; bm: 5..255
  // sgbm: smoothness penalties; 0 = OpenCV's usual 8 and 32 x channels x block_size^2.
  int p1 = 0, p2 = 0;
  int uniqueness_ratio = 10;
  int speckle_window_size = 100;
  int speckle_range = 2;
  int disp12_max_diff = 1;
  int pre_filter_cap = 63;
  std::string mode = "3way";  // sgbm: sgbm | hh | 3way | hh4 (3way: the fastest, on several threads)
};

// Reads a matcher file: a map of the fields above (`algorithm: sgbm`, `num_disparities: 192`, ...),
// any subset, over the defaults. Errors name the file, line and key, and what was expected.
Expected<MatcherParams> load_matcher_params(const std::string& path);
// The same from YAML text (`name` for the messages).
Expected<MatcherParams> parse_matcher_params(const std::string& text, const std::string& name);

// Disparity (CV_32FC1, rectified px, u_left - u_right) of a rectified 8-bit gray pair, NaN where
// the matcher found none. Only rows [row0, row1) are matched (with the block's margin around them);
// the other rows are NaN. Errors: other image types or sizes, parameters OpenCV refuses.
Expected<cv::Mat> match_disparity(const MatcherParams& p, const cv::Mat& left_gray, const cv::Mat& right_gray,
                                  int row0 = 0, int row1 = -1);

}  // namespace augrig::eval
