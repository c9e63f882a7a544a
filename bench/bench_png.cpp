// bench_png: augrig's own PNG writer (core/png, what the EuRoC export writes its images with)
// against OpenCV's (cv::imencode, libpng underneath) and libpng called directly, on 1280x960
// frames like a flight's: smooth ground texture, fields, a receiver and Gaussian sensor noise of
// sigma 2 DN. Encoding into memory only (no file I/O), one thread. Prints a Markdown table for
// docs/PERFORMANCE.md: ms per image (median of --reps), MB/s of pixels, the file's size, and
// every file decoded again by cv::imdecode and compared with its pixels.
//   build/bench_png [--reps N]
// Compression level semantics: core/png's 1 is Huffman-only coding of Sub-filtered rows (masks:
// run-length coding of Up-filtered rows), its 2..9 zlib's levels with Sub; OpenCV's level is
// zlib's level with libpng's adaptive filters (its default strategy, or the Huffman-only one
// with IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY); "libpng, Sub, Huffman-only" is core/png's level 1
// through libpng. The own writer has no 16-bit path: depth (render/ground_truth) goes through
// OpenCV, measured here for its cost alone.
// A second table: render/image_file's encode_jpeg (the live view's compressed topics, issue 35 §1;
// goal: quality 80 within 8 ms a view) on the same frames, RGB and as a Bayer mosaic (demosaiced
// first), with the decoded image's PSNR against what was encoded.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <png.h>
#include <zlib.h>

#include "core/image.hpp"
#include "core/png.hpp"
#include "render/cv_image.hpp"
#include "render/image_file.hpp"

using namespace augrig;

namespace {

constexpr int kW = 1280, kH = 960;

// Smooth value noise (a few octaves) plus fields, a receiver ellipse and sensor noise.
std::vector<float> scene(std::mt19937& rng) {
  std::vector<float> v(static_cast<std::size_t>(kW) * kH, 110.0f);
  for (int octave = 0; octave < 4; ++octave) {
    const int cell = 256 >> octave, n = std::max(kW, kH) / cell + 2;
    std::vector<float> lattice(static_cast<std::size_t>(n) * n);
    for (float& l : lattice) l = std::uniform_real_distribution<float>(-1, 1)(rng);
    const float amp = 40.0f / static_cast<float>(1 << octave);
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const int gx = x / cell, gy = y / cell;
        const float fx = static_cast<float>(x % cell) / cell, fy = static_cast<float>(y % cell) / cell;
        const float a = lattice[gy * n + gx], b = lattice[gy * n + gx + 1];
        const float c = lattice[(gy + 1) * n + gx], d = lattice[(gy + 1) * n + gx + 1];
        v[static_cast<std::size_t>(y) * kW + x] +=
            amp * ((a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy);
      }
  }
  std::normal_distribution<float> noise(0.0f, 2.0f);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      float& p = v[static_cast<std::size_t>(y) * kW + x];
      if ((x / 97 + y / 131) % 3 == 0) p += 18.0f;
      const double dx = (x - kW / 2) / 260.0, dy = (y - kH / 2 - 120) / 70.0;
      if (dx * dx + dy * dy < 1.0) p = 70.0f + 0.05f * static_cast<float>(x % 200);
      p += noise(rng);
    }
  return v;
}

bool in_boom(int x, int y) {
  return y <= kH * 3 / 4 && std::abs(x - (kW / 2 - 80 + y / 3)) < 35;
}

struct Frames {
  Image mono, rgb, mono_aug, mask;
  cv::Mat depth16;
};

Frames make_frames() {
  std::mt19937 rng(7);
  const std::vector<float> g = scene(rng), r = scene(rng), b = scene(rng);
  Frames f{Image(kW, kH, PixelFormat::kMono8), Image(kW, kH, PixelFormat::kRGB8),
           Image(kW, kH, PixelFormat::kMono8), Image(kW, kH, PixelFormat::kMono8),
           cv::Mat(kH, kW, CV_16UC1, cv::Scalar(0))};
  auto u8 = [](float v) { return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L)); };
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * kW + x;
      f.mono.row(y)[x] = u8(g[i]);
      f.rgb.row(y)[3 * x] = u8(0.6f * r[i] + 0.4f * g[i]);
      f.rgb.row(y)[3 * x + 1] = u8(g[i]);
      f.rgb.row(y)[3 * x + 2] = u8(0.6f * b[i] + 0.4f * g[i]);
      const double dx = (x - kW / 2) / 260.0, dy = (y - kH / 2 - 120) / 70.0;
      const bool receiver = dx * dx + dy * dy < 1.0;
      f.mono_aug.row(y)[x] = in_boom(x, y) ? static_cast<std::uint8_t>(150 + (x + y) % 7) : f.mono.row(y)[x];
      f.mask.row(y)[x] = static_cast<std::uint8_t>((in_boom(x, y) ? 1 : 0) | (receiver ? 2 : 0));
      // Receiver depth in mm, 0 elsewhere (render/ground_truth's 16-bit PNG).
      if (receiver) f.depth16.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(25000 + x - y / 2);
    }
  return f;
}

cv::Mat as_mat(const Image& im) {
  const int type = im.format() == PixelFormat::kRGB8 ? CV_8UC3 : CV_8UC1;
  cv::Mat m(im.height(), im.width(), type, const_cast<std::uint8_t*>(im.row(0)),
            static_cast<std::size_t>(im.row(1) - im.row(0)));
  if (type == CV_8UC3) {
    cv::Mat bgr;
    cv::cvtColor(m, bgr, cv::COLOR_RGB2BGR);
    return bgr;
  }
  return m.clone();
}

std::string own_png(PngEncoder& enc, const Image& im) {
  auto p = enc.encode(im);
  if (!p) std::abort();
  return png_file(*p);
}

std::string cv_png(const cv::Mat& m, int level, int strategy) {
  std::vector<std::uint8_t> buf;
  cv::imencode(".png", m, buf, {cv::IMWRITE_PNG_COMPRESSION, level, cv::IMWRITE_PNG_STRATEGY, strategy});
  return std::string(buf.begin(), buf.end());
}

// libpng directly: one filter, zlib's level and strategy, into memory.
std::string libpng_png(const Image& im, int filter, int level, int strategy) {
  std::string out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) std::abort();
  png_set_write_fn(
      png, &out,
      [](png_structp p, png_bytep d, png_size_t n) {
        static_cast<std::string*>(png_get_io_ptr(p))->append(reinterpret_cast<const char*>(d), n);
      },
      nullptr);
  const int colour = im.format() == PixelFormat::kRGB8 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY;
  png_set_IHDR(png, info, static_cast<png_uint_32>(im.width()), static_cast<png_uint_32>(im.height()), 8,
               colour, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, filter);
  png_set_compression_level(png, level);
  png_set_compression_strategy(png, strategy);
  png_write_info(png, info);
  for (int y = 0; y < im.height(); ++y) png_write_row(png, const_cast<std::uint8_t*>(im.row(y)));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

bool decodes_to(const std::string& file, const cv::Mat& pixels) {
  const cv::Mat d = cv::imdecode(std::vector<std::uint8_t>(file.begin(), file.end()), cv::IMREAD_UNCHANGED);
  return !d.empty() && d.size() == pixels.size() && d.type() == pixels.type() &&
         cv::norm(d, pixels, cv::NORM_INF) == 0;
}

struct Row {
  const char* image;
  const char* writer;
  std::size_t pixel_bytes;
  const cv::Mat* expect;
  std::function<std::string()> encode;
};

void run(const Row& row, int reps) {
  std::vector<double> ms;
  std::string file;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    file = row.encode();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  const double med = ms[ms.size() / 2];
  std::printf("| %s | %s | %.2f | %.0f | %.2f | %s |\n", row.image, row.writer, med,
              static_cast<double>(row.pixel_bytes) / 1e3 / med, static_cast<double>(file.size()) / 1e6,
              decodes_to(file, *row.expect) ? "yes" : "NO");
  std::fflush(stdout);
}

// The JPEG rows: ms per view (median), the file's size, the decoded image's PSNR against the
// BGR image encoded (a Bayer mosaic's after demosaicing: what compression loses, not demosaicing).
int jpeg_table(const Frames& f, int reps) {
  Image bayer(kW, kH, PixelFormat::kBayerRG8);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) bayer.row(y)[x] = f.rgb.row(y)[3 * x + bayer_channel(bayer.format(), x, y)];
  struct JpegRow {
    const char* image;
    const Image* im;
    int quality;
  };
  const JpegRow rows[] = {{"RGB8", &f.rgb, 80},   {"RGB8", &f.rgb, 90},   {"RGB8", &f.rgb, 60},
                          {"BayerRG8", &bayer, 80}, {"Mono8", &f.mono, 80}};
  std::printf("\nencode_jpeg (render/image_file), median of %d encodes into memory, one thread\n\n", reps);
  std::printf("| image | quality | ms / view | file MB | of raw | PSNR dB |\n|---|---:|---:|---:|---:|---:|\n");
  for (const JpegRow& r : rows) {
    std::vector<double> ms;
    std::vector<std::uint8_t> file;
    for (int i = 0; i < reps; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      auto e = encode_jpeg(r.im->cview(), r.quality);
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      if (!e) return 1;
      file = std::move(*e);
    }
    std::sort(ms.begin(), ms.end());
    const cv::Mat decoded = cv::imdecode(file, cv::IMREAD_UNCHANGED);
    std::printf("| %s | %d | %.2f | %.3f | %.1f %% | %.1f |\n", r.image, r.quality, ms[ms.size() / 2],
                static_cast<double>(file.size()) / 1e6,
                100.0 * static_cast<double>(file.size()) / static_cast<double>(r.im->size_bytes()),
                cv::PSNR(decoded, bgr_of(r.im->cview())));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int reps = 15;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--reps") == 0 && i + 1 < argc) {
      reps = std::max(1, std::atoi(argv[++i]));
    } else {
      std::fprintf(stderr, "usage: bench_png [--reps N]\n");
      return 2;
    }
  }
  cv::setNumThreads(1);
  const Frames f = make_frames();
  const cv::Mat mono = as_mat(f.mono), rgb = as_mat(f.rgb), aug = as_mat(f.mono_aug), mask = as_mat(f.mask);
  const std::size_t n1 = static_cast<std::size_t>(kW) * kH, n3 = 3 * n1;
  PngEncoder img0(0, PngKind::kImage), img1(1, PngKind::kImage), img6(6, PngKind::kImage);
  PngEncoder mask1(1, PngKind::kMask);
  const auto raw_png = img1.encode(f.mono);
  if (!raw_png) return 1;
  const int kDef = cv::IMWRITE_PNG_STRATEGY_DEFAULT, kHuff = cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY;
  const std::vector<Row> rows = {
      {"Mono8", "core/png, level 1", n1, &mono, [&] { return own_png(img1, f.mono); }},
      {"Mono8", "cv::imencode, level 1", n1, &mono, [&] { return cv_png(mono, 1, kDef); }},
      {"Mono8", "cv::imencode, level 1, Huffman-only", n1, &mono, [&] { return cv_png(mono, 1, kHuff); }},
      {"Mono8", "libpng, Sub, Huffman-only", n1, &mono,
       [&] { return libpng_png(f.mono, PNG_FILTER_SUB, 1, Z_HUFFMAN_ONLY); }},
      {"Mono8", "core/png, level 0 (stored)", n1, &mono, [&] { return own_png(img0, f.mono); }},
      {"Mono8", "cv::imencode, level 0", n1, &mono, [&] { return cv_png(mono, 0, kDef); }},
      {"Mono8", "core/png, level 6", n1, &mono, [&] { return own_png(img6, f.mono); }},
      {"Mono8", "cv::imencode, level 6", n1, &mono, [&] { return cv_png(mono, 6, kDef); }},
      {"Mono8 augmented", "core/png, level 1, raw's bands reused", n1, &aug,
       [&] {
         auto p = img1.encode(f.mono_aug, &*raw_png, &f.mono);
         return png_file(*p);
       }},
      {"Mono8 augmented", "cv::imencode, level 1", n1, &aug, [&] { return cv_png(aug, 1, kDef); }},
      {"RGB8", "core/png, level 1", n3, &rgb, [&] { return own_png(img1, f.rgb); }},
      {"RGB8", "cv::imencode, level 1", n3, &rgb, [&] { return cv_png(rgb, 1, kDef); }},
      {"RGB8", "cv::imencode, level 1, Huffman-only", n3, &rgb, [&] { return cv_png(rgb, 1, kHuff); }},
      {"RGB8", "libpng, Sub, Huffman-only", n3, &rgb,
       [&] { return libpng_png(f.rgb, PNG_FILTER_SUB, 1, Z_HUFFMAN_ONLY); }},
      {"mask (Mono8)", "core/png, level 1", n1, &mask, [&] { return own_png(mask1, f.mask); }},
      {"mask (Mono8)", "cv::imencode, level 1", n1, &mask, [&] { return cv_png(mask, 1, kDef); }},
      {"depth 16-bit", "cv::imencode, level 1 (no own path)", 2 * n1, &f.depth16,
       [&] { return cv_png(f.depth16, 1, kDef); }},
  };
  std::printf("%dx%d, median of %d encodes into memory, one thread\n\n", kW, kH, reps);
  std::printf(
      "| image | writer | ms / image | MB/s | file MB | decodes exactly |\n|---|---|---:|---:|---:|---|\n");
  for (const Row& r : rows) run(r, reps);
  return jpeg_table(f, reps);
}
