#include "eval/matcher.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include <opencv2/calib3d.hpp>

#include "core/yaml_reader.hpp"

namespace augrig::eval {

Expected<MatcherParams> parse_matcher_params(const std::string& text, const std::string& name) {
  const yaml::Context c{"eval::load_matcher_params(): ", name};
  return yaml::guarded(c, [&]() -> MatcherParams {
    const YAML::Node root = YAML::Load(text);
    MatcherParams p;
    if (!root.IsDefined() || root.IsNull()) return p;
    yaml::expect_map(c, root, "", "a map of matcher parameters (docs/EVALUATE.md)");
    yaml::check_keys(
        c, root, "",
        {"algorithm", "min_disparity", "num_disparities", "block_size", "p1", "p2", "uniqueness_ratio",
         "speckle_window_size", "speckle_range", "disp12_max_diff", "pre_filter_cap", "mode"});
    auto integer = [&](const char* key, int& out, int lo, int hi, const std::string& what) {
      const YAML::Node n = root[key];
      if (!n.IsDefined()) return;
      const double v = yaml::to_number(c, n, key, what);
      if (!(v >= lo && v <= hi) || v != std::floor(v))
        yaml::fail(c, n, key, "expected " + what + ", got " + yaml::fmt(v));
      out = static_cast<int>(v);
    };
    if (const YAML::Node n = root["algorithm"]; n.IsDefined()) {
      p.algorithm = yaml::to_string_value(c, n, "algorithm", "sgbm or bm");
      if (p.algorithm != "sgbm" && p.algorithm != "bm")
        yaml::fail(c, n, "algorithm", "expected sgbm or bm, got '" + p.algorithm + "'");
    }
    if (const YAML::Node n = root["mode"]; n.IsDefined()) {
      p.mode = yaml::to_string_value(c, n, "mode", "sgbm, hh, 3way or hh4");
      if (p.mode != "sgbm" && p.mode != "hh" && p.mode != "3way" && p.mode != "hh4")
        yaml::fail(c, n, "mode", "expected sgbm, hh, 3way or hh4, got '" + p.mode + "'");
    }
    integer("min_disparity", p.min_disparity, -4096, 4096, "an integer in [-4096, 4096]");
    integer("num_disparities", p.num_disparities, 16, 4096, "a multiple of 16 in [16, 4096]");
    if (p.num_disparities % 16 != 0)
      yaml::fail(c, root["num_disparities"], "num_disparities",
                 "expected a multiple of 16 in [16, 4096], got " + std::to_string(p.num_disparities));
    integer("block_size", p.block_size, 1, 255, "an odd integer in [1, 255]");
    if (p.block_size % 2 == 0)
      yaml::fail(c, root["block_size"], "block_size",
                 "expected an odd integer in [1, 255], got " + std::to_string(p.block_size));
    if (p.algorithm == "bm" && p.block_size < 5)
      yaml::fail(c, root["block_size"].IsDefined() ? root["block_size"] : root, "block_size",
                 "expected at least 5 for bm, got " + std::to_string(p.block_size));
    integer("p1", p.p1, 0, 1 << 24, "an integer >= 0 (0: OpenCV's usual)");
    integer("p2", p.p2, 0, 1 << 24, "an integer >= 0 (0: OpenCV's usual)");
    integer("uniqueness_ratio", p.uniqueness_ratio, 0, 100, "a percentage in [0, 100]");
    integer("speckle_window_size", p.speckle_window_size, 0, 1 << 20, "an integer >= 0");
    integer("speckle_range", p.speckle_range, 0, 4096, "an integer >= 0");
    integer("disp12_max_diff", p.disp12_max_diff, -1, 4096, "an integer >= -1 (-1: no check)");
    integer("pre_filter_cap", p.pre_filter_cap, 1, 63, "an integer in [1, 63]");
    if (p.p2 && p.p1 && p.p2 <= p.p1)
      yaml::fail(c, root["p2"], "p2",
                 "expected p2 > p1 (" + std::to_string(p.p1) + "), got " + std::to_string(p.p2));
    return p;
  });
}

Expected<MatcherParams> load_matcher_params(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return make_error("eval::load_matcher_params(): ", path, ": cannot open the file");
  std::ostringstream s;
  s << f.rdbuf();
  return parse_matcher_params(s.str(), path);
}

Expected<cv::Mat> match_disparity(const MatcherParams& p, const cv::Mat& left_gray, const cv::Mat& right_gray,
                                  int row0, int row1) {
  const char* where = "eval::match_disparity(): ";
  if (left_gray.type() != CV_8UC1 || right_gray.type() != CV_8UC1)
    return make_error(where, "expected 8-bit gray images");
  if (left_gray.size() != right_gray.size())
    return make_error(where, "the left and right images differ in size");
  const int h = left_gray.rows;
  if (row1 < 0 || row1 > h) row1 = h;
  row0 = std::clamp(row0, 0, h);
  cv::Mat out(left_gray.size(), CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  if (row0 >= row1) return out;
  // The rows asked for plus the block's reach (and SGBM's paths need some context): a band.
  const int margin = p.block_size + 8;
  const int b0 = std::max(0, row0 - margin), b1 = std::min(h, row1 + margin);
  const cv::Rect band(0, b0, left_gray.cols, b1 - b0);
  cv::Mat disp16;
  try {
    if (p.algorithm == "bm") {
      auto bm = cv::StereoBM::create(p.num_disparities, p.block_size);
      bm->setMinDisparity(p.min_disparity);
      bm->setUniquenessRatio(p.uniqueness_ratio);
      bm->setSpeckleWindowSize(p.speckle_window_size);
      bm->setSpeckleRange(p.speckle_range);
      bm->setDisp12MaxDiff(p.disp12_max_diff);
      bm->setPreFilterCap(p.pre_filter_cap);
      bm->compute(left_gray(band), right_gray(band), disp16);
    } else {
      const int area = p.block_size * p.block_size;
      const int mode = p.mode == "hh"     ? cv::StereoSGBM::MODE_HH
                       : p.mode == "3way" ? cv::StereoSGBM::MODE_SGBM_3WAY
                       : p.mode == "hh4"  ? cv::StereoSGBM::MODE_HH4
                                          : cv::StereoSGBM::MODE_SGBM;
      auto sgbm =
          cv::StereoSGBM::create(p.min_disparity, p.num_disparities, p.block_size, p.p1 ? p.p1 : 8 * area,
                                 p.p2 ? p.p2 : 32 * area, p.disp12_max_diff, p.pre_filter_cap,
                                 p.uniqueness_ratio, p.speckle_window_size, p.speckle_range, mode);
      sgbm->compute(left_gray(band), right_gray(band), disp16);
    }
  } catch (const cv::Exception& e) {
    return make_error(where, p.algorithm, ": OpenCV refused: ", e.what());
  }
  // 16 x disparity in CV_16S; below min_disparity means "none".
  const int invalid_below = p.min_disparity * 16;
  for (int y = row0; y < row1; ++y) {
    const std::int16_t* s = disp16.ptr<std::int16_t>(y - b0);
    float* d = out.ptr<float>(y);
    for (int x = 0; x < out.cols; ++x)
      if (s[x] >= invalid_below) d[x] = static_cast<float>(s[x]) / 16.0f;
  }
  return out;
}

}  // namespace augrig::eval
