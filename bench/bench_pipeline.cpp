// bench_pipeline: issue 17's end-to-end figure, replay -> augment -> record losslessly (raw,
// augmented and masks of both cameras, 1280x960), with every path compared in the same run:
//   copy        the recorder stores each replayed raw image by copying its recorded blob
//               (recorder::RecordedFrame::raw_blobs; no decode-and-compress of the raw images);
//   recompress  the path before: ReplayOptions::keep_raw_blobs off, so the recorder compresses the
//               raw images again (what any non-replay source gets);
//   PNG         every image written as PNG with cv::imwrite (six files per stereo frame);
// and, to split the cost, replay alone and replay -> augment with nothing recorded; and the real
// command, `augrig replay INPUT --record OUT --headless` (pipeline::Pipeline: a StereoSource, its
// capture thread and adjacent pairing around the ReplaySource, the recorded poses, the recorder),
// run as a child process.
// Two scenes: "boom" (the receiver absent: SceneState::receiver_present false, so no receiver,
// no stereo classes) and "receiver" (boom + receiver + stereo classes, as the demo).
//   build/bench_pipeline [--frames N] [--png-frames M] [--format bayer|rgb8] [--reuse-input]
//                        [--read-ahead K] [--augrig PATH|none] [--command-only] [--look plain|camera]
// (--look: the command rows' `augrig replay --look`; default its own default, the camera look. The
// in-process rows augment with the plain look.) N: 450 by default; fewer make the figures noise.
// The input recording is made first (not timed) from the built-in demo flight's cameras: the
// synthetic renderer's last N stereo frames, with the boom and receiver of the scenario's truth.
// --reuse-input keeps it in /tmp/augrig_bench_pipeline and uses it again (for profiling).
// Timed: ReplaySource (as fast as possible) -> Augmenter (AugmentedOutput::kChangedBox, as `run`
// and `replay` use it) -> sink. A Recorder sink is timed until close() has committed everything;
// the producer waits while the recorder's queue is full, so nothing is dropped.
// CPU: getrusage(RUSAGE_SELF), user + system of every thread, per stereo frame. "replay CPU" is
// the reading thread's CPU inside ReplaySource::read plus its read-ahead thread's
// (ReplayOptions::read_ahead; --read-ahead K sets it, 0 decodes on the reading thread as before);
// "read() ms" the reading thread's wall time in read(), what the read-ahead takes off its path.
// The `augrig replay` rows: the child's wall time and CPU (wait4), less those of the same command
// replaying only the last frame (start-up: GL context, opening; the recording's close), over the
// other N - 1 frames; "pipeline /s" is the rate the pipeline's own summary prints (from its first
// pair read, which the capture thread may have read ahead while the GL context was made), and its
// "fps incl. close" is N over the whole child's wall time, start-up included.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/clock.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder/replay_source.hpp"
#include "recorder/store.hpp"
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

// User + system CPU time of the whole process (all threads), ms.
double rusage_cpu_ms() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  auto ms = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_usec) * 1e-3;
  };
  return ms(u.ru_utime) + ms(u.ru_stime);
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

enum class Sink { kReplayOnly, kNone, kCopy, kRecompress, kPng, kCommand };
const char* sink_name(Sink s) {
  switch (s) {
    case Sink::kReplayOnly:
      return "replay only (decode raw)";
    case Sink::kNone:
      return "replay -> augment (nothing recorded)";
    case Sink::kCopy:
      return "replay -> augment -> Recorder, raw blobs copied";
    case Sink::kRecompress:
      return "replay -> augment -> Recorder, raw recompressed (before)";
    case Sink::kPng:
      return "replay -> augment -> PNG (cv::imwrite) x6";
    case Sink::kCommand:
      return "augrig replay --record --headless (Pipeline, child process)";
  }
  return "?";
}

struct Figures {
  std::size_t frames = 0;
  double fps = 0;             // until the last frame is committed
  double fps_incl_close = 0;  // with the recorder's close()
  double cpu_ms = 0;          // all threads, per stereo frame
  double replay_cpu_ms = 0;   // CPU inside ReplaySource::read (reading thread) + its read-ahead thread's
  double read_wall_ms = 0;    // wall time the reading thread spent in ReplaySource::read
  double augment_ms = 0;      // wall time of augment()
  double encode_cpu_ms = 0;   // RecorderStats::encode_ms per frame
  double insert_cpu_ms = 0;   // RecorderStats::insert_ms per frame
  std::uint64_t raw_copied = 0;
  double stored_mb = 0;
  double pipeline_fps = 0;  // kCommand: the rate in the pipeline's own summary
};

// A child process's wall time, CPU (user + system) and output.
struct ChildRun {
  double wall_s = 0, cpu_s = 0;
  std::string output;
};

ChildRun run_child(const std::vector<std::string>& args, const fs::path& log) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto t0 = Clock::now();
  const pid_t pid = fork();
  if (pid < 0) {
    std::perror("bench_pipeline: fork");
    std::exit(1);
  }
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, 1);
      dup2(fd, 2);
    }
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  if (wait4(pid, &status, 0, &ru) != pid) {
    std::perror("bench_pipeline: wait4");
    std::exit(1);
  }
  ChildRun r;
  r.wall_s = seconds_since(t0);
  auto sec = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_usec) * 1e-6;
  };
  r.cpu_s = sec(ru.ru_utime) + sec(ru.ru_stime);
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  r.output = ss.str();
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::fprintf(stderr, "bench_pipeline: %s failed (status %d):\n%s\n", args[0].c_str(), status,
                 r.output.c_str());
    std::exit(1);
  }
  return r;
}

// Makes the input recording: the demo flight's last `frames` stereo frames in `format`.
// The scenario's camera format is the input's.
// With `boom_input`, the same frames again with receiver_present false (what `augrig replay`
// augments with the boom alone).
void make_input(int frames, const fs::path& input, const fs::path& boom_input, sim::Scenario& scenario) {
  const sim::Flight flight = need(sim::Flight::create(scenario), "flight");
  const sim::SensorLogs logs = sim::simulate_sensors(scenario, flight);
  std::vector<sim::FrameTruth> truths = sim::frame_truths(scenario, flight, logs.cameras);
  std::map<std::uint64_t, int> cams;
  for (const auto& f : truths) cams[f.sequence] |= 1 << f.camera;
  std::erase_if(truths, [&](const sim::FrameTruth& f) { return cams[f.sequence] != 3; });
  if (truths.size() > 2 * static_cast<std::size_t>(frames))
    truths.erase(truths.begin(), truths.end() - 2 * frames);
  auto source = need(sim::FlightSource::create(scenario, flight, truths), "flight source");
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(scenario.rig);
  recorder::RecorderOptions ro;
  ro.overwrite = true;
  auto rec = need(recorder::Recorder::create(input.string(), info, ro), "input recording");
  std::unique_ptr<recorder::Recorder> boom_rec;
  if (!boom_input.empty())
    boom_rec = need(recorder::Recorder::create(boom_input.string(), info, ro), "boom input");
  for (std::size_t i = 0; i + 1 < truths.size(); i += 2) {
    recorder::FrameRecord fr;
    need(source->read(fr.raw.left, {}), "render");
    fr.boom = source->last_truth().boom;
    fr.T_body_receiver = source->last_truth().T_body_receiver;
    need(source->read(fr.raw.right, {}), "render");
    fr.raw.right.camera = CameraId::kRight;
    fr.raw.t_key_ns = (fr.raw.left.t_ns + fr.raw.right.t_ns) / 2;
    fr.raw.skew_ns = fr.raw.right.t_ns - fr.raw.left.t_ns;
    fr.raw.pair_sequence = i / 2;
    while (rec->stats().frames_in_flight >= 32 || (boom_rec && boom_rec->stats().frames_in_flight >= 32))
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (boom_rec) {
      recorder::FrameRecord copy = fr;
      copy.receiver_present = false;
      if (!boom_rec->push(std::move(copy))) std::exit(1);
    }
    if (!rec->push(std::move(fr))) std::exit(1);
  }
  if (!rec->close()) std::exit(1);
  if (boom_rec && !boom_rec->close()) std::exit(1);
}

struct Bench {
  fs::path dir, input, boom_input;
  Augmenter* augmenter = nullptr;
  Rig rig;
  std::optional<std::size_t> read_ahead;  // ReplayOptions::read_ahead; default: the library's
  std::string augrig;                     // the augrig binary for the kCommand rows
  std::string look;                       // their --look; empty: replay's default

  // `augrig replay` of the whole input and of its last frame alone; the difference over N - 1 frames.
  Figures run_command(bool with_receiver, std::size_t frames) {
    const fs::path in = with_receiver ? input : boom_input;
    const fs::path out = dir / "command_output";
    auto cmd = [&](std::size_t from) {
      std::vector<std::string> a = {augrig,       "replay",      in.string(), "--record",
                                    out.string(), "--overwrite", "--headless"};
      if (from) a.insert(a.end(), {"--from-frame", std::to_string(from)});
      if (!look.empty()) a.insert(a.end(), {"--look", look});
      return run_child(a, dir / "command.log");
    };
    const ChildRun one = cmd(frames - 1);
    const ChildRun all = cmd(0);
    Figures g;
    g.frames = frames;
    const double k = static_cast<double>(std::max<std::size_t>(frames - 1, 1));
    g.fps = k / std::max(all.wall_s - one.wall_s, 1e-9);
    g.fps_incl_close = static_cast<double>(frames) / all.wall_s;
    g.cpu_ms = 1e3 * (all.cpu_s - one.cpu_s) / k;
    // "run: 90 stereo frames augmented in 1.2 s (75.3/s"
    if (const auto p = all.output.find("stereo frames augmented in "); p != std::string::npos)
      if (const auto q = all.output.find(" (", p); q != std::string::npos)
        g.pipeline_fps = std::atof(all.output.c_str() + q + 2);
    if (all.output.find("Recorded " + std::to_string(frames) + " stereo frame(s)") == std::string::npos) {
      std::fprintf(stderr, "bench_pipeline: augrig replay did not record %zu frames:\n%s\n", frames,
                   all.output.c_str());
      std::exit(1);
    }
    auto rd = need(recorder::RecordingReader::open(out.string()), "reopen the command's recording");
    const recorder::CheckReport report = rd->check();
    if (!report.ok() || report.frames != frames) {
      std::fprintf(stderr, "bench_pipeline: the command's recording does not check:\n%s\n",
                   report.to_string().c_str());
      std::exit(1);
    }
    g.stored_mb = static_cast<double>(report.stored_bytes) / 1e6;
    return g;
  }

  Figures run(Sink sink, bool with_receiver, std::size_t count) {
    Figures g;
    recorder::ReplayOptions ro;
    ro.keep_raw_blobs = sink == Sink::kCopy;
    if (read_ahead) ro.read_ahead = *read_ahead;
    auto replay = need(recorder::ReplaySource::open(input.string(), ro), "replay");
    count = std::min(count, replay->frame_count());
    std::unique_ptr<recorder::Recorder> out;
    if (sink == Sink::kCopy || sink == Sink::kRecompress) {
      recorder::RecordingInfo info;
      info.rig_yaml = rig_to_yaml(rig);
      recorder::RecorderOptions o;
      o.overwrite = true;
      out = need(recorder::Recorder::create((dir / "output").string(), info, o), "output recording");
    }
    if (sink == Sink::kPng) {
      fs::remove_all(dir / "png");
      fs::create_directories(dir / "png");
    }
    StereoResult result;
    double augment_s = 0, replay_cpu = 0, read_wall_s = 0;
    const auto t0 = Clock::now();
    const double cpu0 = rusage_cpu_ms();
    const double read_ahead_cpu0 = replay->read_ahead_cpu_ms();
    std::size_t n = 0;
    for (; n < count; ++n) {
      recorder::FrameRecord fr;
      const double r0 = thread_cpu_ms();
      const auto w0 = Clock::now();
      if (need(replay->read(fr.raw.left, std::chrono::seconds(1)), "replay") != ReadStatus::kFrame) break;
      if (need(replay->read(fr.raw.right, std::chrono::seconds(1)), "replay") != ReadStatus::kFrame) break;
      read_wall_s += seconds_since(w0);
      replay_cpu += thread_cpu_ms() - r0;
      if (sink == Sink::kReplayOnly) continue;
      const recorder::FrameRecord& rec = replay->current();
      fr.raw.t_key_ns = rec.raw.t_key_ns;
      fr.raw.skew_ns = rec.raw.skew_ns;
      fr.raw.pair_sequence = rec.raw.pair_sequence;
      SceneState scene;
      scene.boom = *rec.boom;
      scene.T_body_receiver = *rec.T_body_receiver;
      scene.receiver_present = with_receiver;
      const auto ta = Clock::now();
      if (auto st = augmenter->augment(fr.raw, scene, result); !st) {
        std::fprintf(stderr, "bench_pipeline: augment: %s\n", st.error().message.c_str());
        std::exit(1);
      }
      augment_s += seconds_since(ta);
      if (out) {
        fr.augmented = {result.left.augmented, result.right.augmented};
        fr.augmented_box = {result.left.augmented_box, result.right.augmented_box};
        fr.mask = {result.left.mask, result.right.mask};
        fr.stats = result.stats;
        fr.boom = scene.boom;
        fr.T_body_receiver = scene.T_body_receiver;
        fr.receiver_present = with_receiver;
        // Wait for room first: a refused push would count a drop and lose the frame.
        while (out->stats().frames_in_flight >= 60)
          std::this_thread::sleep_for(std::chrono::microseconds(200));
        if (!out->push(std::move(fr))) {
          std::fprintf(stderr, "bench_pipeline: a frame was dropped\n");
          std::exit(1);
        }
      } else if (sink == Sink::kPng) {
        const std::string s = std::to_string(n);
        write_png(dir / "png" / ("raw_l" + s + ".png"), fr.raw.left.image);
        write_png(dir / "png" / ("raw_r" + s + ".png"), fr.raw.right.image);
        write_png(dir / "png" / ("aug_l" + s + ".png"), whole_augmented(fr.raw.left.image, result.left));
        write_png(dir / "png" / ("aug_r" + s + ".png"), whole_augmented(fr.raw.right.image, result.right));
        write_png(dir / "png" / ("mask_l" + s + ".png"), result.left.mask);
        write_png(dir / "png" / ("mask_r" + s + ".png"), result.right.mask);
      }
    }
    double close_s = 0;
    if (out) {
      // Sustained throughput: until the writer has committed the last frame; close() (the final
      // checkpoint into the database and its fsync, once per recording) is reported apart.
      while (out->stats().frames_committed + out->stats().frames_dropped < n)
        std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    const double wall = seconds_since(t0);
    const double cpu = rusage_cpu_ms() - cpu0;
    if (out) {
      const auto tc = Clock::now();
      if (auto st = out->close(); !st) {
        std::fprintf(stderr, "bench_pipeline: close: %s\n", st.error().message.c_str());
        std::exit(1);
      }
      close_s = seconds_since(tc);
    }
    const double k = static_cast<double>(std::max<std::size_t>(n, 1));
    g.frames = n;
    g.fps = static_cast<double>(n) / wall;
    g.fps_incl_close = static_cast<double>(n) / (wall + close_s);
    g.cpu_ms = cpu / k;
    g.replay_cpu_ms = (replay_cpu + replay->read_ahead_cpu_ms() - read_ahead_cpu0) / k;
    g.augment_ms = 1e3 * augment_s / k;
    g.read_wall_ms = 1e3 * read_wall_s / k;
    if (out) {
      const recorder::RecorderStats s = out->stats();
      g.encode_cpu_ms = s.encode_ms / k;
      g.insert_cpu_ms = s.insert_ms / k;
      g.raw_copied = s.raw_blobs_copied;
      g.stored_mb = static_cast<double>(s.stored_bytes) / 1e6;
      if (s.frames_committed != n) {
        std::fprintf(stderr, "bench_pipeline: %llu of %zu frames committed\n",
                     static_cast<unsigned long long>(s.frames_committed), n);
        std::exit(1);
      }
      // The recording must check clean: the copy is a readable recording.
      auto rd = need(recorder::RecordingReader::open((dir / "output").string()), "reopen");
      const recorder::CheckReport report = rd->check();
      if (!report.ok()) {
        std::fprintf(stderr, "bench_pipeline: the output recording does not check:\n%s\n",
                     report.to_string().c_str());
        std::exit(1);
      }
    }
    return g;
  }
};

}  // namespace

int main(int argc, char** argv) {
  int frames = 450, png_frames = 15;  // 90 frames measured 101 to 154 fps for one binary (PERFORMANCE.md)
  bool reuse = false, command_only = false;
  std::optional<std::size_t> read_ahead;
  std::string augrig = (fs::read_symlink("/proc/self/exe").parent_path() / "augrig").string();
  std::string look;
  PixelFormat format = PixelFormat::kBayerRG8;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--frames" && has_value) {
      frames = std::atoi(argv[++i]);
    } else if (a == "--png-frames" && has_value) {
      png_frames = std::atoi(argv[++i]);
    } else if (a == "--reuse-input") {
      reuse = true;
    } else if (a == "--read-ahead" && has_value) {
      read_ahead = static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--augrig" && has_value) {
      augrig = argv[++i];
    } else if (a == "--command-only") {
      command_only = true;
    } else if (a == "--look" && has_value) {
      look = argv[++i];
    } else if (a == "--format" && has_value) {
      const std::string f = argv[++i];
      if (f == "bayer")
        format = PixelFormat::kBayerRG8;
      else if (f == "rgb8")
        format = PixelFormat::kRGB8;
      else {
        std::fprintf(stderr, "bench_pipeline: --format: expected bayer or rgb8, got %s\n", f.c_str());
        return 2;
      }
    } else {
      std::fprintf(
          stderr,
          "usage: bench_pipeline [--frames N] [--png-frames M] [--format bayer|rgb8] [--reuse-input]\n"
          "                      [--read-ahead K] [--augrig PATH|none] [--command-only]\n"
          "                      [--look plain|camera]\n");
      return 2;
    }
  }
  if (frames < 2 || png_frames < 0) {
    std::fprintf(stderr, "bench_pipeline: --frames must be >= 2 and --png-frames >= 0\n");
    return 2;
  }
  auto ctx = need(create_gl_context(GlBackend::kEglHeadless), "GL context");
  std::printf("bench_pipeline: %s, %u hardware threads\n", ctx->renderer().c_str(),
              std::thread::hardware_concurrency());

  Bench b;
  b.read_ahead = read_ahead;
  b.look = look;
  if (augrig != "none" && access(augrig.c_str(), X_OK) != 0) {
    std::printf("no augrig binary at %s: the augrig replay rows are left out (--augrig PATH)\n",
                augrig.c_str());
    augrig = "none";
  }
  if (augrig != "none") b.augrig = augrig;
  b.dir = fs::temp_directory_path() / "augrig_bench_pipeline";
  b.input = b.dir / (std::string("input_") + std::string(to_string(format)) + "_" + std::to_string(frames));
  b.boom_input =
      b.dir / (std::string("input_boom_") + std::string(to_string(format)) + "_" + std::to_string(frames));
  sim::Scenario scenario = need(sim::builtin_scenario("demo"), "scenario");
  scenario.sensors.cameras.format = format;
  b.rig = scenario.rig;
  if (!reuse || !fs::exists(b.input / "recording.sqlite") || !fs::exists(b.boom_input / "recording.sqlite")) {
    fs::remove_all(b.input);
    fs::remove_all(b.boom_input);
    std::printf("making the input recording (not timed) ...\n");
    std::fflush(stdout);
    make_input(frames, b.input, b.boom_input, scenario);
  }
  AugmentOptions options;
  options.augmented_output = AugmentedOutput::kChangedBox;
  Eigen::Vector3d receptacle;
  options.receiver_model = std::make_shared<const Model>(make_builtin_receiver(&receptacle));
  auto augmenter = need(Augmenter::create(scenario.rig, options), "augmenter");
  b.augmenter = augmenter.get();
  std::printf("rasteriser: %s; ReplaySource read-ahead %zu stereo frame(s)\n",
              to_string(augmenter->rasterizer()), read_ahead.value_or(recorder::ReplayOptions{}.read_ahead));

  const std::size_t n = static_cast<std::size_t>(frames);
  const std::size_t m = static_cast<std::size_t>(png_frames);
  struct Row {
    const char* scene;
    Sink sink;
    Figures g;
  };
  std::vector<Row> rows;
  if (command_only && b.augrig.empty()) {
    std::fprintf(stderr, "bench_pipeline: --command-only needs the augrig binary (--augrig PATH)\n");
    return 2;
  }
  if (!command_only) rows.push_back({"-", Sink::kReplayOnly, b.run(Sink::kReplayOnly, false, n)});
  for (bool with_receiver : {false, true}) {
    const char* scene = with_receiver ? "receiver" : "boom";
    if (command_only) {
      rows.push_back({scene, Sink::kCommand, b.run_command(with_receiver, n)});
      continue;
    }
    (void)b.run(Sink::kNone, with_receiver, 5);  // warm up (first-use allocations, thread start)
    for (Sink s : {Sink::kNone, Sink::kCopy, Sink::kRecompress})
      rows.push_back({scene, s, b.run(s, with_receiver, n)});
    if (m > 0) rows.push_back({scene, Sink::kPng, b.run(Sink::kPng, with_receiver, m)});
    if (!b.augrig.empty()) rows.push_back({scene, Sink::kCommand, b.run_command(with_receiver, n)});
  }
  if (!reuse) fs::remove_all(b.dir);

  std::printf(
      "\n%d stereo frames %s 1280x960 of the demo flight; boom: receiver absent; receiver: boom + "
      "receiver + stereo classes\n\n",
      frames, to_string(format).data());
  std::printf(
      "| scene | pipeline | frames | stereo fps | fps incl. close | CPU ms/frame (all threads) | replay CPU "
      "ms | read() ms (wall) | augment ms (wall) | "
      "encode CPU ms | insert CPU ms | raw blobs copied | stored MB | pipeline /s |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const Row& r : rows) {
    const Figures& g = r.g;
    if (r.sink == Sink::kCommand) {
      std::printf("| %s | %s | %zu | %.1f | %.1f | %.1f | - | - | - | - | - | - | %.1f | %.1f |\n", r.scene,
                  sink_name(r.sink), g.frames, g.fps, g.fps_incl_close, g.cpu_ms, g.stored_mb,
                  g.pipeline_fps);
      continue;
    }
    std::printf(
        "| %s | %s | %zu | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %llu | %.1f | - |\n",
        r.scene, sink_name(r.sink), g.frames, g.fps, g.fps_incl_close, g.cpu_ms, g.replay_cpu_ms,
        g.read_wall_ms, g.augment_ms, g.encode_cpu_ms, g.insert_cpu_ms,
        static_cast<unsigned long long>(g.raw_copied), g.stored_mb);
  }
  std::printf("\n");
  for (const char* scene : {"boom", "receiver"}) {
    const Figures *copy = nullptr, *re = nullptr, *png = nullptr;
    for (const Row& r : rows) {
      if (std::string(r.scene) != scene) continue;
      if (r.sink == Sink::kCopy) copy = &r.g;
      if (r.sink == Sink::kRecompress) re = &r.g;
      if (r.sink == Sink::kPng) png = &r.g;
    }
    if (!copy || !re) continue;
    std::printf("%s: copy / recompress %.2f x fps, %.2f x CPU per frame", scene, copy->fps / re->fps,
                copy->cpu_ms / re->cpu_ms);
    if (png) std::printf("; copy / PNG %.1f x fps", copy->fps / png->fps);
    std::printf("; target %d stereo fps (%.1f CPU ms per frame on 2 cores)\n",
                scene == std::string("boom") ? 120 : 60, 2000.0 / (scene == std::string("boom") ? 120 : 60));
  }
  return 0;
}
