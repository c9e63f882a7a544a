// write_png_file: RGB comes back from OpenCV's BGR files in the right order, gray stays gray, the
// caller's pixels stay unchanged, errors name the file.
#include "render/image_file.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

TEST(ImageFile, RgbAndGrayRoundTripThroughOpenCv) {
  const std::string dir = test::output_dir("image_file");
  Image rgb(3, 2, PixelFormat::kRGB8);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 3; ++x) {
      rgb.row(y)[3 * x] = static_cast<std::uint8_t>(10 * x + y);  // R
      rgb.row(y)[3 * x + 1] = 100;                                 // G
      rgb.row(y)[3 * x + 2] = 200;                                 // B
    }
  const Image before = rgb;
  ASSERT_TRUE(write_png_file(dir + "/rgb.png", rgb));
  EXPECT_TRUE(pixels_equal(rgb, before));
  const cv::Mat m = cv::imread(dir + "/rgb.png", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(m.type(), CV_8UC3);
  EXPECT_EQ(m.at<cv::Vec3b>(1, 2)[2], 21);  // OpenCV's BGR: red is the third channel
  EXPECT_EQ(m.at<cv::Vec3b>(1, 2)[0], 200);

  Image bayer(4, 2, PixelFormat::kBayerRG8);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 4; ++x) bayer.row(y)[x] = static_cast<std::uint8_t>(x + 4 * y);
  ASSERT_TRUE(write_png_file(dir + "/bayer.png", bayer));
  const cv::Mat g = cv::imread(dir + "/bayer.png", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(g.type(), CV_8UC1);
  EXPECT_EQ(g.at<std::uint8_t>(1, 3), 7);
}

TEST(ImageFile, ErrorsNameTheFile) {
  auto empty = write_png_file("/tmp/x.png", Image());
  ASSERT_FALSE(empty);
  EXPECT_NE(empty.error().message.find("/tmp/x.png: nothing to write"), std::string::npos);
  auto nodir = write_png_file("/nonexistent/dir/x.png", Image(2, 2, PixelFormat::kMono8));
  ASSERT_FALSE(nodir);
  EXPECT_NE(nodir.error().message.find("/nonexistent/dir/x.png"), std::string::npos);
}

}  // namespace
}  // namespace augrig
