// write_png_file: RGB comes back from OpenCV's BGR files in the right order, gray stays gray, the
// caller's pixels stay unchanged, errors name the file.
#include "render/image_file.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

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

// encode_jpeg: decoded by OpenCV's own reader, the image comes back (PSNR over 35 dB at quality 90,
// the channels in their order), a Bayer mosaic as its colours, Mono8 as gray; quality costs bytes.
TEST(ImageFile, JpegDecodesBackToTheImage) {
  Image rgb(320, 240, PixelFormat::kRGB8);
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) {
      std::uint8_t* p = rgb.row(y) + 3 * x;
      p[0] = static_cast<std::uint8_t>(x * 255 / 319);  // red ramps to the right
      p[1] = static_cast<std::uint8_t>(y * 255 / 239);  // green down
      p[2] = 60;
    }
  auto hi = encode_jpeg(rgb.cview(), 90);
  ASSERT_TRUE(hi) << hi.error().message;
  EXPECT_EQ((*hi)[0], 0xff);
  EXPECT_EQ((*hi)[1], 0xd8);  // SOI
  const cv::Mat back = cv::imdecode(*hi, cv::IMREAD_COLOR);
  ASSERT_EQ(back.size(), cv::Size(320, 240));
  const cv::Mat want(240, 320, CV_8UC3, rgb.data(), rgb.stride_bytes());
  cv::Mat want_bgr;
  cv::cvtColor(want, want_bgr, cv::COLOR_RGB2BGR);
  EXPECT_GT(cv::PSNR(back, want_bgr), 35.0);
  auto lo = encode_jpeg(rgb.cview(), 20);
  ASSERT_TRUE(lo);
  EXPECT_LT(lo->size(), hi->size());

  Image bayer(64, 48, PixelFormat::kBayerRG8);  // a uniform red-ish colour as an RG mosaic
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      const int ch = bayer_channel(PixelFormat::kBayerRG8, x, y);
      bayer.row(y)[x] = static_cast<std::uint8_t>(ch == 0 ? 220 : ch == 1 ? 90 : 20);
    }
  const cv::Mat c = cv::imdecode(*encode_jpeg(bayer.cview(), 95), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(c.type(), CV_8UC3);
  const cv::Vec3b mid = c.at<cv::Vec3b>(24, 32);
  EXPECT_NEAR(mid[2], 220, 6);
  EXPECT_NEAR(mid[1], 90, 6);
  EXPECT_NEAR(mid[0], 20, 6);

  Image mono(16, 16, PixelFormat::kMono8);
  std::fill(mono.data(), mono.data() + 256, std::uint8_t{128});
  EXPECT_EQ(cv::imdecode(*encode_jpeg(mono.cview(), 80), cv::IMREAD_UNCHANGED).type(), CV_8UC1);
  auto bad = encode_jpeg(rgb.cview(), 0);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, "encode_jpeg(): quality 0: expected 1..100");
  EXPECT_FALSE(encode_jpeg(ConstImageView{}, 80));
}

}  // namespace
}  // namespace augrig
