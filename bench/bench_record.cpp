// bench_record: how fast the Recorder (recorder/recorder.hpp) stores stereo frames losslessly —
// raw, augmented and masks of both cameras — against the naive baseline of writing every image as
// a PNG with cv::imwrite. Prints the figures for docs/RECORDING.md.
//   build/bench_record [--frames N] [--png-frames M] [--noise SIGMA] [--out DIR] [--keep]
// The frames: 1280x960 BayerRG8 per camera from a procedural scene (sky gradient, a horizon,
// textured ground that moves from frame to frame, a receiver-like shape with hard edges, the right
// camera offset by a stereo disparity) with Gaussian sensor noise (sigma 2 DN by default), mosaicked
// RGGB; the augmented image is the raw one with a diagonal boom band painted in (about 5 % of the
// pixels); the masks are zero except the boom and receiver regions. All frames are made before
// the clock starts, and each is moved into push() as a live pipeline would hand it over; the
// producer waits while the recorder's queue is full, so nothing is dropped and the figure is the
// recorder's sustained throughput, from the first push until the last frame is committed, and
// with the one-time close() (final checkpoint and fsync) added. Each run starts after sync(), with
// every image buffer its own mapping, so that the runs of one invocation are comparable.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <malloc.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sys/resource.h>
#include <unistd.h>

#include "core/clock.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"

using namespace augrig;
using namespace augrig::recorder;
namespace fs = std::filesystem;

namespace {

constexpr int kW = 1280, kH = 960;

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// The system (kernel) part of the process's CPU time (core/clock.hpp's process_cpu_ms()), ms.
double process_sys_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_stime.tv_sec) * 1e3 + static_cast<double>(u.ru_stime.tv_usec) * 1e-3;
}

// Smooth value noise on a lattice, several octaves: fields and clouds on the ground.
struct Ground {
  static constexpr int kSize = 2048;
  std::vector<float> tex;
  Ground() : tex(static_cast<std::size_t>(kSize) * kSize) {
    std::mt19937 rng(7);
    for (int octave = 0; octave < 5; ++octave) {
      const int cell = 256 >> octave;
      const int n = kSize / cell + 1;
      std::vector<float> lattice(static_cast<std::size_t>(n) * n);
      for (float& v : lattice) v = std::uniform_real_distribution<float>(-1, 1)(rng);
      const float amp = 40.0f / static_cast<float>(1 << octave);
      for (int y = 0; y < kSize; ++y) {
        const int gy = y / cell;
        const float fy = static_cast<float>(y % cell) / cell;
        for (int x = 0; x < kSize; ++x) {
          const int gx = x / cell;
          const float fx = static_cast<float>(x % cell) / cell;
          const float a = lattice[gy * n + gx], b = lattice[gy * n + gx + 1];
          const float c = lattice[(gy + 1) * n + gx], d = lattice[(gy + 1) * n + gx + 1];
          tex[static_cast<std::size_t>(y) * kSize + x] +=
              amp * ((a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy);
        }
      }
    }
    // Field boundaries: hard edges every 97 texels.
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x)
        if ((x / 97 + y / 131) % 3 == 0) tex[static_cast<std::size_t>(y) * kSize + x] += 18.0f;
  }
  float at(int x, int y) const {
    return tex[static_cast<std::size_t>(y & (kSize - 1)) * kSize + (x & (kSize - 1))];
  }
};

// Gaussian noise, drawn once and read from a random offset per image.
struct NoiseTable {
  std::vector<float> v;
  explicit NoiseTable(double sigma) : v(1 << 22) {
    std::mt19937 rng(11);
    std::normal_distribution<float> n(0.0f, static_cast<float>(sigma));
    for (float& x : v) x = n(rng);
  }
};

bool in_receiver(int x, int y, int cx, int cy) {
  const double dx = (x - cx) / 260.0, dy = (y - cy) / 70.0;
  const bool fuselage = dx * dx + dy * dy < 1.0;
  const bool wing = std::abs(y - cy - 10) < 14 && std::abs(x - cx) < 420 - std::abs(y - cy) * 4;
  return fuselage || wing;
}

bool in_boom(int x, int y) {
  // A band from the top centre down and to the right, 70 px wide: about 5 % of the image.
  if (y > kH * 3 / 4) return false;
  const int centre = kW / 2 - 80 + y / 3;
  return std::abs(x - centre) < 35;
}

Image render_raw(const Ground& g, const NoiseTable& noise, std::mt19937& rng, int frame, int camera) {
  Image img(kW, kH, PixelFormat::kBayerRG8);
  const int disparity = camera == 0 ? 0 : 24;
  const int shift_x = frame * 3, shift_y = frame * 5;  // the ground moves under the tanker
  const std::size_t off = std::uniform_int_distribution<std::size_t>(0, noise.v.size() - kW * kH - 1)(rng);
  const float* nz = noise.v.data() + off;
  const int cx = kW / 2 + 40 - disparity + (frame % 40) - 20, cy = kH / 2 + 120;
  for (int y = 0; y < kH; ++y) {
    std::uint8_t* row = img.row(y);
    for (int x = 0; x < kW; ++x) {
      const int ch = bayer_channel(PixelFormat::kBayerRG8, x, y);
      const int h = 300 + (x - kW / 2) / 12;  // a slightly tilted horizon
      float v;
      if (in_receiver(x, y, cx, cy)) {
        v = 150.0f + 0.05f * static_cast<float>(x - cx) + (ch == 2 ? 10.0f : 0.0f) -
            (y > cy + 30 ? 35.0f : 0.0f);
      } else if (y < h) {
        // Sky: brighter towards the horizon, blue.
        const float t = static_cast<float>(y) / static_cast<float>(std::max(h, 1));
        v = ch == 2 ? 170.0f + 40.0f * t : ch == 1 ? 120.0f + 50.0f * t : 80.0f + 60.0f * t;
      } else {
        const float base = ch == 1 ? 95.0f : ch == 0 ? 85.0f : 70.0f;
        v = base + g.at(x + shift_x - disparity, (y - h) * 2 + shift_y);
      }
      v += nz[static_cast<std::size_t>(y) * kW + x];
      row[x] = static_cast<std::uint8_t>(std::clamp(v, 0.0f, 255.0f));
    }
  }
  return img;
}

FrameRecord make_frame(const Ground& g, const NoiseTable& noise, std::mt19937& rng, int i) {
  FrameRecord f;
  f.raw.pair_sequence = static_cast<std::uint64_t>(i);
  f.raw.t_key_ns = 1'000'000'000LL + i * 33'333'333LL;
  f.raw.left.t_ns = f.raw.right.t_ns = f.raw.t_key_ns;
  f.raw.left.clock = f.raw.right.clock = ClockDomain::kDevice;
  f.raw.right.camera = CameraId::kRight;
  for (int c = 0; c < 2; ++c) {
    Frame& fr = f.raw[static_cast<CameraId>(c)];
    fr.sequence = static_cast<std::uint64_t>(i);
    fr.image = render_raw(g, noise, rng, i, c);
    Image aug = fr.image;
    Image mask(kW, kH, PixelFormat::kMono8);
    const int disparity = c == 0 ? 0 : 24;
    const int cx = kW / 2 + 40 - disparity + (i % 40) - 20, cy = kH / 2 + 120;
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) {
        std::uint8_t m = in_receiver(x, y, cx, cy) ? kMaskReceiver : 0;
        if (in_boom(x + disparity, y)) {
          m |= kMaskBoom;
          const int ch = bayer_channel(PixelFormat::kBayerRG8, x, y);
          aug.row(y)[x] = static_cast<std::uint8_t>(120 + 20 * ch + (x % 64) / 4);
        }
        mask.row(y)[x] = m;
      }
    }
    f.augmented[c] = std::move(aug);
    f.mask[c] = std::move(mask);
  }
  f.T_cam_receiver[0] = f.T_cam_receiver[1] = pose_from_ypr({0.2, 6.0, 20.0}, 0.0, 0.1, 0.0);
  f.T_body_receiver = pose_from_ypr({-20.0, 0.0, 8.0}, 0.0, 0.0, 0.0);
  f.boom = BoomArticulation{0.5, 0.0, 3.0};
  f.stats = OcclusionStats{};
  return f;
}

std::uint64_t dir_bytes(const std::string& dir) {
  std::uint64_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) n += e.file_size();
  return n;
}

struct Row {
  std::string name;
  double fps = 0, ms_per_frame = 0, ratio = 0, fps_with_close = 0, cpu_ms = 0, sys_ms = 0;
  double encode_ms = -1, insert_ms = -1, commit_ms = -1, checkpoint_ms = -1, close_ms = -1;
};

Row run_recorder(const std::string& name, const std::vector<FrameRecord>& pool, int frames,
                 const std::string& out, int level, int threads, bool keep) {
  const std::string dir = out + "/rec-" + std::to_string(level) + "-" + std::to_string(threads);
  fs::remove_all(dir);
  // Copies made before the clock starts, so that the timed loop only moves frames in.
  std::vector<FrameRecord> items;
  items.reserve(static_cast<std::size_t>(frames));
  for (int i = 0; i < frames; ++i) {
    items.push_back(pool[static_cast<std::size_t>(i) % pool.size()]);
    items.back().raw.pair_sequence = static_cast<std::uint64_t>(i);
  }
  // Start every run with no dirty pages left from the one before (its writeback would be billed here).
  ::sync();
  RecorderOptions opt;
  opt.zstd_level = level;
  opt.compression_threads = threads;
  RecordingInfo info;
  info.extra["bench"] = "bench_record";
  auto rec = Recorder::create(dir, info, opt);
  if (!rec) {
    std::fprintf(stderr, "%s\n", rec.error().message.c_str());
    std::exit(1);
  }
  const auto t0 = Clock::now();
  const double cpu0 = process_cpu_ms(), sys0 = process_sys_ms();
  for (int i = 0; i < frames; ++i) {
    while ((*rec)->stats().frames_in_flight >= opt.queue_capacity)
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    if (!(*rec)->push(std::move(items[static_cast<std::size_t>(i)]))) {
      std::fprintf(stderr, "bench_record: frame %d dropped: %s\n", i,
                   (*rec)->status() ? "queue full" : (*rec)->status().error().message.c_str());
      std::exit(1);
    }
  }
  // Sustained: until the last frame is committed. Then the one-time close (flush, summary, final
  // checkpoint with its fsync).
  while ((*rec)->stats().frames_committed < static_cast<std::uint64_t>(frames) && (*rec)->status())
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  const double sustained_ms = ms_since(t0);
  const auto t_close = Clock::now();
  if (auto st = (*rec)->close(); !st) {
    std::fprintf(stderr, "%s\n", st.error().message.c_str());
    std::exit(1);
  }
  const double close_ms = ms_since(t_close);
  const double total_ms = ms_since(t0);
  const double cpu_ms = process_cpu_ms() - cpu0, sys_ms = process_sys_ms() - sys0;
  const RecorderStats s = (*rec)->stats();
  Row r;
  r.name = name;
  r.fps = frames / (sustained_ms / 1000.0);
  r.ms_per_frame = sustained_ms / frames;
  r.fps_with_close = frames / (total_ms / 1000.0);
  r.cpu_ms = cpu_ms / frames;
  r.sys_ms = sys_ms / frames;
  r.ratio = static_cast<double>(s.image_bytes) / static_cast<double>(dir_bytes(dir));
  r.encode_ms = s.encode_ms / frames;
  r.insert_ms = s.insert_ms / frames;
  r.commit_ms = s.commit_ms / frames;
  r.checkpoint_ms = s.checkpoint_ms / frames;
  r.close_ms = close_ms;
  // The recording must read back and check clean (not timed).
  auto rd = RecordingReader::open(dir);
  if (!rd || (*rd)->frame_count() != static_cast<std::size_t>(frames)) {
    std::fprintf(stderr, "bench_record: %s does not read back\n", dir.c_str());
    std::exit(1);
  }
  auto f = (*rd)->read_frame(static_cast<std::size_t>(frames - 1));
  const FrameRecord& want = pool[static_cast<std::size_t>(frames - 1) % pool.size()];
  if (!f || !pixels_equal(f->raw.left.image, want.raw.left.image) ||
      !pixels_equal(f->augmented[1], want.augmented[1]) || !pixels_equal(f->mask[0], want.mask[0])) {
    std::fprintf(stderr, "bench_record: %s: the last frame does not read back bit-exact\n", dir.c_str());
    std::exit(1);
  }
  if (!keep) fs::remove_all(dir);
  return r;
}

Row run_png(const std::vector<FrameRecord>& pool, int frames, const std::string& out, bool keep) {
  const std::string dir = out + "/png";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ::sync();
  std::uint64_t image_bytes = 0;
  const auto t0 = Clock::now();
  const double cpu0 = process_cpu_ms(), sys0 = process_sys_ms();
  char name[512];
  for (int i = 0; i < frames; ++i) {
    const FrameRecord& f = pool[static_cast<std::size_t>(i) % pool.size()];
    for (int c = 0; c < 2; ++c) {
      const char* cam = c == 0 ? "left" : "right";
      const Image* images[3] = {&f.raw[static_cast<CameraId>(c)].image, &f.augmented[c], &f.mask[c]};
      const char* kinds[3] = {"raw", "augmented", "mask"};
      for (int k = 0; k < 3; ++k) {
        const Image& img = *images[k];
        const cv::Mat m(img.height(), img.width(), CV_8UC1, const_cast<std::uint8_t*>(img.data()),
                        img.stride_bytes());
        std::snprintf(name, sizeof name, "%s/%06d_%s_%s.png", dir.c_str(), i, cam, kinds[k]);
        if (!cv::imwrite(name, m)) {
          std::fprintf(stderr, "bench_record: cv::imwrite(%s) failed\n", name);
          std::exit(1);
        }
        image_bytes += img.size_bytes();
      }
    }
  }
  const double total_ms = ms_since(t0);
  Row r;
  r.name = "PNG baseline (cv::imwrite, 6 files per frame)";
  r.fps = r.fps_with_close = frames / (total_ms / 1000.0);
  r.ms_per_frame = total_ms / frames;
  r.cpu_ms = (process_cpu_ms() - cpu0) / frames;
  r.sys_ms = (process_sys_ms() - sys0) / frames;
  r.ratio = static_cast<double>(image_bytes) / static_cast<double>(dir_bytes(dir));
  if (!keep) fs::remove_all(dir);
  return r;
}

void print_row(const Row& r, double png_fps) {
  auto cell = [](double v) {
    static char buf[8][32];
    static int k = 0;
    char* b = buf[k++ % 8];
    if (v < 0)
      std::snprintf(b, 32, "—");
    else
      std::snprintf(b, 32, "%.2f", v);
    return b;
  };
  std::printf(
      "| %-46s | %7.1f | %6.2f | %5.1fx | %7.1f | %6.2f (%.2f) | %5.2f | %6s | %6s | %6s | %6s | %7s |\n",
      r.name.c_str(), r.fps, r.ms_per_frame, r.fps / png_fps, r.fps_with_close, r.cpu_ms, r.sys_ms, r.ratio,
      cell(r.encode_ms), cell(r.insert_ms), cell(r.commit_ms), cell(r.checkpoint_ms), cell(r.close_ms));
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 300, png_frames = 20;
  double noise = 2.0;
  std::string out = "bench_record_out";
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--frames") == 0 && i + 1 < argc)
      frames = std::max(1, std::atoi(argv[++i]));
    else if (std::strcmp(argv[i], "--png-frames") == 0 && i + 1 < argc)
      png_frames = std::max(1, std::atoi(argv[++i]));
    else if (std::strcmp(argv[i], "--noise") == 0 && i + 1 < argc)
      noise = std::atof(argv[++i]);
    else if (std::strcmp(argv[i], "--out") == 0 && i + 1 < argc)
      out = argv[++i];
    else if (std::strcmp(argv[i], "--keep") == 0)
      keep = true;
    else {
      std::fprintf(
          stderr, "usage: bench_record [--frames N] [--png-frames M] [--noise SIGMA] [--out DIR] [--keep]\n");
      return 2;
    }
  }
  fs::create_directories(out);
  // Every image buffer its own mapping, in every run: glibc's adaptive threshold would otherwise
  // serve later runs from the heap after the first run freed mapped images, and the runs would
  // not be comparable.
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
  const auto tg = Clock::now();
  const Ground ground;
  const NoiseTable table(noise);
  std::mt19937 rng(1);
  std::vector<FrameRecord> pool;
  for (int i = 0; i < 16; ++i) pool.push_back(make_frame(ground, table, rng, i));
  std::fprintf(stderr, "bench_record: 16 distinct synthetic stereo frames made in %.1f s\n",
               ms_since(tg) / 1000.0);

  std::printf(
      "bench_record: 1280x960 BayerRG8 stereo, raw + augmented + masks per camera (7.4 MB per stereo frame), "
      "sensor noise sigma %.1f DN; %d frames per recorder run, %d for PNG; %u hardware threads\n\n",
      noise, frames, png_frames, std::thread::hardware_concurrency());
  {
    double load[3] = {0, 0, 0};
    if (getloadavg(load, 3) == 3)
      std::printf("load average before the runs: %.2f %.2f %.2f\n\n", load[0], load[1], load[2]);
  }
  const Row png = run_png(pool, png_frames, out, keep);
  std::vector<Row> rows;
  rows.push_back(run_recorder("Recorder, zstd 1, 2 compression threads", pool, frames, out, 1, 2, keep));
  rows.push_back(run_recorder("Recorder, zstd 1, 1 compression thread", pool, frames, out, 1, 1, keep));
  rows.push_back(run_recorder("Recorder, zstd 3, 2 compression threads", pool, frames, out, 3, 2, keep));
  std::printf(
      "| pipeline                                       | stereo fps | ms / frame | vs PNG | fps incl. close "
      "| "
      "CPU ms / frame (system) | compression | encode ms | insert ms | commit ms | checkpoint ms | close ms "
      "|\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const Row& r : rows) print_row(r, png.fps);
  print_row(png, png.fps);
  std::printf(
      "\nstereo fps and ms / frame: wall time from the first push until the last frame is committed "
      "(sustained "
      "throughput); fps incl. close adds the one-time close (final flush, summary, checkpoint and fsync). "
      "CPU ms / frame: user + system time of the whole process over the run (every thread, the kernel's "
      "file writes included) per stereo frame, its system part in brackets; on two idle cores the ceiling is "
      "2000 / this. "
      "encode and insert: CPU time per stereo frame (encode summed over the compression threads); commit and "
      "checkpoint: wall time per stereo frame (checkpoints mostly on their own thread, fsync included); they "
      "overlap. compression: image bytes over bytes on disk.\n");
  return 0;
}
