// bench_pipeline: issue 4's end-to-end figure, replay -> augment -> record losslessly (raw,
// augmented and masks of both cameras, 1280x960), against the naive baseline in the same run:
// replay -> augment -> every image written as PNG with cv::imwrite.
//   build/bench_pipeline [--frames N] [--png-frames M] [--format bayer|rgb8|both]
// The input recording is made first (not timed) from the built-in demo flight's cameras: the
// synthetic renderer's frames of the approach, with the receiver and boom of the scenario's truth,
// as BayerRG8 (what GigE cameras deliver) and as RGB8 (what the demo renders), one after the other.
// Timed: ReplaySource reads (as fast as possible) -> Augmenter (boom + receiver + stereo classes)
// -> Recorder::push (the producer waits while the recorder's queue is full: nothing is dropped),
// until close() has committed everything.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "core/clock.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder/replay_source.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/image_file.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"

using namespace augrig;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

template <typename T>
T need(Expected<T> e, const char* what) {
  if (!e) {
    std::fprintf(stderr, "bench_pipeline: %s: %s\n", what, e.error().message.c_str());
    std::exit(1);
  }
  return std::move(e).value();
}

void write_png(const fs::path& p, const Image& im) {
  if (!write_png_file(p.string(), im)) std::exit(1);
}

// One format's figures.
struct Figures {
  double rec_fps = 0, rec_aug_ms = 0, png_fps = 0, png_aug_ms = 0;
  double rec_cpu_ms = 0, png_cpu_ms = 0;  // CPU time of all threads per stereo frame
  double encode_cpu_ms = 0;               // of which the recorder's compression (RecorderStats)
};

// Records the input in `format` (not timed), then times replay -> augment -> Recorder and
// replay -> augment -> PNG over it.
Figures run_format(PixelFormat format, int frames, int png_frames, const fs::path& dir) {
  fs::remove_all(dir);
  // The input: the demo flight's last `frames` stereo frames, recorded raw (not timed).
  sim::Scenario scenario = need(sim::builtin_scenario("demo"), "scenario");
  scenario.sensors.cameras.format = format;
  const sim::Flight flight = need(sim::Flight::create(scenario), "flight");
  const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
  std::vector<sim::FrameTruth> truths = sim::frame_truths(scenario, flight, logs.cameras);
  std::map<std::uint64_t, int> cams;
  for (const auto& f : truths) cams[f.sequence] |= 1 << f.camera;
  std::erase_if(truths, [&](const sim::FrameTruth& f) { return cams[f.sequence] != 3; });
  if (truths.size() > 2 * static_cast<std::size_t>(frames))
    truths.erase(truths.begin(), truths.end() - 2 * frames);
  {
    auto source = need(sim::FlightSource::create(scenario, flight, truths), "flight source");
    recorder::RecordingInfo info;
    info.rig_yaml = rig_to_yaml(scenario.rig);
    auto rec = need(recorder::Recorder::create((dir / "input").string(), info), "input recording");
    for (std::size_t i = 0; i + 1 < truths.size(); i += 2) {
      recorder::FrameRecord fr;
      need(source->read(fr.raw.left, {}), "render");
      fr.boom = source->last_truth().boom;
      fr.T_body_receiver = source->last_truth().T_body_receiver;
      need(source->read(fr.raw.right, {}), "render");
      fr.raw.right.camera = CameraId::kRight;
      while (!rec->push(recorder::FrameRecord(fr))) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (!rec->close()) std::exit(1);
  }
  const std::size_t n = truths.size() / 2;
  AugmentOptions options;
  // As `augrig run` and `replay` do: the augmenter makes only the boxes the boom changes and the
  // recorder stores them as they are (the PNG baseline gets whole images made from them).
  options.augmented_output = AugmentedOutput::kChangedBox;
  Eigen::Vector3d receptacle;
  options.receiver_model = std::make_shared<const Model>(make_builtin_receiver(&receptacle));
  auto augmenter = need(Augmenter::create(scenario.rig, options), "augmenter");

  // One pass: replay -> augment -> sink; returns stereo frames per second.
  auto run = [&](std::size_t count, auto&& sink) {
    recorder::ReplayOptions ro;
    auto replay = need(recorder::ReplaySource::open((dir / "input").string(), ro), "replay");
    StereoFrame frame;
    StereoResult result;
    double augment_s = 0;
    const auto t0 = Clock::now();
    for (std::size_t i = 0; i < count; ++i) {
      if (need(replay->read(frame.left, std::chrono::seconds(1)), "replay") != ReadStatus::kFrame) break;
      if (need(replay->read(frame.right, std::chrono::seconds(1)), "replay") != ReadStatus::kFrame) break;
      const recorder::FrameRecord& rec = replay->current();
      SceneState scene;
      scene.boom = *rec.boom;
      scene.T_body_receiver = *rec.T_body_receiver;
      const auto ta = Clock::now();
      if (!augmenter->augment(frame, scene, result)) std::exit(1);
      augment_s += seconds_since(ta);
      sink(frame, result);
    }
    return std::pair{static_cast<double>(count) / seconds_since(t0),
                     1e3 * augment_s / static_cast<double>(count)};
  };

  // Recorder sink.
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(scenario.rig);
  auto out = need(recorder::Recorder::create((dir / "output").string(), info), "output recording");
  const auto t0 = Clock::now();
  const double cpu0 = process_cpu_ms();
  auto [rec_fps_loop, rec_aug_ms] = run(n, [&](const StereoFrame& f, const StereoResult& r) {
    recorder::FrameRecord fr;
    fr.raw = f;
    fr.augmented = {r.left.augmented, r.right.augmented};
    fr.augmented_box = {r.left.augmented_box, r.right.augmented_box};
    fr.mask = {r.left.mask, r.right.mask};
    fr.stats = r.stats;
    while (!out->push(std::move(fr))) std::this_thread::sleep_for(std::chrono::microseconds(200));
  });
  (void)rec_fps_loop;
  if (!out->close()) std::exit(1);
  const double encode_cpu_ms = out->stats().encode_ms / static_cast<double>(n);
  const double rec_fps = static_cast<double>(n) / seconds_since(t0);
  const double rec_cpu_ms = (process_cpu_ms() - cpu0) / static_cast<double>(n);

  // PNG sink: six images per stereo frame.
  const std::size_t m = std::min<std::size_t>(n, static_cast<std::size_t>(png_frames));
  fs::create_directories(dir / "png");
  std::size_t k = 0;
  const double cpu1 = process_cpu_ms();
  auto [png_fps, png_aug_ms] = run(m, [&](const StereoFrame& f, const StereoResult& r) {
    const std::string s = std::to_string(k++);
    write_png(dir / "png" / ("raw_l" + s + ".png"), f.left.image);
    write_png(dir / "png" / ("raw_r" + s + ".png"), f.right.image);
    write_png(dir / "png" / ("aug_l" + s + ".png"), whole_augmented(f.left.image, r.left));
    write_png(dir / "png" / ("aug_r" + s + ".png"), whole_augmented(f.right.image, r.right));
    write_png(dir / "png" / ("mask_l" + s + ".png"), r.left.mask);
    write_png(dir / "png" / ("mask_r" + s + ".png"), r.right.mask);
  });

  const double png_cpu_ms = (process_cpu_ms() - cpu1) / static_cast<double>(m);
  fs::remove_all(dir);
  return {rec_fps, rec_aug_ms, png_fps, png_aug_ms, rec_cpu_ms, png_cpu_ms, encode_cpu_ms};
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 120, png_frames = 20;
  std::vector<PixelFormat> formats = {PixelFormat::kBayerRG8, PixelFormat::kRGB8};
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--frames") frames = std::atoi(argv[i + 1]);
    if (a == "--png-frames") png_frames = std::atoi(argv[i + 1]);
    if (a == "--format") {
      const std::string f = argv[i + 1];
      if (f == "bayer")
        formats = {PixelFormat::kBayerRG8};
      else if (f == "rgb8")
        formats = {PixelFormat::kRGB8};
      else if (f != "both") {
        std::fprintf(stderr, "bench_pipeline: --format: expected bayer, rgb8 or both, got %s\n", f.c_str());
        return 2;
      }
    }
  }
  const fs::path dir = fs::temp_directory_path() / "augrig_bench_pipeline";
  auto ctx = need(create_gl_context(GlBackend::kEglHeadless), "GL context");
  std::printf("bench_pipeline: %s, %u hardware threads\n", ctx->renderer().c_str(),
              std::thread::hardware_concurrency());
  std::vector<std::pair<PixelFormat, Figures>> all;
  for (PixelFormat f : formats) all.emplace_back(f, run_format(f, frames, png_frames, dir));

  std::printf("%d stereo frames 1280x960 of the demo flight (boom + receiver + stereo classes)\n\n", frames);
  std::printf(
      "| raw format | pipeline                                   | stereo fps | augment ms/frame | CPU "
      "ms/frame |\n");
  std::printf(
      "|------------|--------------------------------------------|-----------:|-----------------:|-----------"
      "--:|\n");
  for (const auto& [f, g] : all) {
    const char* name = to_string(f).data();
    std::printf("| %-10s | replay -> augment -> Recorder (lossless)   | %10.1f | %16.1f | %12.1f |\n", name,
                g.rec_fps, g.rec_aug_ms, g.rec_cpu_ms);
    std::printf("| %-10s | replay -> augment -> PNG (cv::imwrite) x6  | %10.1f | %16.1f | %12.1f |\n", name,
                g.png_fps, g.png_aug_ms, g.png_cpu_ms);
  }
  for (const auto& [f, g] : all)
    std::printf(
        "%s: ratio recorder / PNG %.1f x; the recorder's compression %.1f of the %.1f CPU ms per frame\n",
        to_string(f).data(), g.rec_fps / g.png_fps, g.encode_cpu_ms, g.rec_cpu_ms);
  std::printf("target (issue 4): 120 stereo fps\n");
  return 0;
}
