// The matchers on a synthetic rectified pair whose disparity is known everywhere (a random texture
// shifted by a slanted disparity field), and their parameter files' errors.
#include "eval/matcher.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace augrig::eval {
namespace {

// Left: a blurred random texture; right(x) = left(x + d(x, y)) for d = 20 + 0.02 x + 0.01 y.
void synthetic_pair(cv::Mat& left, cv::Mat& right, cv::Mat& truth) {
  const int w = 400, h = 240;
  cv::Mat tex(h, w + 120, CV_8UC1);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> u(0, 255);
  for (int y = 0; y < tex.rows; ++y)
    for (int x = 0; x < tex.cols; ++x) tex.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(u(rng));
  cv::GaussianBlur(tex, tex, cv::Size(5, 5), 1.0);
  left = tex(cv::Rect(0, 0, w, h)).clone();
  right.create(h, w, CV_8UC1);
  truth.create(h, w, CV_32FC1);
  cv::Mat map_x(h, w, CV_32FC1), map_y(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) truth.at<float>(y, x) = static_cast<float>(20.0 + 0.02 * x + 0.01 * y);
  // right(xr) shows the point the left shows at xl = xr + d: solve per right pixel (d varies slowly).
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double xl = x + 20.0;
      for (int it = 0; it < 5; ++it) xl = x + 20.0 + 0.02 * xl + 0.01 * y;
      map_x.at<float>(y, x) = static_cast<float>(xl);
      map_y.at<float>(y, x) = static_cast<float>(y);
    }
  cv::remap(tex, right, map_x, map_y, cv::INTER_LINEAR);
}

TEST(Matcher, SgbmAndBmFindAKnownDisparity) {
  cv::Mat left, right, truth;
  synthetic_pair(left, right, truth);
  for (const char* algo : {"sgbm", "bm"}) {
    SCOPED_TRACE(algo);
    MatcherParams p;
    p.algorithm = algo;
    p.num_disparities = 64;
    p.block_size = algo == std::string("bm") ? 9 : 5;
    auto d = match_disparity(p, left, right, 40, 200);
    ASSERT_TRUE(d) << d.error().message;
    int valid = 0, good = 0, outside_band = 0;
    for (int y = 0; y < d->rows; ++y)
      for (int x = 80; x < d->cols - 10; ++x) {
        const float v = d->at<float>(y, x);
        if (y < 40 || y >= 200) {
          outside_band += !std::isnan(v);
          continue;
        }
        if (std::isnan(v)) continue;
        ++valid;
        good += std::abs(v - truth.at<float>(y, x)) < 1.0f;
      }
    EXPECT_EQ(outside_band, 0) << "only the rows asked for";
    EXPECT_GT(valid, 0.8 * 160 * (400 - 90));
    EXPECT_GT(good, 0.95 * valid);
  }
  // Wrong inputs.
  MatcherParams p;
  EXPECT_FALSE(match_disparity(p, left, right(cv::Rect(0, 0, 100, 100))));
  cv::Mat colour;
  cv::cvtColor(left, colour, cv::COLOR_GRAY2BGR);
  EXPECT_FALSE(match_disparity(p, colour, colour));
}

TEST(Matcher, ParameterFilesNameTheLineAndKey) {
  auto ok = parse_matcher_params("algorithm: bm\nnum_disparities: 192\nblock_size: 15\n", "m.yaml");
  ASSERT_TRUE(ok) << ok.error().message;
  EXPECT_EQ(ok->algorithm, "bm");
  EXPECT_EQ(ok->num_disparities, 192);
  EXPECT_EQ(ok->block_size, 15);
  EXPECT_EQ(ok->uniqueness_ratio, 10) << "the default";
  ASSERT_TRUE(parse_matcher_params("", "empty.yaml")) << "all defaults";
  struct Case {
    std::string text, expected;
  } cases[] = {
      {"num_disparities: 100\n", "m.yaml:1:18: key 'num_disparities': expected a multiple of 16"},
      {"algorithm: sgbm\nblock_size: 4\n", "m.yaml:2:13: key 'block_size': expected an odd integer"},
      {"algorithm: bm\nblock_size: 3\n", "expected at least 5 for bm"},
      {"algorithm: census\n", "key 'algorithm': expected sgbm or bm, got 'census'"},
      {"blok_size: 5\n", "key 'blok_size': unknown key"},
      {"p1: 100\np2: 50\n", "expected p2 > p1 (100)"},
      {"uniqueness_ratio: 1e9\n", "key 'uniqueness_ratio': expected a percentage in [0, 100]"},
      {"- 1\n- 2\n", "expected a map of matcher parameters"},
      {"mode: [\n", "YAML syntax error"},
  };
  for (const Case& c : cases) {
    auto r = parse_matcher_params(c.text, "m.yaml");
    ASSERT_FALSE(r) << c.text;
    EXPECT_NE(r.error().message.find(c.expected), std::string::npos) << r.error().message;
  }
  auto missing = load_matcher_params("/no/such/matcher.yaml");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("/no/such/matcher.yaml: cannot open"), std::string::npos);
}

}  // namespace
}  // namespace augrig::eval
