// bench_h264: what the live view's H.264 topics cost (issue 35 §1: both augmented views at
// 1280x960, 30 fps, within 8 Mbit/s together and within the live budget). Reads the first --frames
// pairs of a simulated flight (sim://demo with the boom in the scene, as augmented views show it;
// --source URI for another), then codes each camera's views as one stream through
// render/video_codec, as the live view does (a 4 Mbit/s cap per view, a keyframe every 30 frames),
// for each x264 preset asked for. Prints a Markdown table for docs/PERFORMANCE.md: ms per view
// (median, p99; conversion from RGB or Bayer included), the CPU share of 2 cores that both views at
// 30 fps take, Mbit/s of both views at 30 fps, keyframes, and the decoded views' PSNR; and JPEG
// quality 80 on the same views for comparison.
//   build/bench_h264 [--frames N] [--source URI] [--presets a,b,...] [--kbps K] [--crf N]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "pipeline/sources.hpp"
#include "render/cv_image.hpp"
#include "render/image_file.hpp"
#include "render/video_codec.hpp"

using namespace augrig;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  int frames = 150;
  std::string source = "sim://demo?rate=0&boom=physical";
  std::vector<std::string> presets = {"ultrafast", "superfast", "veryfast"};
  int kbps = 4000, crf = 23;
};

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

// The decoded picture against what was coded (a Bayer view's demosaiced colours), in BGR.
double psnr_of(const Image& decoded, const Image& coded) {
  cv::Mat d = decoded.format() == PixelFormat::kMono8 ? cv_view(decoded.cview()) : cv::Mat();
  if (d.empty()) cv::cvtColor(cv_view(decoded.cview()), d, cv::COLOR_RGB2BGR);
  cv::Mat c = bgr_of(coded.cview());
  if (d.channels() == 1 && c.channels() == 3) cv::cvtColor(c, c, cv::COLOR_BGR2GRAY);
  return cv::PSNR(d, c);
}

// Both cameras' views of the first n pairs.
Expected<std::vector<std::array<Image, 2>>> read_views(const Options& o) {
  auto opened = pipeline::open_sources(o.source);
  if (!opened) return opened.error();
  auto stereo = pipeline::start_stereo(std::move(*opened));
  if (!stereo) return stereo.error();
  std::vector<std::array<Image, 2>> views;
  while (static_cast<int>(views.size()) < o.frames) {
    StereoFrame f;
    auto st = (*stereo)->read(f, std::chrono::seconds(30));
    if (!st) return st.error();
    if (*st == ReadStatus::kEndOfStream) break;
    if (*st != ReadStatus::kFrame) continue;
    views.push_back({Image::copy_of(f.left.image.cview()), Image::copy_of(f.right.image.cview())});
    if (views.size() % 30 == 0) std::fprintf(stderr, "read %zu of %d pairs\n", views.size(), o.frames);
  }
  if (views.empty()) return make_error("bench_h264: ", o.source, ": no pairs");
  return views;
}

int h264_row(const std::vector<std::array<Image, 2>>& views, const Options& o, const std::string& preset) {
  H264Options ho;
  ho.preset = preset;
  ho.max_kbps = o.kbps;
  ho.crf = o.crf;
  std::vector<double> ms, psnr;
  std::size_t bytes = 0, keys = 0;
  for (int c = 0; c < 2; ++c) {
    const Image& first = views[0][static_cast<std::size_t>(c)];
    auto enc = H264Encoder::create(first.width(), first.height(), ho);
    auto dec = H264Decoder::create();
    if (!enc || !dec) {
      std::fprintf(stderr, "%s\n", (enc ? dec.error() : enc.error()).message.c_str());
      return 1;
    }
    for (std::size_t i = 0; i < views.size(); ++i) {
      const Image& im = views[i][static_cast<std::size_t>(c)];
      const auto t0 = Clock::now();
      auto unit = (*enc)->encode(im.cview(), static_cast<TimestampNs>(i) * 33'333'333);
      ms.push_back(ms_since(t0));
      if (!unit) return std::fprintf(stderr, "%s\n", unit.error().message.c_str()), 1;
      bytes += unit->data.size();
      keys += unit->keyframe ? 1 : 0;
      auto pic = (*dec)->decode(unit->data.data(), unit->data.size(), im.width(), im.height());
      if (!pic) return std::fprintf(stderr, "%s\n", pic.error().message.c_str()), 1;
      psnr.push_back(psnr_of(*pic, im));
    }
  }
  const double seconds = static_cast<double>(views.size()) / 30.0;
  const double median = percentile(ms, 0.5);
  double mean_ms = 0, mean_psnr = 0;
  for (double m : ms) mean_ms += m / static_cast<double>(ms.size());
  for (double p : psnr) mean_psnr += p / static_cast<double>(psnr.size());
  std::printf("| H.264 %s, crf %d, cap %d kbit/s a view | %.2f | %.2f | %.0f %% | %.2f | %zu | %.1f |\n",
              preset.c_str(), o.crf, o.kbps, median, percentile(ms, 0.99),
              100.0 * mean_ms * 2 * 30 / 1000.0 / 2.0, static_cast<double>(bytes) * 8 / seconds / 1e6, keys,
              mean_psnr);
  return 0;
}

void jpeg_row(const std::vector<std::array<Image, 2>>& views) {
  std::vector<double> ms, psnr;
  std::size_t bytes = 0;
  for (const auto& pair : views)
    for (const Image& im : pair) {
      const auto t0 = Clock::now();
      auto jpeg = encode_jpeg(im.cview(), 80);
      ms.push_back(ms_since(t0));
      if (!jpeg) continue;
      bytes += jpeg->size();
      const cv::Mat d = cv::imdecode(*jpeg, cv::IMREAD_UNCHANGED);
      psnr.push_back(cv::PSNR(d, d.channels() == 1 ? cv_view(im.cview()) : bgr_of(im.cview())));
    }
  double mean_ms = 0, mean_psnr = 0;
  for (double m : ms) mean_ms += m / static_cast<double>(ms.size());
  for (double p : psnr) mean_psnr += p / static_cast<double>(psnr.size());
  const double seconds = static_cast<double>(views.size()) / 30.0;
  std::printf("| JPEG quality 80 | %.2f | %.2f | %.0f %% | %.2f | all | %.1f |\n", percentile(ms, 0.5),
              percentile(ms, 0.99), 100.0 * mean_ms * 2 * 30 / 1000.0 / 2.0,
              static_cast<double>(bytes) * 8 / seconds / 1e6, mean_psnr);
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool more = i + 1 < argc;
    if (a == "--frames" && more) {
      o.frames = std::max(2, std::atoi(argv[++i]));
    } else if (a == "--source" && more) {
      o.source = argv[++i];
    } else if (a == "--presets" && more) {
      o.presets.clear();
      std::istringstream in(argv[++i]);
      for (std::string p; std::getline(in, p, ',');) o.presets.push_back(p);
    } else if (a == "--kbps" && more) {
      o.kbps = std::max(0, std::atoi(argv[++i]));
    } else if (a == "--crf" && more) {
      o.crf = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: bench_h264 [--frames N] [--source URI] [--presets a,b] [--kbps K] [--crf N]\n");
      return 2;
    }
  }
  cv::setNumThreads(1);
  auto views = read_views(o);
  if (!views) return std::fprintf(stderr, "%s\n", views.error().message.c_str()), 1;
  const Image& v = (*views)[0][0];
  std::printf("%zu pairs of %s, %dx%d %s, one thread, a view at a time\n\n", views->size(), o.source.c_str(),
              v.width(), v.height(), std::string(to_string(v.format())).c_str());
  std::printf(
      "| coding | ms / view (median) | p99 | CPU of 2 cores, both views at 30 fps | Mbit/s, both at 30 fps "
      "| keyframes | PSNR dB |\n|---|---:|---:|---:|---:|---:|---:|\n");
  for (const std::string& p : o.presets)
    if (int rc = h264_row(*views, o, p); rc) return rc;
  jpeg_row(*views);
  return 0;
}
