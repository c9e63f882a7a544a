// H264Encoder / H264Decoder: each frame one Annex B unit, keyframes (IDR with SPS and PPS) where the
// interval and the caller put them and nowhere else, no B-frames (ffprobe, FFmpeg's own tool, reads
// the concatenated stream: its frame types and count), pictures decoded back close to what went in
// (colour, gray as gray, Bayer demosaiced, odd sizes cropped), a decoder that joins at a keyframe
// mid-stream, and errors for what cannot be coded or decoded.
#include "render/video_codec.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "render/cv_image.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

// A textured, moving scene: what a camera gives (smooth shading, edges, some fine detail).
Image scene_rgb(int w, int h, int frame) {
  Image im(w, h, PixelFormat::kRGB8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = im.row(y) + 3 * x;
      const double u = x + 2.0 * frame, v = y + 1.0 * frame;
      // Smooth colour, sharp edges in brightness (as a camera's 4:2:0 stream carries them).
      const int edge = ((static_cast<int>(u) / 16 + static_cast<int>(v) / 16) % 2) ? 40 : -40;
      p[0] = static_cast<std::uint8_t>(128 + 60 * std::sin(u / 17.0) + edge);
      p[1] = static_cast<std::uint8_t>(128 + 50 * std::cos(v / 23.0) + edge);
      p[2] = static_cast<std::uint8_t>(128 + 40 * std::sin((u + v) / 31.0) + edge);
    }
  return im;
}

double psnr(const cv::Mat& a, const cv::Mat& b) {
  return cv::PSNR(a, b);
}

// The NAL unit types in an Annex B unit, in order.
std::vector<int> nal_types(const std::vector<std::uint8_t>& d) {
  std::vector<int> t;
  for (std::size_t i = 0; i + 3 < d.size(); ++i)
    if (d[i] == 0 && d[i + 1] == 0 && d[i + 2] == 1) {
      t.push_back(d[i + 3] & 0x1f);
      i += 2;
    }
  return t;
}

bool has(const std::vector<int>& v, int x) {
  return std::find(v.begin(), v.end(), x) != v.end();
}

TEST(H264, EveryFrameOneUnitKeyframesWhereAskedNoBFramesAndCloseToTheInput) {
  const int w = 320, h = 240, n = 40;
  H264Options o;
  o.gop_frames = 10;
  auto enc = H264Encoder::create(w, h, o);
  ASSERT_TRUE(enc) << enc.error().message;
  auto dec = H264Decoder::create();
  ASSERT_TRUE(dec) << dec.error().message;
  const std::string file = test::output_dir("video_codec") + "/stream.h264";
  std::ofstream out(file, std::ios::binary);
  std::vector<bool> key;
  for (int i = 0; i < n; ++i) {
    const Image in = scene_rgb(w, h, i);
    auto unit = (*enc)->encode(in.cview(), TimestampNs{1'000'000'000} + i * 33'333'333LL, i == 15);
    ASSERT_TRUE(unit) << unit.error().message;
    out.write(reinterpret_cast<const char*>(unit->data.data()),
              static_cast<std::streamsize>(unit->data.size()));
    key.push_back(unit->keyframe);
    const std::vector<int> types = nal_types(unit->data);
    const bool idr = has(types, 5);
    EXPECT_EQ(idr, unit->keyframe) << "frame " << i;
    EXPECT_EQ(has(types, 7) && has(types, 8), idr)
        << "frame " << i << ": SPS and PPS with each IDR, only there";
    EXPECT_EQ(unit->data[0] | unit->data[1], 0) << "Annex B start code";
    // Decoded at once, this frame's picture (nothing held back).
    auto pic = (*dec)->decode(unit->data.data(), unit->data.size());
    ASSERT_TRUE(pic) << i << ": " << pic.error().message;
    ASSERT_EQ(pic->format(), PixelFormat::kRGB8);
    ASSERT_EQ(pic->width(), w);
    EXPECT_GT(psnr(cv_view(pic->cview()), cv_view(in.cview())), 32.0) << "frame " << i;
  }
  out.close();
  // Keyframes: the interval's (0, 10, 20, 30; x264 counts on from a forced one) and the forced 15.
  EXPECT_TRUE(key[0]);
  EXPECT_TRUE(key[15]);
  int keys = 0;
  for (int i = 0; i < n; ++i) keys += key[i] ? 1 : 0;
  EXPECT_GE(keys, 4);
  EXPECT_LE(keys, 6);
  for (int i = 1; i < n; ++i)
    if (key[i]) {
      int gap = 1;
      while (i - gap > 0 && !key[i - gap]) ++gap;
      EXPECT_LE(gap, 10) << "frame " << i;
    }
  EXPECT_EQ((*enc)->frames(), static_cast<std::uint64_t>(n));

  // FFmpeg's ffprobe: n frames, only I and P, keyframes where we said.
  std::string probe;
  ASSERT_EQ(
      test::run_command("ffprobe -v error -show_entries frame=pict_type,key_frame -of csv=p=0 '" + file + "'",
                        &probe),
      0)
      << probe;
  std::istringstream lines(probe);
  int frames = 0;
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) continue;
    ASSERT_LT(frames, n);
    const bool k = line[0] == '1';
    EXPECT_EQ(k, static_cast<bool>(key[frames])) << "frame " << frames << ": " << line;
    EXPECT_TRUE(line.find(",I") != std::string::npos || line.find(",P") != std::string::npos) << line;
    ++frames;
  }
  EXPECT_EQ(frames, n) << probe;
}

TEST(H264, GrayStaysGrayAndBayerIsDemosaiced) {
  Image gray(64, 48, PixelFormat::kMono8);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) gray.row(y)[x] = static_cast<std::uint8_t>(x < 8 ? 0 : x > 56 ? 255 : 4 * x);
  auto enc = H264Encoder::create(64, 48);
  auto dec = H264Decoder::create();
  ASSERT_TRUE(enc && dec);
  auto unit = (*enc)->encode(gray.cview(), 0);
  ASSERT_TRUE(unit) << unit.error().message;
  auto pic = (*dec)->decode(unit->data.data(), unit->data.size());
  ASSERT_TRUE(pic) << pic.error().message;
  ASSERT_EQ(pic->format(), PixelFormat::kMono8);
  double worst = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) worst = std::max(worst, std::abs(double(pic->row(y)[x]) - gray.row(y)[x]));
  EXPECT_LE(worst, 6.0);
  EXPECT_LE(pic->row(20)[2], 3);     // black stays black (limited range mapped back)
  EXPECT_GE(pic->row(20)[60], 252);  // white stays white

  // Bayer: coded as the demosaiced colours (OpenCV's, as the JPEG topics).
  const Image rgb = scene_rgb(64, 48, 3);
  Image bayer(64, 48, PixelFormat::kBayerRG8);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) bayer.row(y)[x] = rgb.row(y)[3 * x + ((y % 2) + (x % 2))];  // R G / G B
  auto enc2 = H264Encoder::create(64, 48);
  auto dec2 = H264Decoder::create();
  auto u2 = (*enc2)->encode(bayer.cview(), 0);
  ASSERT_TRUE(u2) << u2.error().message;
  auto p2 = (*dec2)->decode(u2->data.data(), u2->data.size());
  ASSERT_TRUE(p2) << p2.error().message;
  ASSERT_EQ(p2->format(), PixelFormat::kRGB8);
  cv::Mat want;
  cv::cvtColor(bgr_of(bayer.cview()), want, cv::COLOR_BGR2RGB);
  EXPECT_GT(psnr(cv_view(p2->cview()), want), 30.0);
}

TEST(H264, OddSizesArePaddedAndCroppedBack) {
  const int w = 161, h = 97;
  const Image in = scene_rgb(w, h, 0);
  auto enc = H264Encoder::create(w, h);
  auto dec = H264Decoder::create();
  ASSERT_TRUE(enc && dec);
  auto unit = (*enc)->encode(in.cview(), 0);
  ASSERT_TRUE(unit) << unit.error().message;
  auto whole = (*dec)->decode(unit->data.data(), unit->data.size());
  ASSERT_TRUE(whole);
  EXPECT_EQ(whole->width(), 162);  // the coded size
  EXPECT_EQ(whole->height(), 98);
  auto dec2 = H264Decoder::create();
  auto pic = (*dec2)->decode(unit->data.data(), unit->data.size(), w, h);
  ASSERT_TRUE(pic);
  ASSERT_EQ(pic->width(), w);
  ASSERT_EQ(pic->height(), h);
  EXPECT_GT(psnr(cv_view(pic->cview()), cv_view(in.cview())), 32.0);
}

TEST(H264, ADecoderJoinsAtAKeyframeAndNotBefore) {
  const int w = 128, h = 96;
  H264Options o;
  o.gop_frames = 1000;  // no keyframe but the first and the one asked for
  auto enc = H264Encoder::create(w, h, o);
  ASSERT_TRUE(enc);
  std::vector<H264AccessUnit> units;
  for (int i = 0; i < 12; ++i) {
    auto u = (*enc)->encode(scene_rgb(w, h, i).cview(), i * 33'000'000LL, i == 6);
    ASSERT_TRUE(u) << u.error().message;
    units.push_back(std::move(*u));
  }
  ASSERT_FALSE(units[3].keyframe);
  ASSERT_TRUE(units[6].keyframe);
  // A client that joins at frame 3 has no picture until the keyframe.
  auto dec = H264Decoder::create();
  auto p3 = (*dec)->decode(units[3].data.data(), units[3].data.size());
  ASSERT_FALSE(p3);
  EXPECT_NE(p3.error().message.find("keyframe"), std::string::npos) << p3.error().message;
  for (int i = 6; i < 12; ++i) {
    auto p = (*dec)->decode(units[static_cast<std::size_t>(i)].data.data(),
                            units[static_cast<std::size_t>(i)].data.size());
    ASSERT_TRUE(p) << i << ": " << p.error().message;
    const Image want = scene_rgb(w, h, i);
    EXPECT_GT(psnr(cv_view(p->cview()), cv_view(want.cview())), 32.0) << i;
  }
}

TEST(H264, BitRateCapHolds) {
  // Fine moving texture at a high quality asked for: the cap, not the quality, decides the rate.
  const int w = 320, h = 240, n = 90;
  H264Options o;
  o.max_kbps = 200;
  o.crf = 10;
  auto enc = H264Encoder::create(w, h, o);
  ASSERT_TRUE(enc);
  std::size_t bytes = 0;
  for (int i = 0; i < n; ++i) {
    auto u = (*enc)->encode(scene_rgb(w, h, 3 * i).cview(), i * 33'333'333LL);
    ASSERT_TRUE(u);
    bytes += u->data.size();
  }
  // VBV: over T seconds at most the cap's T seconds plus its one-second buffer.
  const double seconds = n / 30.0, kbit = bytes * 8.0 / 1000.0;
  EXPECT_LT(kbit, 200 * (seconds + 1) * 1.05) << kbit / seconds << " kbit/s";
  // Without the cap the same frames take several times as much.
  o.max_kbps = 0;
  auto free = H264Encoder::create(w, h, o);
  std::size_t free_bytes = 0;
  for (int i = 0; i < n; ++i)
    free_bytes += (*free)->encode(scene_rgb(w, h, 3 * i).cview(), i * 33'333'333LL)->data.size();
  EXPECT_GT(free_bytes, 2 * bytes);
}

TEST(H264, ErrorsSayWhat) {
  EXPECT_NE(H264Encoder::create(1, 10).error().message.find("expected 2x2"), std::string::npos);
  H264Options o;
  o.crf = 60;
  EXPECT_NE(H264Encoder::create(64, 48, o).error().message.find("crf 60"), std::string::npos);
  o = {};
  o.gop_frames = 0;
  EXPECT_NE(H264Encoder::create(64, 48, o).error().message.find("keyframe interval"), std::string::npos);
  o = {};
  o.preset = "warp9";
  const std::string bad_preset = H264Encoder::create(64, 48, o).error().message;
  EXPECT_NE(bad_preset.find("preset 'warp9': expected one of ultrafast, superfast"), std::string::npos)
      << bad_preset;
  for (const char* p : {"ultrafast", "superfast", "veryslow"}) EXPECT_TRUE(is_x264_preset(p)) << p;
  for (const char* p : {"", "Ultrafast", "placebo", "fast "}) EXPECT_FALSE(is_x264_preset(p)) << p;
  auto enc = H264Encoder::create(64, 48);
  ASSERT_TRUE(enc);
  Image small(32, 48, PixelFormat::kRGB8);
  auto u = (*enc)->encode(small.cview(), 0);
  ASSERT_FALSE(u);
  EXPECT_NE(u.error().message.find("32x48"), std::string::npos) << u.error().message;

  auto dec = H264Decoder::create();
  EXPECT_FALSE((*dec)->decode(nullptr, 0));
  std::vector<std::uint8_t> junk(500);
  cv::RNG rng(3);
  for (auto& b : junk) b = static_cast<std::uint8_t>(rng.uniform(0, 256));
  EXPECT_FALSE((*dec)->decode(junk.data(), junk.size()));  // an error, not a crash
}

}  // namespace
}  // namespace augrig
