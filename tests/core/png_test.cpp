// core/png: every file it writes decodes, through an independent reader (OpenCV's imdecode,
// libpng underneath), to exactly the pixels given: each kind, channel count and compression, sizes
// that are not a multiple of a band, and an image encoded reusing another's bands.
#include "core/png.hpp"

#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace augrig {
namespace {

// Smooth gradients with noise: compressible, but not trivially.
Image test_image(int w, int h, PixelFormat f, unsigned seed) {
  Image im(w, h, f);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(-3, 3);
  const int bpp = bytes_per_pixel(f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w * bpp; ++x)
      im.row(y)[x] = static_cast<std::uint8_t>((x / bpp + 2 * y + 40 * (x % bpp)) / 3 + noise(rng));
  return im;
}

// The file decoded by OpenCV, back in the Image's channel order.
cv::Mat decode(const std::string& file) {
  cv::Mat m = cv::imdecode(std::vector<std::uint8_t>(file.begin(), file.end()), cv::IMREAD_UNCHANGED);
  if (m.channels() == 3) cv::cvtColor(m, m, cv::COLOR_BGR2RGB);
  if (m.channels() == 4) cv::cvtColor(m, m, cv::COLOR_BGRA2RGBA);
  return m;
}

void expect_same(const cv::Mat& m, const Image& im) {
  ASSERT_FALSE(m.empty());
  ASSERT_EQ(m.depth(), CV_8U);
  ASSERT_EQ(m.cols, im.width());
  ASSERT_EQ(m.rows, im.height());
  ASSERT_EQ(m.channels(), bytes_per_pixel(im.format()));
  const std::size_t row_bytes = static_cast<std::size_t>(im.width()) * static_cast<std::size_t>(m.channels());
  for (int y = 0; y < im.height(); ++y)
    ASSERT_EQ(std::memcmp(m.ptr<std::uint8_t>(y), im.row(y), row_bytes), 0) << "row " << y;
}

TEST(Png, EveryFormatAndCompressionDecodesExactly) {
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kRGB8, PixelFormat::kRGBA8})
    for (PngKind kind : {PngKind::kImage, PngKind::kMask})
      for (int compression : {0, 1, 2, 6, 9}) {
        SCOPED_TRACE(std::string(to_string(f)) + " kind " + std::to_string(static_cast<int>(kind)) +
                     " compression " + std::to_string(compression));
        const Image im = test_image(97, 70, f, 3);  // 70 rows: two whole bands and a short one
        PngEncoder enc(compression, kind);
        auto png = enc.encode(im);
        ASSERT_TRUE(png) << png.error().message;
        EXPECT_EQ(png->bands.size(), 3u);
        expect_same(decode(png_file(*png)), im);
      }
}

// The encoder is reused image after image (one per thread): each file stands alone.
TEST(Png, OneEncoderManyImages) {
  PngEncoder enc(1, PngKind::kImage);
  for (unsigned seed = 0; seed < 4; ++seed) {
    const Image im = test_image(64 + static_cast<int>(seed), 33, PixelFormat::kMono8, seed);
    auto png = enc.encode(im);
    ASSERT_TRUE(png);
    expect_same(decode(png_file(*png)), im);
  }
}

// An augmented image reuses the raw image's bands where its rows are unchanged, and is exactly
// itself once decoded; a reuse that does not fit (another size) is ignored.
TEST(Png, ReusedBandsDecodeToTheNewImage) {
  for (int compression : {0, 1, 6}) {
    SCOPED_TRACE(compression);
    const Image raw = test_image(120, 100, PixelFormat::kRGB8, 1);
    Image aug = raw;
    for (int y = 40; y < 50; ++y)
      for (int x = 30; x < 60; ++x) aug.row(y)[x] = 255;
    PngEncoder enc(compression, PngKind::kImage);
    auto raw_png = enc.encode(raw);
    ASSERT_TRUE(raw_png);
    auto aug_png = enc.encode(aug, &*raw_png, &raw);
    ASSERT_TRUE(aug_png);
    EXPECT_EQ(aug_png->bands[0].bytes, raw_png->bands[0].bytes);  // rows 0..31 unchanged: the same bytes
    EXPECT_EQ(aug_png->bands[3].bytes, raw_png->bands[3].bytes);
    expect_same(decode(png_file(*aug_png)), aug);
    expect_same(decode(png_file(*raw_png)), raw);
    const Image other = test_image(60, 100, PixelFormat::kRGB8, 2);
    auto other_png = enc.encode(other, &*raw_png, &raw);
    ASSERT_TRUE(other_png);
    expect_same(decode(png_file(*other_png)), other);
  }
}

TEST(Png, WriteBinaryFileNamesAPathItCannotCreate) {
  const std::string path = ::testing::TempDir() + "/no_such_dir/x.png";
  const Status s = write_binary_file(path, "x");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find(path + ": cannot create the file"), std::string::npos)
      << s.error().message;
  const std::string ok = ::testing::TempDir() + "/png_test_bytes.bin";
  ASSERT_TRUE(write_binary_file(ok, std::string("ab\0c", 4)));
  std::FILE* f = std::fopen(ok.c_str(), "rb");
  ASSERT_TRUE(f);
  char buf[8];
  EXPECT_EQ(std::fread(buf, 1, sizeof buf, f), 4u);
  std::fclose(f);
  std::remove(ok.c_str());
}

}  // namespace
}  // namespace augrig
