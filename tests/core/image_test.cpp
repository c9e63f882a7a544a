#include "core/image.hpp"

#include <gtest/gtest.h>

namespace augrig {
namespace {

TEST(Image, StrideAndRows) {
  Image img(5, 3, PixelFormat::kRGB8, 20);
  EXPECT_EQ(img.stride_bytes(), 20u);
  EXPECT_EQ(img.size_bytes(), 60u);
  img.row(2)[14] = 7;
  EXPECT_EQ(img.data()[2 * 20 + 14], 7);
  Image tight(5, 3, PixelFormat::kRGB8);
  EXPECT_EQ(tight.stride_bytes(), 15u);
}

TEST(Image, CopyOfRepacksAndComparesPixelsOnly) {
  Image padded(4, 2, PixelFormat::kMono8, 8);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 8; ++x) padded.row(y)[x] = static_cast<std::uint8_t>(10 * y + x);
  Image copy = Image::copy_of(padded.cview());
  EXPECT_EQ(copy.stride_bytes(), 4u);
  EXPECT_TRUE(pixels_equal(copy, padded));  // padding bytes 4..7 are not pixels
  copy.row(1)[3] ^= 1;
  EXPECT_FALSE(pixels_equal(copy, padded));
}

TEST(Image, ReshapeKeepsTheBufferWhenItShrinks) {
  Image img(100, 50, PixelFormat::kRGB8, 400);
  const std::uint8_t* buffer = img.data();
  img.reshape(30, 20, PixelFormat::kMono8);
  EXPECT_EQ(img.width(), 30);
  EXPECT_EQ(img.height(), 20);
  EXPECT_EQ(img.format(), PixelFormat::kMono8);
  EXPECT_EQ(img.stride_bytes(), 30u);  // tight
  EXPECT_EQ(img.size_bytes(), 600u);
  EXPECT_EQ(img.data(), buffer);  // no reallocation
  img.row(19)[29] = 9;
  img.reshape(0, 0, PixelFormat::kRGB8);
  EXPECT_TRUE(img.empty());
  img.reshape(200, 100, PixelFormat::kRGBA8);  // grows: a larger buffer
  EXPECT_EQ(img.size_bytes(), 80000u);
  img.row(99)[799] = 1;
}

TEST(Image, BayerChannelsFollowPfncNames) {
  // BayerRG8: R G / G B
  EXPECT_EQ(bayer_channel(PixelFormat::kBayerRG8, 0, 0), 0);
  EXPECT_EQ(bayer_channel(PixelFormat::kBayerRG8, 1, 0), 1);
  EXPECT_EQ(bayer_channel(PixelFormat::kBayerRG8, 0, 1), 1);
  EXPECT_EQ(bayer_channel(PixelFormat::kBayerRG8, 1, 1), 2);
  // BayerGB8: G B / R G
  EXPECT_EQ(bayer_channel(PixelFormat::kBayerGB8, 1, 0), 2);
  EXPECT_EQ(bayer_channel(PixelFormat::kBayerGB8, 0, 1), 0);
  // Pattern repeats every 2 pixels.
  EXPECT_EQ(bayer_channel(PixelFormat::kBayerBG8, 4, 6), bayer_channel(PixelFormat::kBayerBG8, 0, 0));
  EXPECT_EQ(bayer_channel(PixelFormat::kMono8, 0, 0), -1);
}

TEST(Image, PixelFormatNamesRoundTrip) {
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kRGB8, PixelFormat::kRGBA8, PixelFormat::kBayerRG8,
                        PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8}) {
    PixelFormat g{};
    ASSERT_TRUE(parse_pixel_format(to_string(f), g));
    EXPECT_EQ(g, f);
  }
  PixelFormat g{};
  EXPECT_FALSE(parse_pixel_format("YUV422", g));
}

}  // namespace
}  // namespace augrig
