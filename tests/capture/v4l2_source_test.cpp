// V4l2Source and list_v4l2_devices() driven against the fake V4L2 device
// (tests/support/fake_v4l2_device.hpp), and, when AUGRIG_V4L2_DEVICE=/dev/videoN is set, against a
// real device such as vivid (docs/V4L2.md).
#include "capture/v4l2_source.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <random>
#include <thread>

#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <unistd.h>

#include "tests/support/fake_v4l2_device.hpp"

namespace augrig {
namespace {

using namespace std::chrono_literals;
using test::fake_format;
using test::FakeV4l2Config;
using test::FakeV4l2Device;
using test::FakeV4l2Io;

constexpr auto kWait = 2s;  // frames are pushed before read(), so this is never waited out

FakeV4l2Config camera(std::vector<std::uint32_t> fourccs, std::uint32_t w = 64, std::uint32_t h = 48) {
  FakeV4l2Config c;
  c.formats.clear();
  for (std::uint32_t f : fourccs) c.formats.push_back(fake_format(f));
  c.width = w;
  c.height = h;
  return c;
}

V4l2Options options(std::vector<std::uint32_t> fourccs = {}) {
  V4l2Options o;
  o.device_path = "/dev/video0";
  o.pixel_formats = std::move(fourccs);
  return o;
}

// Streaming from open(): these tests push frames before the first read(), as a device that
// streams captures them (the default, streaming from the first read, has its own test).
std::unique_ptr<V4l2Source> open_ok(V4l2Options o, FakeV4l2Io& io) {
  o.stream_at_open = true;
  auto s = V4l2Source::open(o, io);
  EXPECT_TRUE(s) << s.error().message;
  return s ? std::move(*s) : nullptr;
}

TimestampNs monotonic_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<TimestampNs>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// ---------------------------------------------------------------------------------------------
// Fourccs and the format table

TEST(V4l2Formats, FourccTextRoundTrips) {
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_YUYV), "YUYV");
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_SBGGR8), "BA81");
  EXPECT_EQ(fourcc_to_string(V4L2_PIX_FMT_Y16), "Y16");
  ASSERT_TRUE(fourcc_from_string("MJPG"));
  EXPECT_EQ(*fourcc_from_string("MJPG"), static_cast<std::uint32_t>(V4L2_PIX_FMT_MJPEG));
  EXPECT_EQ(*fourcc_from_string("Y16"), static_cast<std::uint32_t>(V4L2_PIX_FMT_Y16));
  for (const char* bad : {"", "TOOLONG", "a b", "\x01XY"}) {
    auto r = fourcc_from_string(bad);
    ASSERT_FALSE(r) << bad;
    EXPECT_TRUE(contains(r.error().message, "fourcc_from_string()"));
  }
}

TEST(V4l2Formats, BayerFourccsMapToTheCellTheyName) {
  // The kernel names each Bayer format by its top-left 2x2 cell in reading order
  // (SBGGR8: "BGBG.. GRGR.."); PixelFormat::kBayerXY8 must sample the same colours.
  const struct {
    std::uint32_t fourcc;
    const char* cell;
    PixelFormat expected;
  } cases[] = {{V4L2_PIX_FMT_SBGGR8, "BGGR", PixelFormat::kBayerBG8},
               {V4L2_PIX_FMT_SGBRG8, "GBRG", PixelFormat::kBayerGB8},
               {V4L2_PIX_FMT_SGRBG8, "GRBG", PixelFormat::kBayerGR8},
               {V4L2_PIX_FMT_SRGGB8, "RGGB", PixelFormat::kBayerRG8}};
  for (const auto& c : cases) {
    const auto f = v4l2_to_pixel_format(c.fourcc);
    ASSERT_TRUE(f) << c.cell;
    EXPECT_EQ(*f, c.expected) << c.cell;
    for (int i = 0; i < 4; ++i) {
      const int channel = std::string("RGB").find(c.cell[i]);
      EXPECT_EQ(bayer_channel(*f, i % 2, i / 2), channel) << c.cell << " cell " << i;
    }
  }
  EXPECT_EQ(v4l2_to_pixel_format(V4L2_PIX_FMT_GREY), PixelFormat::kMono8);
  EXPECT_EQ(v4l2_to_pixel_format(V4L2_PIX_FMT_RGB24), PixelFormat::kRGB8);
  EXPECT_EQ(v4l2_to_pixel_format(V4L2_PIX_FMT_YUYV), PixelFormat::kRGB8);
  EXPECT_EQ(v4l2_to_pixel_format(V4L2_PIX_FMT_MJPEG), PixelFormat::kRGB8);
  EXPECT_FALSE(v4l2_to_pixel_format(V4L2_PIX_FMT_NV12));
}

// ---------------------------------------------------------------------------------------------
// Pixels

struct RawCase {
  std::uint32_t fourcc;
  PixelFormat format;
  int bytes_per_pixel;
};

class V4l2RawFormats : public ::testing::TestWithParam<RawCase> {};

// GREY, RGB24 and Bayer are copied bit-exactly, row by row, skipping the driver's row padding.
TEST_P(V4l2RawFormats, DeliversTheDriversBytesExactly) {
  for (std::uint32_t align : {1u, 64u}) {
    FakeV4l2Io io;
    FakeV4l2Config c = camera({GetParam().fourcc}, 70, 30);
    c.bytesperline_align = align;
    FakeV4l2Device& dev = io.add_device(c);
    auto src = open_ok(options({GetParam().fourcc}), io);
    ASSERT_TRUE(src);
    EXPECT_EQ(src->info().fourcc, GetParam().fourcc);
    EXPECT_EQ(src->info().pixel_format, GetParam().format);
    const std::uint32_t tight = 70u * GetParam().bytes_per_pixel;
    EXPECT_EQ(src->info().bytes_per_line, (tight + align - 1) / align * align);
    if (align == 64u) {
      EXPECT_GT(src->info().bytes_per_line, tight) << "the case must exercise padding";
    }

    ASSERT_TRUE(dev.push_frame(dev.pattern_frame(9)));
    Frame f;
    auto r = src->read(f, kWait);
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_EQ(*r, ReadStatus::kFrame);
    ASSERT_EQ(f.image.format(), GetParam().format);
    ASSERT_EQ(f.image.width(), 70);
    ASSERT_EQ(f.image.height(), 30);
    int mismatches = 0;
    for (int y = 0; y < 30; ++y)
      for (std::uint32_t x = 0; x < tight; ++x)
        mismatches += f.image.row(y)[x] != FakeV4l2Device::pattern_byte(static_cast<int>(x), y, 9);
    EXPECT_EQ(mismatches, 0) << "align " << align;
  }
}

INSTANTIATE_TEST_SUITE_P(AllRaw, V4l2RawFormats,
                         ::testing::Values(RawCase{V4L2_PIX_FMT_GREY, PixelFormat::kMono8, 1},
                                           RawCase{V4L2_PIX_FMT_RGB24, PixelFormat::kRGB8, 3},
                                           RawCase{V4L2_PIX_FMT_SBGGR8, PixelFormat::kBayerBG8, 1},
                                           RawCase{V4L2_PIX_FMT_SGBRG8, PixelFormat::kBayerGB8, 1},
                                           RawCase{V4L2_PIX_FMT_SGRBG8, PixelFormat::kBayerGR8, 1},
                                           RawCase{V4L2_PIX_FMT_SRGGB8, PixelFormat::kBayerRG8, 1}),
                         [](const auto& info) { return fourcc_to_string(info.param.fourcc); });

// BT.601 limited range in double precision: the textbook formula, rounded.
std::array<int, 3> bt601_reference(int y, int cb, int cr) {
  const double yy = 255.0 / 219.0 * (y - 16);
  const double k = 255.0 / 224.0;
  const double rgb[3] = {yy + 1.402 * k * (cr - 128),
                         yy - 0.344136 * k * (cb - 128) - 0.714136 * k * (cr - 128),
                         yy + 1.772 * k * (cb - 128)};
  std::array<int, 3> out{};
  for (int i = 0; i < 3; ++i) out[i] = std::clamp(static_cast<int>(std::lround(rgb[i])), 0, 255);
  return out;
}

TEST(V4l2Source, YuyvIsConvertedWithBt601LimitedRange) {
  const int w = 64, h = 48;
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_YUYV}, w, h);
  c.bytesperline_align = 256;  // 128 bytes of pixels, 128 of padding per row
  FakeV4l2Device& dev = io.add_device(c);
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  ASSERT_EQ(src->info().bytes_per_line, 256u);

  // Hand-computed pixels first (pairs share Cb/Cr), then random bytes.
  const std::uint8_t hand[][3] = {{16, 128, 128}, {235, 128, 128}, {126, 128, 128}, {81, 90, 240}};
  const std::array<int, 3> hand_rgb[] = {{0, 0, 0}, {255, 255, 255}, {128, 128, 128}, {254, 0, 0}};
  std::vector<std::uint8_t> bytes(256 * h, 0xEE);
  std::mt19937 rng(7);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < 2 * w; ++x) bytes[y * 256 + x] = static_cast<std::uint8_t>(rng());
  for (int i = 0; i < 4; ++i) {
    std::uint8_t* p = &bytes[4 * i];  // row 0, pixels 2i and 2i+1
    p[0] = p[2] = hand[i][0];
    p[1] = hand[i][1];
    p[3] = hand[i][2];
  }
  ASSERT_TRUE(dev.push_frame(bytes));
  Frame f;
  auto r = src->read(f, kWait);
  ASSERT_TRUE(r && *r == ReadStatus::kFrame);
  ASSERT_EQ(f.image.format(), PixelFormat::kRGB8);

  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 2; ++k)
      for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(f.image.row(0)[3 * (2 * i + k) + ch], hand_rgb[i][ch]) << i;

  // Against OpenCV's conversion (20-bit fixed point, its own rounding) and the double formula.
  // OpenCV clamps Y-16 at 0 before adding the chroma, so it differs for footroom values (Y < 16);
  // the BT.601 equations (and this backend) stay linear there. Those pixels are compared with the
  // double formula only.
  cv::Mat yuyv(h, w, CV_8UC2, bytes.data(), 256);
  cv::Mat rgb;
  cv::cvtColor(yuyv, rgb, cv::COLOR_YUV2RGB_YUYV);
  int max_cv = 0, max_ref = 0, off_cv = 0, off_ref = 0, compared_cv = 0, footroom = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::uint8_t* s = &bytes[y * 256 + (x & ~1) * 2];
      const int luma = s[(x & 1) * 2];
      const auto ref = bt601_reference(luma, s[1], s[3]);
      footroom += luma < 16;
      for (int ch = 0; ch < 3; ++ch) {
        const int ours = f.image.row(y)[3 * x + ch];
        max_ref = std::max(max_ref, std::abs(ours - ref[ch]));
        off_ref += ours != ref[ch];
        if (luma < 16) continue;
        const int d_cv = std::abs(ours - rgb.at<cv::Vec3b>(y, x)[ch]);
        max_cv = std::max(max_cv, d_cv);
        off_cv += d_cv != 0;
        ++compared_cv;
      }
    }
  }
  EXPECT_GT(footroom, 0) << "the random bytes must include footroom luma";
  EXPECT_LE(max_cv, 1) << "vs cv::cvtColor(COLOR_YUV2RGB_YUYV)";
  EXPECT_LE(max_ref, 1) << "vs the double-precision formula";
  // Off by one from the exact formula only where the value sits within fixed-point noise of .5
  // (2 of 9216 here). OpenCV rounds its coefficients to three decimals (2.018 for 2.0172 on Cb->B),
  // so about 4 % of its values differ by one.
  EXPECT_LT(off_ref, w * h * 3 / 200);
  EXPECT_LT(off_cv, compared_cv / 10);
}

cv::Mat test_picture_bgr(int w, int h) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<std::uint8_t>(4 * x), static_cast<std::uint8_t>(5 * y),
                                          static_cast<std::uint8_t>(255 - 2 * x - y));
  cv::circle(img, {w / 2, h / 2}, h / 3, {20, 200, 60}, -1);
  cv::rectangle(img, {4, 4}, {w / 4, h / 4}, {250, 250, 250}, -1);
  return img;
}

std::vector<std::uint8_t> jpeg_of(const cv::Mat& bgr) {
  std::vector<std::uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, 90}));
  return bytes;
}

TEST(V4l2Source, MjpegIsDecodedLikeOpenCvDecodesTheSameBytes) {
  const int w = 80, h = 48;
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_MJPEG}, w, h));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  EXPECT_EQ(src->info().fourcc, static_cast<std::uint32_t>(V4L2_PIX_FMT_MJPEG));
  EXPECT_EQ(src->info().bytes_per_line, 0u);

  const cv::Mat picture = test_picture_bgr(w, h);
  const std::vector<std::uint8_t> jpeg = jpeg_of(picture);
  ASSERT_TRUE(dev.push_frame(jpeg));
  Frame f;
  auto r = src->read(f, kWait);
  ASSERT_TRUE(r && *r == ReadStatus::kFrame) << (r ? "" : r.error().message);
  ASSERT_EQ(f.image.format(), PixelFormat::kRGB8);
  ASSERT_EQ(f.image.width(), w);
  ASSERT_EQ(f.image.height(), h);

  cv::Mat decoded_bgr = cv::imdecode(jpeg, cv::IMREAD_COLOR);
  int max_decode = 0;
  double sum_original = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        const int ours = f.image.row(y)[3 * x + ch];
        max_decode = std::max(max_decode, std::abs(ours - decoded_bgr.at<cv::Vec3b>(y, x)[2 - ch]));
        sum_original += std::abs(ours - picture.at<cv::Vec3b>(y, x)[2 - ch]);
      }
  EXPECT_LE(max_decode, 1) << "vs cv::imdecode of the same bytes";
  // The picture itself, within JPEG loss, in RGB order (BGR would be off by ~100 on average).
  EXPECT_LT(sum_original / (w * h * 3), 6.0);
  EXPECT_EQ(src->stats().decode_failures, 0u);
}

TEST(V4l2Source, CorruptMjpegIsADroppedFrameWithAReason) {
  const int w = 64, h = 48;
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_MJPEG}, w, h);
  c.max_buffers = 4;
  FakeV4l2Device& dev = io.add_device(c);
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  const std::vector<std::uint8_t> good = jpeg_of(test_picture_bgr(w, h));
  std::vector<std::uint8_t> truncated(good.begin(), good.begin() + good.size() / 2);
  std::vector<std::uint8_t> garbage(300);
  for (std::size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<std::uint8_t>(i * 37 + 11);
  const std::vector<std::uint8_t> wrong_size = jpeg_of(test_picture_bgr(32, 16));

  ASSERT_TRUE(dev.push_frame(garbage));
  Frame f;
  auto r = src->read(f, 20ms);
  ASSERT_TRUE(r);
  EXPECT_EQ(*r, ReadStatus::kTimeout);
  EXPECT_EQ(src->stats().decode_failures, 1u);
  EXPECT_TRUE(contains(src->stats().last_drop_reason, "corrupt MJPEG")) << src->stats().last_drop_reason;

  ASSERT_TRUE(dev.push_frame(truncated));
  ASSERT_TRUE(dev.push_frame(wrong_size));
  ASSERT_TRUE(dev.push_frame(good));
  r = src->read(f, kWait);
  ASSERT_TRUE(r && *r == ReadStatus::kFrame);
  EXPECT_EQ(f.sequence, 3u) << "the good frame after three bad ones";
  EXPECT_EQ(src->stats().decode_failures, 3u);
  EXPECT_TRUE(contains(src->stats().last_drop_reason, "MJPEG image is 32x16"))
      << src->stats().last_drop_reason;
  EXPECT_EQ(src->stats().frames_delivered, 1u);
  EXPECT_EQ(src->frames_dropped(), 3u);
  EXPECT_EQ(src->stats().sequence_gap_frames, 0u);
}

TEST(V4l2Source, TruncatedMjpegCanBeKeptWhenAskedTo) {
  const int w = 64, h = 48;
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_MJPEG}, w, h));
  V4l2Options o = options();
  o.keep_mjpeg_frames_with_warnings = true;
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  const std::vector<std::uint8_t> good = jpeg_of(test_picture_bgr(w, h));
  ASSERT_TRUE(dev.push_frame(std::vector<std::uint8_t>(good.begin(), good.begin() + good.size() * 2 / 3)));
  Frame f;
  auto r = src->read(f, kWait);
  ASSERT_TRUE(r && *r == ReadStatus::kFrame);
  EXPECT_EQ(src->stats().mjpeg_warnings_kept, 1u);
  EXPECT_EQ(src->stats().decode_failures, 0u);
}

TEST(V4l2Source, ShortBufferIsDropped) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 32, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  ASSERT_TRUE(dev.push_frame(std::vector<std::uint8_t>(32 * 16 - 1, 5)));
  ASSERT_TRUE(dev.push_frame(std::vector<std::uint8_t>(32 * 16, 6)));
  Frame f;
  auto r = src->read(f, kWait);
  ASSERT_TRUE(r && *r == ReadStatus::kFrame);
  EXPECT_EQ(f.image.row(15)[31], 6);
  EXPECT_EQ(src->stats().short_buffers, 1u);
  EXPECT_EQ(src->frames_dropped(), 1u);
}

// ---------------------------------------------------------------------------------------------
// Negotiation

TEST(V4l2Source, ReportsTheSizeTheDriverAdjustedTo) {
  FakeV4l2Io io;
  io.add_device(camera({V4L2_PIX_FMT_GREY}));  // stepwise 16..4096, step 2
  V4l2Options o = options();
  o.width_px = 641;
  o.height_px = 479;
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  EXPECT_EQ(src->info().width_px, 642);
  EXPECT_EQ(src->info().height_px, 480);
  ASSERT_EQ(src->info().notes.size(), 1u);
  EXPECT_TRUE(contains(src->info().notes[0], "641x479 to 642x480")) << src->info().notes[0];

  FakeV4l2Io io2;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_GREY});
  c.discrete_sizes = {{640, 480}, {1280, 720}};
  FakeV4l2Device& dev2 = io2.add_device(c);
  o.width_px = 1200;
  o.height_px = 700;
  auto src2 = open_ok(o, io2);
  ASSERT_TRUE(src2);
  EXPECT_EQ(src2->info().width_px, 1280);
  EXPECT_EQ(src2->info().height_px, 720);
  ASSERT_TRUE(dev2.push_frame(dev2.pattern_frame(1)));
  Frame f;
  ASSERT_TRUE(src2->read(f, kWait));
  EXPECT_EQ(f.image.width(), 1280);
  EXPECT_EQ(f.image.height(), 720);
}

TEST(V4l2Source, KeepsTheCurrentSizeWhenNoneIsAsked) {
  FakeV4l2Io io;
  io.add_device(camera({V4L2_PIX_FMT_GREY}, 320, 240));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  EXPECT_EQ(src->info().width_px, 320);
  EXPECT_EQ(src->info().height_px, 240);
  EXPECT_TRUE(src->info().notes.empty());
}

TEST(V4l2Source, PicksTheFirstWantedFormatTheDeviceOffers) {
  FakeV4l2Io io;
  io.add_device(camera({V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY}));
  auto best = open_ok(options(), io);  // default preference: YUYV before GREY before MJPEG
  ASSERT_TRUE(best);
  EXPECT_EQ(best->info().fourcc, static_cast<std::uint32_t>(V4L2_PIX_FMT_YUYV));
  best.reset();
  auto mono = open_ok(options({V4L2_PIX_FMT_SRGGB8, V4L2_PIX_FMT_GREY}), io);
  ASSERT_TRUE(mono);
  EXPECT_EQ(mono->info().fourcc, static_cast<std::uint32_t>(V4L2_PIX_FMT_GREY));
  EXPECT_EQ(mono->info().pixel_format, PixelFormat::kMono8);
}

TEST(V4l2Source, UnsupportedFormatsAreClearErrors) {
  FakeV4l2Io io;
  io.add_device(camera({V4L2_PIX_FMT_Y16, V4L2_PIX_FMT_NV12}));
  auto none = V4l2Source::open(options(), io);
  ASSERT_FALSE(none);
  EXPECT_TRUE(contains(none.error().message, "V4l2Source::open(): /dev/video0: ")) << none.error().message;
  EXPECT_TRUE(contains(none.error().message, "offers the pixel formats Y16, NV12")) << none.error().message;

  auto not_ours = V4l2Source::open(options({V4L2_PIX_FMT_NV12}), io);
  ASSERT_FALSE(not_ours);
  EXPECT_TRUE(contains(not_ours.error().message, "NV12 is not one augrig reads")) << not_ours.error().message;

  FakeV4l2Io io2;
  io2.add_device(camera({V4L2_PIX_FMT_YUYV}));
  auto absent = V4l2Source::open(options({V4L2_PIX_FMT_GREY}), io2);
  ASSERT_FALSE(absent);
  EXPECT_TRUE(contains(absent.error().message, "offers the pixel formats YUYV; none of the wanted GREY"))
      << absent.error().message;
  EXPECT_EQ(io2.open_files(), 0) << "failed opens close the device";
}

TEST(V4l2Source, AFormatTheDriverSubstitutesIsAnError) {
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY});
  c.enum_only_fourccs = {V4L2_PIX_FMT_GREY};  // listed, but S_FMT gives YUYV
  io.add_device(c);
  auto r = V4l2Source::open(options({V4L2_PIX_FMT_GREY}), io);
  ASSERT_FALSE(r);
  EXPECT_TRUE(contains(r.error().message, "substituted the pixel format YUYV for the requested GREY"))
      << r.error().message;
}

TEST(V4l2Source, InterlacedDevicesAreRefused) {
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_GREY});
  c.field = V4L2_FIELD_ALTERNATE;
  io.add_device(c);
  auto r = V4l2Source::open(options(), io);
  ASSERT_FALSE(r);
  EXPECT_TRUE(contains(r.error().message, "V4L2_FIELD_NONE")) << r.error().message;
}

TEST(V4l2Source, OpenErrorsNameTheDevice) {
  FakeV4l2Io io;
  V4l2Options o = options();
  o.device_path = "/dev/video7";
  auto missing = V4l2Source::open(o, io);
  ASSERT_FALSE(missing);
  EXPECT_TRUE(contains(missing.error().message, "/dev/video7: cannot open: ENOENT"))
      << missing.error().message;

  FakeV4l2Config out = camera({V4L2_PIX_FMT_GREY});
  out.path = "/dev/video1";
  out.device_caps = V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING;
  io.add_device(out);
  o.device_path = "/dev/video1";
  auto output = V4l2Source::open(o, io);
  ASSERT_FALSE(output);
  EXPECT_TRUE(
      contains(output.error().message, "/dev/video1: 'Fake V4L2 Camera' is not a video capture device"))
      << output.error().message;

  FakeV4l2Config denied = camera({V4L2_PIX_FMT_GREY});
  denied.path = "/dev/video2";
  denied.open_errno = EACCES;
  io.add_device(denied);
  o.device_path = "/dev/video2";
  auto perm = V4l2Source::open(o, io);
  ASSERT_FALSE(perm);
  EXPECT_TRUE(contains(perm.error().message, "EACCES")) << perm.error().message;
  EXPECT_TRUE(contains(perm.error().message, "'video' group")) << perm.error().message;

  o.device_path = "/dev/video0";
  o.buffer_count = 1;
  auto one = V4l2Source::open(o, io);
  ASSERT_FALSE(one);
  EXPECT_TRUE(contains(one.error().message, "buffer_count 1: expected at least 2")) << one.error().message;
}

// By default the device streams from the first read(): nothing is captured while the caller sets
// up, so no stale frames fill the buffers and no frame after them is lost.
TEST(V4l2Source, StreamsFromTheFirstRead) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}));
  auto r = V4l2Source::open(options(), io);
  ASSERT_TRUE(r) << r.error().message;
  auto& src = *r;
  EXPECT_FALSE(dev.streaming());
  EXPECT_EQ(dev.queued_buffers(), src->info().buffer_count);  // queued, ready for STREAMON
  EXPECT_FALSE(dev.push_frame(dev.pattern_frame(1))) << "a device not streaming captures nothing";
  Frame f;
  auto first = src->read(f, std::chrono::milliseconds(0));
  ASSERT_TRUE(first) << first.error().message;
  EXPECT_EQ(*first, ReadStatus::kTimeout);
  EXPECT_TRUE(dev.streaming());
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(2), {}, 0));
  auto second = src->read(f, kWait);
  ASSERT_TRUE(second) << second.error().message;
  EXPECT_EQ(*second, ReadStatus::kFrame);
  EXPECT_EQ(f.sequence, 0u);
  EXPECT_EQ(src->frames_dropped(), 0u);
  const auto log = dev.ioctl_log();
  EXPECT_EQ(std::count(log.begin(), log.end(), static_cast<unsigned long>(VIDIOC_STREAMON)), 1);
}

TEST(V4l2Source, ASecondReaderOfABusyDeviceIsRefused) {
  FakeV4l2Io io;
  io.add_device(camera({V4L2_PIX_FMT_GREY}));
  auto first = open_ok(options(), io);
  ASSERT_TRUE(first);
  auto second = V4l2Source::open(options(), io);
  ASSERT_FALSE(second);
  EXPECT_TRUE(contains(second.error().message, "EBUSY")) << second.error().message;
  EXPECT_EQ(io.open_files(), 1);
}

TEST(V4l2Source, MissingRealNodeIsAClearError) {
  V4l2Options o;
  for (int n = 63;; ++n) {
    o.device_path = "/dev/video" + std::to_string(n);
    if (::access(o.device_path.c_str(), F_OK) != 0) break;
  }
  auto r = V4l2Source::open(o);
  ASSERT_FALSE(r);
  EXPECT_TRUE(contains(r.error().message, o.device_path + ": cannot open: ENOENT")) << r.error().message;
}

TEST(V4l2Source, BuffersFrameRateAndTeardown) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}));
  V4l2Options o = options();
  o.buffer_count = 16;  // the fake grants at most 8
  o.frame_rate_hz = 60;
  {
    auto src = open_ok(o, io);
    ASSERT_TRUE(src);
    EXPECT_EQ(src->uri(), "v4l2:///dev/video0");
    EXPECT_EQ(src->info().buffer_count, 8u);
    EXPECT_EQ(src->info().frame_rate_hz, 60.0);
    EXPECT_EQ(dev.time_per_frame().numerator * 60, dev.time_per_frame().denominator);
    ASSERT_EQ(src->info().notes.size(), 1u);
    EXPECT_TRUE(contains(src->info().notes[0], "granted 8 buffers (requested 16)")) << src->info().notes[0];
    EXPECT_TRUE(dev.streaming());
    EXPECT_EQ(dev.mappings(), 8);
    EXPECT_EQ(dev.queued_buffers(), 8u);
  }
  // STREAMOFF, munmap, REQBUFS 0, close.
  EXPECT_FALSE(dev.streaming());
  EXPECT_EQ(dev.mappings(), 0);
  EXPECT_EQ(dev.buffer_count(), 0u);
  EXPECT_EQ(io.open_files(), 0);
  const auto log = dev.ioctl_log();
  ASSERT_GE(log.size(), 2u);
  EXPECT_EQ(log[log.size() - 2], static_cast<unsigned long>(VIDIOC_STREAMOFF));
  EXPECT_EQ(log.back(), static_cast<unsigned long>(VIDIOC_REQBUFS));

  o.buffer_count = 4;
  o.frame_rate_hz = 50;  // the fake has 15, 30 and 60
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  EXPECT_EQ(src->info().frame_rate_hz, 60.0);
  ASSERT_EQ(src->info().notes.size(), 1u);
  EXPECT_TRUE(contains(src->info().notes[0], "frame rate to 60")) << src->info().notes[0];
}

TEST(V4l2Source, AFrameRateTheDeviceCannotSetIsAnError) {
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_GREY});
  c.frame_intervals.clear();  // no G/S_PARM
  io.add_device(c);
  auto keep = open_ok(options(), io);
  ASSERT_TRUE(keep);
  EXPECT_EQ(keep->info().frame_rate_hz, 0.0);
  keep.reset();
  V4l2Options o = options();
  o.frame_rate_hz = 30;
  auto r = V4l2Source::open(o, io);
  ASSERT_FALSE(r);
  EXPECT_TRUE(contains(r.error().message, "cannot set the frame rate")) << r.error().message;
}

// ---------------------------------------------------------------------------------------------
// Controls

TEST(V4l2Source, SetsManualExposureAndGain) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}));
  V4l2Options o = options();
  o.exposure_ns = 2'000'000;  // 2 ms = 20 x 100 us
  o.gain = 100;
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  EXPECT_EQ(dev.control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(dev.control(V4L2_CID_EXPOSURE_ABSOLUTE), 20);
  EXPECT_EQ(dev.control(V4L2_CID_AUTOGAIN), 0);
  EXPECT_EQ(dev.control(V4L2_CID_GAIN), 100);
  EXPECT_EQ(src->info().exposure_ns, 2'000'000);
  EXPECT_EQ(src->info().gain, 100);
  EXPECT_TRUE(src->info().notes.empty());
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0)));
  Frame f;
  ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.exposure_ns, 2'000'000);
}

TEST(V4l2Source, ExposureIsRoundedTo100UsAndSaysSo) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}));
  V4l2Options o = options();
  o.exposure_ns = 2'040'000;
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  EXPECT_EQ(dev.control(V4L2_CID_EXPOSURE_ABSOLUTE), 20);
  EXPECT_EQ(src->info().exposure_ns, 2'000'000);
  ASSERT_EQ(src->info().notes.size(), 1u);
  EXPECT_TRUE(contains(src->info().notes[0], "100 us")) << src->info().notes[0];
}

TEST(V4l2Source, ControlErrorsNameTheControl) {
  FakeV4l2Io io;
  FakeV4l2Config bare = camera({V4L2_PIX_FMT_GREY});
  bare.controls.clear();
  io.add_device(bare);
  V4l2Options o = options();
  o.exposure_ns = 1'000'000;
  auto no_exposure = V4l2Source::open(o, io);
  ASSERT_FALSE(no_exposure);
  EXPECT_TRUE(contains(no_exposure.error().message,
                       "/dev/video0: the device has no control V4L2_CID_EXPOSURE_ABSOLUTE"))
      << no_exposure.error().message;
  o.exposure_ns.reset();
  o.gain = 3;
  auto no_gain = V4l2Source::open(o, io);
  ASSERT_FALSE(no_gain);
  EXPECT_TRUE(contains(no_gain.error().message, "no control V4L2_CID_GAIN")) << no_gain.error().message;

  FakeV4l2Io io2;
  io2.add_device(camera({V4L2_PIX_FMT_GREY}));
  V4l2Options o2 = options();
  o2.exposure_ns = 1'000'000'000;  // 1 s = 10000 units; the fake's maximum is 5000
  auto too_long = V4l2Source::open(o2, io2);
  ASSERT_FALSE(too_long);
  EXPECT_TRUE(contains(too_long.error().message, "outside the range [1, 5000] of V4L2_CID_EXPOSURE_ABSOLUTE"))
      << too_long.error().message;
  o2.exposure_ns.reset();
  o2.gain = 481;
  auto too_much = V4l2Source::open(o2, io2);
  ASSERT_FALSE(too_much);
  EXPECT_TRUE(contains(too_much.error().message, "gain 481 is outside the range [0, 480]"))
      << too_much.error().message;
}

TEST(V4l2Source, ExposureWithoutAnAutoExposureControl) {
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_GREY});
  c.controls = {{V4L2_CID_EXPOSURE_ABSOLUTE, "Exposure", V4L2_CTRL_TYPE_INTEGER, 1, 100, 1, 10}};
  FakeV4l2Device& dev = io.add_device(c);
  V4l2Options o = options();
  o.exposure_ns = 500'000;
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  EXPECT_EQ(dev.control(V4L2_CID_EXPOSURE_ABSOLUTE), 5);
}

// ---------------------------------------------------------------------------------------------
// Streaming: timeouts, sequence, errors, clocks

TEST(V4l2Source, NoFrameWithinTheTimeoutIsKTimeout) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  Frame f;
  auto r = src->read(f, 30ms);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(*r, ReadStatus::kTimeout);
  EXPECT_GE(dev.poll_calls(), 1);
  EXPECT_GT(dev.last_poll_timeout_ms(), 0);
  EXPECT_LE(dev.last_poll_timeout_ms(), 30);
  const int polls = dev.poll_calls();
  r = src->read(f, 0ns);
  ASSERT_TRUE(r);
  EXPECT_EQ(*r, ReadStatus::kTimeout);
  EXPECT_EQ(dev.poll_calls(), polls) << "a zero timeout only tries DQBUF";
  EXPECT_EQ(src->stats().frames_delivered, 0u);
  EXPECT_EQ(src->frames_dropped(), 0u);
}

TEST(V4l2Source, AFramePushedWhileWaitingIsDelivered) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  std::thread producer([&] {
    const auto give_up = std::chrono::steady_clock::now() + 10s;
    while (dev.poll_calls() == 0 && std::chrono::steady_clock::now() < give_up) std::this_thread::yield();
    dev.push_frame(dev.pattern_frame(3));
  });
  Frame f;
  auto r = src->read(f, 20s);
  producer.join();
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(*r, ReadStatus::kFrame);
  EXPECT_EQ(f.image.row(1)[2], FakeV4l2Device::pattern_byte(2, 1, 3));
}

TEST(V4l2Source, SequenceGapsAreCountedAsDroppedFrames) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);  // 4 buffers
  ASSERT_TRUE(src);
  for (std::uint32_t seq : {0u, 1u, 4u, 5u}) ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0), {}, seq));
  std::vector<std::uint64_t> seen;
  Frame f;
  for (int i = 0; i < 4; ++i) {
    auto r = src->read(f, kWait);
    ASSERT_TRUE(r && *r == ReadStatus::kFrame);
    seen.push_back(f.sequence);
    EXPECT_EQ(f.camera, CameraId::kLeft);
  }
  EXPECT_EQ(seen, (std::vector<std::uint64_t>{0, 1, 4, 5}));
  EXPECT_EQ(src->stats().sequence_gap_frames, 2u);
  EXPECT_EQ(src->frames_dropped(), 2u);

  // A real overrun: 6..9 fill the 4 buffers, 10 and 11 find none and are lost.
  for (int i = 0; i < 6; ++i) EXPECT_EQ(dev.push_frame(dev.pattern_frame(0)), i < 4);
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.sequence, 9u);
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0)));  // 12 (10 and 11 were lost)
  ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.sequence, 12u);
  EXPECT_EQ(src->stats().sequence_gap_frames, 4u);
  EXPECT_EQ(src->stats().frames_delivered, 9u);
  EXPECT_EQ(src->health().camera_drops, 4u);
  EXPECT_EQ(src->health().transport_drops, 0u);
  EXPECT_TRUE(src->health().connected);
}

TEST(V4l2Source, SequenceNumbersKeepCountingAcrossThe32BitWrap) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  for (std::uint32_t seq : {0xFFFFFFFEu, 0xFFFFFFFFu, 0u, 2u})
    ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0), {}, seq));
  std::vector<std::uint64_t> seen;
  Frame f;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(src->read(f, kWait));
    seen.push_back(f.sequence);
  }
  EXPECT_EQ(seen, (std::vector<std::uint64_t>{0xFFFFFFFEull, 0xFFFFFFFFull, 0x100000000ull, 0x100000002ull}));
  EXPECT_EQ(src->stats().sequence_gap_frames, 1u);
  EXPECT_EQ(src->stats().sequence_regressions, 0u);
}

TEST(V4l2Source, ErrorFlaggedBuffersAreDroppedAndCounted) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(1)));
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(2), {}, {}, V4L2_BUF_FLAG_ERROR));
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(3)));
  Frame f;
  ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.sequence, 0u);
  ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.sequence, 2u) << "the flagged frame 1 is skipped";
  EXPECT_EQ(f.image.row(0)[0], FakeV4l2Device::pattern_byte(0, 0, 3));
  EXPECT_EQ(src->stats().error_buffers, 1u);
  EXPECT_EQ(src->stats().sequence_gap_frames, 0u) << "not counted twice";
  EXPECT_EQ(src->frames_dropped(), 1u);
  EXPECT_TRUE(contains(src->stats().last_drop_reason, "V4L2_BUF_FLAG_ERROR"));
  EXPECT_EQ(src->health().transport_drops, 1u);
  EXPECT_EQ(src->health().camera_drops, 0u);
  EXPECT_EQ(dev.queued_buffers(), 4u) << "every buffer went back to the driver";
}

TEST(V4l2Source, MonotonicTimestampsAreHostMonotonic) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  V4l2Options o = options();
  o.camera = CameraId::kRight;
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0), 5'000'123'000));
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0), 5'000'100'000));  // goes back in time
  const TimestampNs before = monotonic_now_ns();
  Frame f;
  ASSERT_TRUE(src->read(f, kWait));
  const TimestampNs after = monotonic_now_ns();
  EXPECT_EQ(f.t_ns, 5'000'123'000);
  EXPECT_EQ(f.clock, ClockDomain::kHostMonotonic);
  EXPECT_GE(f.t_host_ns, before);
  EXPECT_LE(f.t_host_ns, after);
  EXPECT_EQ(f.camera, CameraId::kRight);
  EXPECT_EQ(f.exposure_ns, 0);
  ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.t_ns, 5'000'100'000);
  EXPECT_EQ(src->stats().non_monotonic_timestamps, 1u);
  EXPECT_EQ(src->stats().unknown_clock_frames, 0u);
}

TEST(V4l2Source, OtherTimestampClocksAreUnknownAndCounted) {
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_GREY}, 16, 16);
  c.timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN;  // an old driver stamping gettimeofday()
  FakeV4l2Device& dev = io.add_device(c);
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  const TimestampNs realtime_ns = 1'700'000'000'000'000'000;
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0), realtime_ns));
  Frame f;
  ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.clock, ClockDomain::kUnknown);
  EXPECT_EQ(f.t_ns, realtime_ns);
  EXPECT_EQ(src->stats().unknown_clock_frames, 1u);
}

TEST(V4l2Source, StartOfExposureTimestampsMoveToMidExposure) {
  FakeV4l2Io io;
  FakeV4l2Config c = camera({V4L2_PIX_FMT_GREY}, 16, 16);
  c.timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
  FakeV4l2Device& dev = io.add_device(c);
  V4l2Options o = options();
  o.exposure_ns = 4'000'000;
  auto src = open_ok(o, io);
  ASSERT_TRUE(src);
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0), 7'000'000'000));
  Frame f;
  ASSERT_TRUE(src->read(f, kWait));
  EXPECT_EQ(f.t_ns, 7'002'000'000);
  EXPECT_EQ(f.clock, ClockDomain::kHostMonotonic);
}

TEST(V4l2Source, ReusingTheSameFrameKeepsImagesApart) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  Frame f;
  for (std::uint8_t seed : {10, 20, 30}) {
    ASSERT_TRUE(dev.push_frame(dev.pattern_frame(seed)));
    ASSERT_TRUE(src->read(f, kWait));
    EXPECT_EQ(f.image.row(5)[7], FakeV4l2Device::pattern_byte(7, 5, seed));
  }
  const Image kept = f.image;
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(40)));
  Frame g;
  ASSERT_TRUE(src->read(g, kWait));
  EXPECT_EQ(kept.row(5)[7], FakeV4l2Device::pattern_byte(7, 5, 30));
  EXPECT_EQ(g.image.row(5)[7], FakeV4l2Device::pattern_byte(7, 5, 40));
}

// ---------------------------------------------------------------------------------------------
// A device that disappears

TEST(V4l2Source, UnplugBeforeReadIsAnErrorNamingTheDevice) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  ASSERT_TRUE(dev.push_frame(dev.pattern_frame(0)));
  dev.unplug();  // a done buffer is no longer reachable: every ioctl is ENODEV
  Frame f;
  auto r = src->read(f, kWait);
  ASSERT_FALSE(r);
  EXPECT_TRUE(contains(r.error().message, "V4l2Source::read(): /dev/video0: device disconnected"))
      << r.error().message;
  EXPECT_TRUE(contains(r.error().message, "ENODEV")) << r.error().message;
  auto again = src->read(f, kWait);
  ASSERT_FALSE(again);
  EXPECT_EQ(again.error().message, r.error().message);
  EXPECT_FALSE(src->health().connected);
  EXPECT_EQ(src->health().message, r.error().message);
  EXPECT_EQ(src->health().disconnects, 1u);
  src.reset();  // teardown on a vanished device
  EXPECT_EQ(io.open_files(), 0);
  EXPECT_EQ(io.mappings(), 0);
}

TEST(V4l2Source, UnplugDuringReadEndsTheReadWithAnError) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  std::thread unplugger([&] {
    const auto give_up = std::chrono::steady_clock::now() + 10s;
    while (dev.poll_calls() == 0 && std::chrono::steady_clock::now() < give_up) std::this_thread::yield();
    dev.unplug();
  });
  Frame f;
  auto r = src->read(f, 30s);  // the unplug must end it, not the timeout
  unplugger.join();
  ASSERT_FALSE(r) << "read returned " << (r ? static_cast<int>(*r) : -1);
  EXPECT_TRUE(contains(r.error().message, "/dev/video0: device disconnected")) << r.error().message;
}

TEST(V4l2Source, AQueueErrorIsAnError) {
  FakeV4l2Io io;
  FakeV4l2Device& dev = io.add_device(camera({V4L2_PIX_FMT_GREY}, 16, 16));
  auto src = open_ok(options(), io);
  ASSERT_TRUE(src);
  dev.set_queue_error();
  Frame f;
  auto r = src->read(f, kWait);
  ASSERT_FALSE(r);
  EXPECT_TRUE(
      contains(r.error().message, "/dev/video0: the driver reported an unrecoverable streaming error"))
      << r.error().message;
}

// ---------------------------------------------------------------------------------------------
// Listing

TEST(ListV4l2Devices, ListsCaptureNodesWithFormatsAndSizes) {
  FakeV4l2Io io;
  FakeV4l2Config cam = camera({V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_NV12});
  cam.card = "HD Webcam C920";
  cam.driver = "uvcvideo";
  cam.bus_info = "usb-0000:00:14.0-1";
  cam.discrete_sizes = {{640, 480}, {1920, 1080}};
  io.add_device(cam);
  FakeV4l2Config meta = camera({V4L2_PIX_FMT_GREY});
  meta.path = "/dev/video1";
  meta.device_caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;  // the UVC metadata node
  io.add_device(meta);
  FakeV4l2Config bayer = camera({V4L2_PIX_FMT_SRGGB8});
  bayer.path = "/dev/video2";
  bayer.card = "Rig camera";
  bayer.step_width = 8;
  bayer.step_height = 4;
  io.add_device(bayer);
  FakeV4l2Config denied = camera({V4L2_PIX_FMT_GREY});
  denied.path = "/dev/video3";
  denied.open_errno = EACCES;
  io.add_device(denied);

  auto list = list_v4l2_devices(io);
  ASSERT_TRUE(list) << list.error().message;
  ASSERT_EQ(list->size(), 3u);
  const V4l2DeviceInfo& c920 = (*list)[0];
  EXPECT_EQ(c920.path, "/dev/video0");
  EXPECT_EQ(c920.card, "HD Webcam C920");
  EXPECT_EQ(c920.driver, "uvcvideo");
  EXPECT_EQ(c920.bus_info, "usb-0000:00:14.0-1");
  EXPECT_TRUE(c920.error.empty());
  ASSERT_EQ(c920.formats.size(), 3u);
  EXPECT_EQ(c920.formats[0].fourcc, static_cast<std::uint32_t>(V4L2_PIX_FMT_YUYV));
  EXPECT_EQ(c920.formats[0].description, "YUYV 4:2:2");
  EXPECT_TRUE(c920.formats[0].supported);
  EXPECT_FALSE(c920.formats[0].compressed);
  EXPECT_TRUE(c920.formats[1].compressed);
  EXPECT_FALSE(c920.formats[2].supported);
  ASSERT_EQ(c920.formats[0].frame_sizes.size(), 2u);
  EXPECT_TRUE(c920.formats[0].frame_sizes[1].discrete());
  EXPECT_EQ(c920.formats[0].frame_sizes[1].max_width_px, 1920u);
  EXPECT_EQ(c920.formats[0].frame_sizes[1].max_height_px, 1080u);

  const V4l2DeviceInfo& rig = (*list)[1];
  EXPECT_EQ(rig.path, "/dev/video2");
  ASSERT_EQ(rig.formats.size(), 1u);
  ASSERT_EQ(rig.formats[0].frame_sizes.size(), 1u);
  const V4l2FrameSize& s = rig.formats[0].frame_sizes[0];
  EXPECT_FALSE(s.discrete());
  EXPECT_EQ(s.min_width_px, 16u);
  EXPECT_EQ(s.max_width_px, 4096u);
  EXPECT_EQ(s.step_width_px, 8u);
  EXPECT_EQ(s.step_height_px, 4u);

  EXPECT_EQ((*list)[2].path, "/dev/video3");
  EXPECT_TRUE(contains((*list)[2].error, "EACCES")) << (*list)[2].error;
  EXPECT_EQ(io.open_files(), 0);
}

TEST(ListV4l2Devices, NoDevicesIsAnEmptyList) {
  FakeV4l2Io io;
  auto list = list_v4l2_devices(io);
  ASSERT_TRUE(list);
  EXPECT_TRUE(list->empty());
  FakeV4l2Io gone;
  gone.add_device().unplug();
  auto none = list_v4l2_devices(gone);
  ASSERT_TRUE(none);
  EXPECT_TRUE(none->empty());
}

// ---------------------------------------------------------------------------------------------
// The same source on a real device: AUGRIG_V4L2_DEVICE=/dev/videoN (e.g. vivid, docs/V4L2.md).

class V4l2RealDevice : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* dev = std::getenv("AUGRIG_V4L2_DEVICE");
    if (dev == nullptr || *dev == '\0') {
      GTEST_SKIP() << "no real device: set AUGRIG_V4L2_DEVICE=/dev/videoN (e.g. after `sudo modprobe vivid`, "
                      "see docs/V4L2.md) to run these tests against it";
    }
    path_ = dev;
  }
  std::string path_;
};

TEST_F(V4l2RealDevice, IsListed) {
  auto list = list_v4l2_devices();
  ASSERT_TRUE(list) << list.error().message;
  auto it = std::find_if(list->begin(), list->end(), [&](const auto& d) { return d.path == path_; });
  ASSERT_NE(it, list->end()) << path_ << " is not listed as a capture device";
  EXPECT_TRUE(it->error.empty()) << it->error;
  EXPECT_FALSE(it->card.empty());
  EXPECT_FALSE(it->formats.empty());
}

TEST_F(V4l2RealDevice, StreamsEveryFormatItOffersThatAugrigReads) {
  auto list = list_v4l2_devices();
  ASSERT_TRUE(list);
  auto it = std::find_if(list->begin(), list->end(), [&](const auto& d) { return d.path == path_; });
  ASSERT_NE(it, list->end());
  int tested = 0;
  for (const V4l2FormatInfo& fmt : it->formats) {
    if (!fmt.supported) continue;
    SCOPED_TRACE(fourcc_to_string(fmt.fourcc));
    V4l2Options o;
    o.device_path = path_;
    o.pixel_formats = {fmt.fourcc};
    o.width_px = 640;
    o.height_px = 480;
    auto src = V4l2Source::open(o);
    ASSERT_TRUE(src) << src.error().message;
    const V4l2StreamInfo& info = (*src)->info();
    EXPECT_EQ(info.fourcc, fmt.fourcc);
    std::optional<std::uint64_t> last_seq;
    std::optional<TimestampNs> last_t;
    for (int i = 0; i < 5; ++i) {
      Frame f;
      auto r = (*src)->read(f, 3s);
      ASSERT_TRUE(r) << r.error().message;
      ASSERT_EQ(*r, ReadStatus::kFrame) << "no frame within 3 s";
      EXPECT_EQ(f.image.format(), *v4l2_to_pixel_format(fmt.fourcc));
      EXPECT_EQ(f.image.width(), info.width_px);
      EXPECT_EQ(f.image.height(), info.height_px);
      if (f.clock == ClockDomain::kHostMonotonic) {
        EXPECT_LE(f.t_ns, f.t_host_ns) << "a monotonic timestamp cannot be in the future";
        EXPECT_GT(f.t_ns, f.t_host_ns - 10'000'000'000) << "nor 10 s old";
      }
      if (last_seq) {
        EXPECT_GT(f.sequence, *last_seq);
      }
      if (last_t) {
        EXPECT_GT(f.t_ns, *last_t);
      }
      last_seq = f.sequence;
      last_t = f.t_ns;
    }
    EXPECT_EQ((*src)->stats().decode_failures, 0u);
    ++tested;
  }
  if (tested == 0) GTEST_SKIP() << path_ << " offers no format augrig reads";
}

TEST_F(V4l2RealDevice, GainWhenTheDeviceHasIt) {
  V4l2Options o;
  o.device_path = path_;
  o.gain = 0;
  auto src = V4l2Source::open(o);
  if (!src && contains(src.error().message, "no control V4L2_CID_GAIN")) GTEST_SKIP() << src.error().message;
  ASSERT_TRUE(src) << src.error().message;
  ASSERT_TRUE((*src)->info().gain.has_value());
  Frame f;
  auto r = (*src)->read(f, 3s);
  ASSERT_TRUE(r && *r == ReadStatus::kFrame);
}

}  // namespace
}  // namespace augrig
