// The blob encodings against their definition: bit-exact round trips for every pixel format, with
// random, structured and padded images; the change box; damaged blobs are errors.
#include "recorder/codec.hpp"

#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

namespace augrig::recorder {
namespace {

constexpr PixelFormat kAllFormats[] = {PixelFormat::kMono8,    PixelFormat::kRGB8,     PixelFormat::kRGBA8,
                                       PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8,
                                       PixelFormat::kBayerBG8};

Image random_image(int w, int h, PixelFormat f, std::uint32_t seed, std::size_t stride = 0) {
  Image img(w, h, f, stride);
  std::mt19937 rng(seed);
  for (int y = 0; y < h; ++y)
    for (std::size_t x = 0; x < img.stride_bytes(); ++x) img.row(y)[x] = static_cast<std::uint8_t>(rng());
  return img;
}

// Smooth shading, per-channel offsets (a Bayer mosaic's colour sites differ), sharp edges and
// Gaussian noise: what a camera sees.
Image structured_image(int w, int h, PixelFormat f, std::uint32_t seed, double noise = 2.0) {
  Image img(w, h, f);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise);
  const int bpp = bytes_per_pixel(f);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < bpp; ++c) {
        const int ch = is_bayer(f) ? bayer_channel(f, x, y) : c;
        double v = 110 + 60 * std::sin(x * 0.011) * std::cos(y * 0.017) + 25.0 * ch + n(rng);
        if ((x / 37 + y / 29) % 5 == 0) v += 70;  // blocks with hard edges
        if (c == 3) v = 255;                      // alpha
        img.row(y)[x * bpp + c] = static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
      }
    }
  }
  return img;
}

TEST(Codec, PredictorDistance) {
  EXPECT_EQ(predictor_distance(PixelFormat::kMono8), 1);
  EXPECT_EQ(predictor_distance(PixelFormat::kRGB8), 3);
  EXPECT_EQ(predictor_distance(PixelFormat::kRGBA8), 4);
  for (PixelFormat f :
       {PixelFormat::kBayerRG8, PixelFormat::kBayerGR8, PixelFormat::kBayerGB8, PixelFormat::kBayerBG8})
    EXPECT_EQ(predictor_distance(f), 2);
}

TEST(Codec, ImageRoundTripIsBitExactForEveryFormat) {
  Encoder enc(1);
  Decoder dec;
  std::vector<std::uint8_t> blob;
  for (PixelFormat f : kAllFormats) {
    SCOPED_TRACE(std::string(to_string(f)));
    // Odd sizes (a row shorter than the SIMD width, an odd width) and a padded stride.
    for (auto [w, h] : {std::pair{1, 1}, {3, 2}, {17, 5}, {321, 243}, {640, 480}}) {
      for (int kind = 0; kind < 3; ++kind) {
        const Image img = kind == 0   ? random_image(w, h, f, 7 + w)
                          : kind == 1 ? structured_image(w, h, f, 11 + w)
                                      : random_image(w, h, f, 13 + w, w * bytes_per_pixel(f) + 13);
        ASSERT_TRUE(enc.encode_image(img.cview(), blob));
        Image back;
        ASSERT_TRUE(dec.decode_image(blob.data(), blob.size(), w, h, f, back));
        EXPECT_TRUE(pixels_equal(img, back)) << w << "x" << h << " kind " << kind;
      }
    }
  }
}

TEST(Codec, StructuredBayerCompresses) {
  Encoder enc(1);
  std::vector<std::uint8_t> blob;
  const Image img = structured_image(1280, 960, PixelFormat::kBayerRG8, 3);
  ASSERT_TRUE(enc.encode_image(img.cview(), blob));
  const double ratio = static_cast<double>(img.size_bytes()) / blob.size();
  EXPECT_GT(ratio, 1.5) << "predictor + zstd should beat 1.5:1 on a noisy (sigma 2) camera image";
  // Constant images shrink to almost nothing.
  Image flat(1280, 960, PixelFormat::kBayerRG8);
  ASSERT_TRUE(enc.encode_image(flat.cview(), blob));
  EXPECT_LT(blob.size(), 2000u);
}

TEST(Codec, ChangedBox) {
  const Image a = random_image(40, 30, PixelFormat::kRGB8, 1);
  Image b = a;
  EXPECT_TRUE(changed_box(a.cview(), b.cview()).empty());
  b.row(7)[3 * 11 + 2] ^= 1;  // pixel (11, 7), blue byte
  EXPECT_EQ(changed_box(a.cview(), b.cview()), (ChangedBox{11, 7, 12, 8}));
  b.row(20)[3 * 2 + 0] ^= 0x80;  // pixel (2, 20)
  EXPECT_EQ(changed_box(a.cview(), b.cview()), (ChangedBox{2, 7, 12, 21}));
  b.row(29)[3 * 39 + 1] ^= 0x01;  // the last pixel
  EXPECT_EQ(changed_box(a.cview(), b.cview()), (ChangedBox{2, 7, 40, 30}));
}

TEST(Codec, DifferenceRoundTripIsBitExact) {
  Encoder enc(1);
  Decoder dec;
  std::vector<std::uint8_t> blob;
  std::mt19937 rng(5);
  for (PixelFormat f : kAllFormats) {
    SCOPED_TRACE(std::string(to_string(f)));
    const Image raw = structured_image(200, 150, f, 21);
    // No change: empty box, empty blob.
    ChangedBox box;
    ASSERT_TRUE(enc.encode_difference(raw.cview(), raw.cview(), box, blob));
    EXPECT_TRUE(box.empty());
    EXPECT_TRUE(blob.empty());
    Image back;
    ASSERT_TRUE(dec.decode_difference(blob.data(), blob.size(), box, raw, back));
    EXPECT_TRUE(pixels_equal(raw, back));
    // A boom-like region painted over, plus scattered single bytes.
    Image aug = raw;
    const int bpp = bytes_per_pixel(f);
    for (int y = 40; y < 90; ++y)
      for (int x = 60 + y / 3; x < 90 + y / 3; ++x)
        for (int c = 0; c < bpp; ++c) aug.row(y)[x * bpp + c] = static_cast<std::uint8_t>(rng());
    aug.row(3)[5] ^= 1;
    aug.row(140)[199 * bpp] ^= 2;
    ASSERT_TRUE(enc.encode_difference(raw.cview(), aug.cview(), box, blob));
    EXPECT_EQ(box, (ChangedBox{5 / bpp, 3, 200, 141}));
    ASSERT_TRUE(dec.decode_difference(blob.data(), blob.size(), box, raw, back));
    EXPECT_TRUE(pixels_equal(aug, back));
  }
}

// The augmented image given as its part inside a box (the augmenter's changed-box output): the
// same box and the same blob as from the whole image, for boxes larger than the change, equal to
// it, holding no change and empty; boxes that do not fit are errors.
TEST(Codec, DifferenceFromTheChangedBoxEqualsTheWholeImages) {
  Encoder enc(1);
  Decoder dec;
  std::mt19937 rng(8);
  for (PixelFormat f : kAllFormats) {
    SCOPED_TRACE(std::string(to_string(f)));
    const Image raw = structured_image(120, 90, f, 31);
    const int bpp = bytes_per_pixel(f);
    Image aug = raw;
    for (int y = 30; y < 61; ++y)
      for (int x = 40 + y / 4; x < 55 + y / 4; ++x)
        for (int c = 0; c < bpp; ++c) aug.row(y)[x * bpp + c] = static_cast<std::uint8_t>(rng());
    ChangedBox want_box;
    std::vector<std::uint8_t> want, blob;
    ASSERT_TRUE(enc.encode_difference(raw.cview(), aug.cview(), want_box, want));
    ASSERT_EQ(want_box, (ChangedBox{47, 30, 70, 61}));
    for (const PixelBox within : {PixelBox{20, 10, 100, 80}, want_box, PixelBox{0, 0, 120, 90}}) {
      const Image part = Image::copy_of(sub_view(aug.cview(), within));
      ChangedBox box;
      ASSERT_TRUE(enc.encode_difference(raw.cview(), part.cview(), within, box, blob));
      EXPECT_EQ(box, want_box);
      EXPECT_EQ(blob, want);
      Image back;
      ASSERT_TRUE(dec.decode_difference(blob.data(), blob.size(), box, raw, back));
      EXPECT_TRUE(pixels_equal(aug, back));
    }
    // A box where nothing changed, and an empty one: no change.
    for (const PixelBox within : {PixelBox{0, 0, 30, 20}, PixelBox{}}) {
      const Image part = within.empty() ? Image() : Image::copy_of(sub_view(aug.cview(), within));
      ChangedBox box{1, 1, 2, 2};
      ASSERT_TRUE(enc.encode_difference(raw.cview(), part.cview(), within, box, blob));
      EXPECT_TRUE(box.empty());
      EXPECT_TRUE(blob.empty());
    }
    // Outside the image, a part of another size or format: errors that say so.
    ChangedBox box;
    const Image part(30, 20, f);
    auto s = enc.encode_difference(raw.cview(), part.cview(), PixelBox{100, 80, 130, 100}, box, blob);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("is not inside the raw image 120x90"), std::string::npos)
        << s.error().message;
    s = enc.encode_difference(raw.cview(), part.cview(), PixelBox{0, 0, 31, 20}, box, blob);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("differs from its box's size 31x20"), std::string::npos)
        << s.error().message;
    const Image other(30, 20, f == PixelFormat::kMono8 ? PixelFormat::kRGB8 : PixelFormat::kMono8);
    EXPECT_FALSE(enc.encode_difference(raw.cview(), other.cview(), PixelBox{0, 0, 30, 20}, box, blob));
  }
}

TEST(Codec, MaskRoundTrip) {
  Encoder enc(1);
  Decoder dec;
  std::vector<std::uint8_t> blob;
  Image mask(333, 201, PixelFormat::kMono8, 340);  // padded stride
  for (int y = 50; y < 120; ++y)
    for (int x = 100; x < 180; ++x) mask.row(y)[x] = static_cast<std::uint8_t>((x + y) % 3);
  ASSERT_TRUE(enc.encode_mask(mask.cview(), blob));
  EXPECT_LT(blob.size(), 4000u);
  Image back;
  ASSERT_TRUE(dec.decode_mask(blob.data(), blob.size(), 333, 201, back));
  EXPECT_TRUE(pixels_equal(mask, back));
  Image rgb(4, 4, PixelFormat::kRGB8);
  EXPECT_FALSE(enc.encode_mask(rgb.cview(), blob));
}

TEST(Codec, DamagedBlobsAreErrors) {
  Encoder enc(1);
  Decoder dec;
  std::vector<std::uint8_t> blob;
  const Image img = structured_image(320, 240, PixelFormat::kBayerGB8, 9);
  ASSERT_TRUE(enc.encode_image(img.cview(), blob));
  Image back;
  // A flipped byte in the payload: zstd's checksum (or the entropy decoder) catches it.
  for (std::size_t pos : {blob.size() / 3, blob.size() / 2, blob.size() - 10}) {
    std::vector<std::uint8_t> bad = blob;
    bad[pos] ^= 0x5a;
    const Status s = dec.decode_image(bad.data(), bad.size(), 320, 240, PixelFormat::kBayerGB8, back);
    EXPECT_FALSE(s) << "flip at " << pos;
  }
  // Truncated.
  {
    const Status s = dec.decode_image(blob.data(), blob.size() / 2, 320, 240, PixelFormat::kBayerGB8, back);
    ASSERT_FALSE(s);
  }
  // Trailing bytes.
  {
    std::vector<std::uint8_t> bad = blob;
    bad.push_back(0);
    const Status s = dec.decode_image(bad.data(), bad.size(), 320, 240, PixelFormat::kBayerGB8, back);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("after its zstd frame"), std::string::npos) << s.error().message;
  }
  // The size recorded for the image does not match the blob.
  {
    const Status s = dec.decode_image(blob.data(), blob.size(), 320, 241, PixelFormat::kBayerGB8, back);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("holds 76800 bytes, expected 77120"), std::string::npos)
        << s.error().message;
  }
  // Not zstd at all, or nothing.
  {
    const std::vector<std::uint8_t> junk(100, 0x42);
    EXPECT_FALSE(dec.decode_image(junk.data(), junk.size(), 10, 10, PixelFormat::kMono8, back));
    EXPECT_FALSE(dec.decode_image(nullptr, 0, 10, 10, PixelFormat::kMono8, back));
  }
  // A change box outside the image.
  {
    const Image raw(10, 10, PixelFormat::kMono8);
    EXPECT_FALSE(dec.decode_difference(blob.data(), blob.size(), ChangedBox{0, 0, 11, 5}, raw, back));
  }
}

TEST(Codec, DepthRoundTripIsBitExactAndDamageIsAnError) {
  Encoder enc(1);
  Decoder dec;
  std::mt19937 rng(11);
  std::vector<float> z(53 * 41);
  for (std::size_t i = 0; i < z.size(); ++i) {
    std::uint32_t b = static_cast<std::uint32_t>(rng());
    if (i % 3) b = 0x41a00000u + static_cast<std::uint32_t>(i) * 97u;  // 20 m and up, smooth
    std::memcpy(&z[i], &b, sizeof b);                                    // every third: any bits (NaNs too)
  }
  std::vector<std::uint8_t> blob;
  ASSERT_TRUE(enc.encode_depth(z.data(), 53, 41, blob));
  std::vector<float> back;
  ASSERT_TRUE(dec.decode_depth(blob.data(), blob.size(), 53, 41, back));
  ASSERT_EQ(back.size(), z.size());
  EXPECT_EQ(std::memcmp(back.data(), z.data(), z.size() * sizeof(float)), 0);
  // The box's size is checked against the blob; a flipped byte fails the checksum.
  EXPECT_FALSE(dec.decode_depth(blob.data(), blob.size(), 53, 40, back));
  std::vector<std::uint8_t> bad = blob;
  bad[bad.size() / 2] ^= 0x10;
  EXPECT_FALSE(dec.decode_depth(bad.data(), bad.size(), 53, 41, back));
  // An empty box is an empty blob, and only that.
  ASSERT_TRUE(enc.encode_depth(z.data(), 0, 0, blob));
  EXPECT_TRUE(blob.empty());
  EXPECT_TRUE(dec.decode_depth(nullptr, 0, 0, 0, back));
  EXPECT_TRUE(back.empty());
  const std::uint8_t junk[3] = {1, 2, 3};
  EXPECT_FALSE(dec.decode_depth(junk, 3, 0, 0, back));
}

// A row's width and height say what to allocate. A damaged or hostile row (20000x20000 for a
// small blob) must be refused from the blob's header, before the image is allocated; an absurd
// size (2e9 x 2e9, 16 EB) must be an error, not bad_alloc.
TEST(Codec, RowSizeIsCheckedBeforeAllocating) {
  Encoder enc(1);
  Decoder dec;
  std::vector<std::uint8_t> blob;
  const Image img = structured_image(10, 10, PixelFormat::kMono8, 3);
  ASSERT_TRUE(enc.encode_image(img.cview(), blob));
  std::vector<std::uint8_t> mask_blob;
  ASSERT_TRUE(enc.encode_mask(img.cview(), mask_blob));
  {
    Image back;
    const Status s = dec.decode_image(blob.data(), blob.size(), 20000, 20000, PixelFormat::kMono8, back);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("holds 100 bytes, expected 400000000"), std::string::npos)
        << s.error().message;
    EXPECT_NE(s.error().message.find("20000x20000"), std::string::npos) << s.error().message;
    EXPECT_EQ(back.size_bytes(), 0u) << "allocated before the blob was checked";
  }
  {
    Image back;
    const Status s = dec.decode_mask(mask_blob.data(), mask_blob.size(), 20000, 20000, back);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("20000x20000"), std::string::npos) << s.error().message;
    EXPECT_EQ(back.size_bytes(), 0u) << "allocated before the blob was checked";
  }
  for (const auto& [w, h] : {std::pair{2000000000, 2000000000}, std::pair{70000, 10}, std::pair{10, 65536},
                             std::pair{0, 10}, std::pair{10, -5}}) {
    Image back;
    Status s;
    ASSERT_NO_THROW(s = dec.decode_image(blob.data(), blob.size(), w, h, PixelFormat::kRGBA8, back));
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("bad image size " + std::to_string(w) + "x" + std::to_string(h)),
              std::string::npos)
        << s.error().message;
    ASSERT_NO_THROW(s = dec.decode_mask(mask_blob.data(), mask_blob.size(), w, h, back));
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("bad mask size"), std::string::npos) << s.error().message;
    EXPECT_EQ(back.size_bytes(), 0u);
  }
  // The largest side allowed still decodes.
  const Image wide = structured_image(65535, 1, PixelFormat::kMono8, 4);
  ASSERT_TRUE(enc.encode_image(wide.cview(), blob));
  Image back;
  ASSERT_TRUE(dec.decode_image(blob.data(), blob.size(), 65535, 1, PixelFormat::kMono8, back));
  EXPECT_TRUE(pixels_equal(wide, back));
}

}  // namespace
}  // namespace augrig::recorder
