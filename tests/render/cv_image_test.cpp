// cv_image: each of augrig's formats as OpenCV gray and BGR, the Bayer patterns' phases included
// (a pattern taken for another swaps red and blue).
#include "render/cv_image.hpp"

#include <gtest/gtest.h>

#include "core/image.hpp"

namespace augrig {
namespace {

// A uniform colour (r, g, b) as a 16x12 mosaic of Bayer pattern `f`.
Image mosaic(PixelFormat f, int r, int g, int b) {
  Image im(16, 12, f);
  for (int y = 0; y < 12; ++y)
    for (int x = 0; x < 16; ++x) {
      const int ch = bayer_channel(f, x, y);
      im.row(y)[x] = static_cast<std::uint8_t>(ch == 0 ? r : ch == 1 ? g : b);
    }
  return im;
}

// The Bayer pattern's phase: a uniform colour mosaicked as each PFNC pattern comes back as that
// colour's gray (a pattern taken for another would swap red and blue).
TEST(CvImage, GrayOfEveryBayerPatternAndColourFormat) {
  const int R = 200, G = 100, B = 30;
  const double gray = 0.299 * R + 0.587 * G + 0.114 * B;
  for (PixelFormat f :
       {PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8}) {
    const cv::Mat g = gray_of(mosaic(f, R, G, B).cview());
    ASSERT_EQ(g.type(), CV_8UC1);
    EXPECT_NEAR(g.at<std::uint8_t>(6, 8), gray, 1.0) << to_string(f);
  }
  Image rgb(4, 2, PixelFormat::kRGB8);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 4; ++x) {
      rgb.row(y)[3 * x] = R;
      rgb.row(y)[3 * x + 1] = G;
      rgb.row(y)[3 * x + 2] = B;
    }
  EXPECT_NEAR(gray_of(rgb.cview()).at<std::uint8_t>(1, 2), gray, 1.0);
  Image mono(3, 3, PixelFormat::kMono8);
  mono.row(1)[1] = 77;
  EXPECT_EQ(gray_of(mono.cview()).at<std::uint8_t>(1, 1), 77);
}

TEST(CvImage, ColourIsBgrAndBayerIsDemosaicedAsOpenCvDoes) {
  Image rgb(2, 1, PixelFormat::kRGB8);
  rgb.data()[0] = 10, rgb.data()[1] = 20, rgb.data()[2] = 30;
  const cv::Mat b = bgr_of(rgb.cview());
  ASSERT_EQ(b.type(), CV_8UC3);
  EXPECT_EQ(b.at<cv::Vec3b>(0, 0), cv::Vec3b(30, 20, 10));
  Image mono(3, 2, PixelFormat::kMono8);
  mono.data()[4] = 77;
  const cv::Mat g = bgr_of(mono.cview());
  ASSERT_EQ(g.type(), CV_8UC1);
  EXPECT_EQ(g.at<std::uint8_t>(1, 1), 77);
  // GenICam's BayerRG is OpenCV's BayerBG: a red site at (0, 0).
  Image bayer(8, 8, PixelFormat::kBayerRG8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) bayer.data()[y * 8 + x] = (y % 2 == 0 && x % 2 == 0) ? 200 : 0;
  const cv::Mat c = bgr_of(bayer.cview());
  ASSERT_EQ(c.type(), CV_8UC3);
  EXPECT_EQ(c.at<cv::Vec3b>(4, 4)[2], 200);  // red
  EXPECT_EQ(c.at<cv::Vec3b>(4, 4)[0], 0);    // no blue
  // Every pattern: a uniform colour mosaicked comes back as that colour.
  for (PixelFormat f :
       {PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8}) {
    const cv::Vec3b bgr = bgr_of(mosaic(f, 200, 100, 30).cview()).at<cv::Vec3b>(6, 8);
    EXPECT_NEAR(bgr[0], 30, 1) << to_string(f);
    EXPECT_NEAR(bgr[1], 100, 1) << to_string(f);
    EXPECT_NEAR(bgr[2], 200, 1) << to_string(f);
  }
}

TEST(CvImage, ViewsShareThePixelsWithTheFormatsType) {
  Image rgba(5, 3, PixelFormat::kRGBA8);
  const cv::Mat v = cv_view(rgba.cview());
  EXPECT_EQ(v.type(), CV_8UC4);
  EXPECT_EQ(v.size(), cv::Size(5, 3));
  rgba.row(2)[4 * 4 + 1] = 9;  // no copy: the image's own bytes
  EXPECT_EQ(v.at<cv::Vec4b>(2, 4)[1], 9);
  EXPECT_EQ(cv_view(Image(4, 4, PixelFormat::kRGB8).cview()).type(), CV_8UC3);
  EXPECT_EQ(cv_view(Image(4, 4, PixelFormat::kBayerGB8).cview()).type(), CV_8UC1);
  EXPECT_TRUE(gray_of(ConstImageView{}).empty());
}

}  // namespace
}  // namespace augrig
