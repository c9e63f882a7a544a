// bench_export: how fast `augrig export DIR --format euroc OUT` (recorder::export_euroc) turns a
// recording into a EuRoC/ASL folder. Prints the figures for docs/PERFORMANCE.md.
//   build/bench_export [--frames N] [--out DIR] [--threads LIST] [--keep]
// The recording: 1280x960 BayerRG8 stereo frames as bench/bench_record makes them (a procedural
// scene with Gaussian sensor noise of sigma 2 DN), each with its augmented images (a boom band,
// about 5 % of the pixels, stored as the changed box as a live run stores it) and masks (boom and
// receiver regions), poses and statistics, plus 200 Hz IMU datagrams as `augrig run --nav` stores
// them. Eight distinct frames are rendered and recorded in turn with increasing timestamps. The
// recording is written once; each configuration then exports it into a fresh folder after
// sync(), without the plot (gnuplot is a one-time cost of its own). Reported per configuration:
// stereo frames per second (wall), CPU ms per stereo frame (user + system of the whole process,
// every thread), and the ratio to the first row of the same run: the previous export's way, each
// frame decoded whole and its six images written by OpenCV (cv::imwrite, PNG compression 1) on one
// thread, with the CSV and YAML files left out (they cost nothing beside the images).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>
#include <thread>
#include <string>
#include <vector>

#include <unistd.h>

#include "core/clock.hpp"
#include "nav/imu_stream.hpp"
#include "recorder/euroc.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "render/image_file.hpp"

using namespace augrig;
using namespace augrig::recorder;
namespace fs = std::filesystem;

namespace {

constexpr int kW = 1280, kH = 960;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Smooth value noise on a lattice (fields on the ground), as bench_record's.
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
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x)
        if ((x / 97 + y / 131) % 3 == 0) tex[static_cast<std::size_t>(y) * kSize + x] += 18.0f;
  }
  float at(int x, int y) const { return tex[static_cast<std::size_t>(y & (kSize - 1)) * kSize + (x & (kSize - 1))]; }
};

bool in_receiver(int x, int y, int cx, int cy) {
  const double dx = (x - cx) / 260.0, dy = (y - cy) / 70.0;
  return dx * dx + dy * dy < 1.0 || (std::abs(y - cy - 10) < 14 && std::abs(x - cx) < 420 - std::abs(y - cy) * 4);
}

bool in_boom(int x, int y) {
  if (y > kH * 3 / 4) return false;
  return std::abs(x - (kW / 2 - 80 + y / 3)) < 35;
}

Image render_raw(const Ground& g, std::mt19937& rng, int frame, int camera) {
  Image img(kW, kH, PixelFormat::kBayerRG8);
  std::normal_distribution<float> noise(0.0f, 2.0f);
  const int disparity = camera == 0 ? 0 : 24;
  const int shift_x = frame * 3, shift_y = frame * 5;
  const int cx = kW / 2 + 40 - disparity + (frame % 40) - 20, cy = kH / 2 + 120;
  for (int y = 0; y < kH; ++y) {
    std::uint8_t* row = img.row(y);
    for (int x = 0; x < kW; ++x) {
      const int ch = bayer_channel(PixelFormat::kBayerRG8, x, y);
      const int h = 300 + (x - kW / 2) / 12;
      float v;
      if (in_receiver(x, y, cx, cy)) {
        v = 150.0f + 0.05f * static_cast<float>(x - cx) + (ch == 2 ? 10.0f : 0.0f) - (y > cy + 30 ? 35.0f : 0.0f);
      } else if (y < h) {
        const float t = static_cast<float>(y) / static_cast<float>(std::max(h, 1));
        v = ch == 2 ? 170.0f + 40.0f * t : ch == 1 ? 120.0f + 50.0f * t : 80.0f + 60.0f * t;
      } else {
        v = (ch == 1 ? 95.0f : ch == 0 ? 85.0f : 70.0f) + g.at(x + shift_x - disparity, (y - h) * 2 + shift_y);
      }
      row[x] = static_cast<std::uint8_t>(std::clamp(v + noise(rng), 0.0f, 255.0f));
    }
  }
  return img;
}

FrameRecord make_frame(const Ground& g, std::mt19937& rng, int i) {
  FrameRecord f;
  f.raw.right.camera = CameraId::kRight;
  for (int c = 0; c < 2; ++c) {
    Frame& fr = f.raw[static_cast<CameraId>(c)];
    fr.clock = ClockDomain::kDevice;
    fr.image = render_raw(g, rng, i, c);
    Image mask(kW, kH, PixelFormat::kMono8);
    const int disparity = c == 0 ? 0 : 24;
    const int cx = kW / 2 + 40 - disparity + (i % 40) - 20, cy = kH / 2 + 120;
    int x0 = kW, y0 = kH, x1 = 0, y1 = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        std::uint8_t m = in_receiver(x, y, cx, cy) ? kMaskReceiver : 0;
        if (in_boom(x + disparity, y)) {
          m |= kMaskBoom;
          x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x + 1), y1 = std::max(y1, y + 1);
        }
        mask.row(y)[x] = m;
      }
    // The augmented image as the augmenter hands it over: only the changed box.
    Image box(x1 - x0, y1 - y0, PixelFormat::kBayerRG8);
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        const int ch = bayer_channel(PixelFormat::kBayerRG8, x, y);
        box.row(y - y0)[x - x0] = in_boom(x + disparity, y) ? static_cast<std::uint8_t>(120 + 20 * ch + (x % 64) / 4)
                                                            : fr.image.row(y)[x];
      }
    f.augmented[c] = std::move(box);
    f.augmented_box[c] = PixelBox{x0, y0, x1, y1};
    f.mask[c] = std::move(mask);
    f.T_cam_receiver[c] = pose_from_ypr({0.2, 6.0, 20.0}, 0.0, 0.1, 0.0);
  }
  f.T_body_receiver = pose_from_ypr({-20.0, 0.0, 8.0}, 0.0, 0.0, 0.0);
  f.boom = BoomArticulation{0.5, 0.0, 3.0};
  f.stats = OcclusionStats{};
  return f;
}

std::string make_recording(const std::string& dir, int frames) {
  fs::remove_all(dir);
  RecordingInfo info;
  info.rig_yaml = rig_to_yaml(Rig::paper_default());
  info.extra["bench"] = "bench_export";
  auto rec = Recorder::create(dir, info);
  if (!rec) {
    std::fprintf(stderr, "%s\n", rec.error().message.c_str());
    std::exit(1);
  }
  const Ground g;
  std::mt19937 rng(3);
  std::vector<FrameRecord> pool;
  for (int i = 0; i < 8; ++i) pool.push_back(make_frame(g, rng, i));
  constexpr TimestampNs kT0 = 1'400'000'000'000'000'000, kPeriod = 33'333'333;
  // 200 Hz IMU increments in datagrams of 4, as `augrig run --nav sim` receives and stores them.
  const int imu_samples = static_cast<int>(static_cast<double>(frames) * 200.0 / 30.0) + 8;
  for (int k = 0; k + 4 <= imu_samples; k += 4) {
    std::vector<nav::ImuSample> s(4);
    for (int j = 0; j < 4; ++j) {
      s[j].t_ns = kT0 + (k + j) * 5'000'000LL;
      s[j].dt_s = 0.005;
      s[j].dtheta_rad = Eigen::Vector3d(1e-5, 2e-5 * j, -1e-5);
      s[j].dv_mps = Eigen::Vector3d(0.01, 0.0, -0.049);
    }
    auto d = nav::encode_imu_datagram(s, static_cast<std::uint64_t>(k));
    NavInputRecord r;
    r.stream = "tanker.imu";
    r.clock = ClockDomain::kUnknown;
    r.arrival_ns = 1'000'000'000LL + (k + 3) * 5'000'000LL;
    r.data.assign(reinterpret_cast<const char*>(d->data()), d->size());
    r.binary = true;
    (*rec)->push(std::move(r));
  }
  for (int i = 0; i < frames; ++i) {
    FrameRecord f = pool[static_cast<std::size_t>(i) % pool.size()];
    f.raw.pair_sequence = static_cast<std::uint64_t>(i);
    f.raw.t_key_ns = kT0 + i * kPeriod;
    for (int c = 0; c < 2; ++c) {
      Frame& fr = f.raw[static_cast<CameraId>(c)];
      fr.t_ns = f.raw.t_key_ns;
      fr.sequence = static_cast<std::uint64_t>(i);
    }
    while (!(*rec)->push(f)) {  // a full queue: wait, the recording must hold every frame
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  if (auto s = (*rec)->close(); !s) {
    std::fprintf(stderr, "%s\n", s.error().message.c_str());
    std::exit(1);
  }
  return dir;
}

std::uint64_t dir_bytes(const std::string& dir) {
  std::uint64_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) n += e.file_size();
  return n;
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 120;
  std::string out = "/tmp/augrig-bench-export";
  std::string threads_list = "1,2";
  std::string levels_list = "";
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--frames")
      frames = std::max(1, std::atoi(value().c_str()));
    else if (a == "--out")
      out = value();
    else if (a == "--threads")
      threads_list = value();
    else if (a == "--keep")
      keep = true;
    else {
      std::fprintf(stderr,
                   "usage: bench_export [--frames N] [--out DIR] [--threads 1,2] [--keep]\n");
      return 2;
    }
  }
  fs::create_directories(out);
  const auto tr = Clock::now();
  const std::string rec_dir = make_recording(out + "/recording", frames);
  std::printf("recording: %d stereo frames 1280x960 BayerRG8 with augmented boxes, masks, IMU datagrams; %.1f MB, made in %.1f s\n",
              frames, static_cast<double>(dir_bytes(rec_dir)) / 1e6, ms_since(tr) / 1e3);
  auto reader = RecordingReader::open(rec_dir);
  if (!reader) {
    std::fprintf(stderr, "%s\n", reader.error().message.c_str());
    return 1;
  }
  std::vector<int> threads;
  {
    std::stringstream ss(threads_list);
    std::string item;
    while (std::getline(ss, item, ',')) threads.push_back(std::atoi(item.c_str()));
  }
  std::printf("| configuration | stereo fps | ms / frame (wall) | CPU ms / frame | vs first | output MB |\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  double first_fps = 0;
  {
    // The previous export's images: OpenCV's PNG writer, whole images, one thread.
    const std::string dir = out + "/export-opencv";
    fs::remove_all(dir);
    fs::create_directories(dir);
    ::sync();
    const double cpu0 = process_cpu_ms();
    const auto t0 = Clock::now();
    const std::size_t n = (*reader)->frame_count();
    for (std::size_t i = 0; i < n; ++i) {
      auto rec = (*reader)->read_frame(i, kPartsAll);
      if (!rec) {
        std::fprintf(stderr, "%s\n", rec.error().message.c_str());
        return 1;
      }
      for (int c = 0; c < 2; ++c) {
        const Image* images[3] = {&rec->raw[static_cast<CameraId>(c)].image, &rec->augmented[c], &rec->mask[c]};
        for (int k = 0; k < 3; ++k)
          if (auto st = write_png_file(dir + "/" + std::to_string(i) + "_" + std::to_string(c) + "_" +
                                           std::to_string(k) + ".png",
                                       *images[k], 1);
              !st) {
            std::fprintf(stderr, "%s\n", st.error().message.c_str());
            return 1;
          }
      }
    }
    const double wall = ms_since(t0), cpu = process_cpu_ms() - cpu0;
    first_fps = 1e3 * static_cast<double>(n) / wall;
    std::printf("| before: cv::imwrite, 6 whole images, 1 thread | %.1f | %.2f | %.2f | 1.00x | %.1f |\n", first_fps,
                wall / static_cast<double>(n), cpu / static_cast<double>(n), static_cast<double>(dir_bytes(dir)) / 1e6);
    std::fflush(stdout);
    if (!keep) fs::remove_all(dir);
  }
  for (int t : threads) {
    const std::string dir = out + "/export-" + std::to_string(t);
    fs::remove_all(dir);
    ::sync();
    EurocExportOptions o;
    o.plot = false;
    o.threads = t;
    EurocExportReport r;
    const double cpu0 = process_cpu_ms();
    const auto t0 = Clock::now();
    if (auto s = export_euroc(**reader, dir, o, r); !s) {
      std::fprintf(stderr, "%s\n", s.error().message.c_str());
      return 1;
    }
    const double wall = ms_since(t0), cpu = process_cpu_ms() - cpu0;
    if (!r.problems.empty()) std::fprintf(stderr, "problem: %s\n", r.problems.front().c_str());
    const double fps = 1e3 * static_cast<double>(r.frames_written) / wall;
    std::printf("| export_euroc, %d thread(s) | %.1f | %.2f | %.2f | %.2fx | %.1f |\n", t, fps,
                wall / static_cast<double>(r.frames_written), cpu / static_cast<double>(r.frames_written),
                fps / first_fps, static_cast<double>(dir_bytes(dir)) / 1e6);
    std::fflush(stdout);
    if (!keep) fs::remove_all(dir);
  }
  if (!keep) fs::remove_all(rec_dir);
  return 0;
}
