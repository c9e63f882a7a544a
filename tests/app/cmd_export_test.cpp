// augrig export through the real binary (docs/REPLAY.md): on a recording this test writes with
// recorder::Recorder from frames it augments itself, the EuRoC layout, exit codes and messages of
// bad inputs, a truncated recording, and OUT/INCOMPLETE of a killed export.
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "app/commands.hpp"
#include "recorder/plot.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "tests/support/test_support.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::augrig_binary;
using test::output_dir;
using test::run_command;

constexpr int kFrames = 8;
constexpr TimestampNs kT0 = 2'000'000'000;
constexpr TimestampNs kPeriod = 33'000'000;

int augrig(const std::string& args, std::string* output = nullptr) {
  return test::run_augrig(args, output);
}

Rig small_rig() {
  Rig rig = Rig::paper_default();
  for (RigCamera& c : rig.cameras) c.model = CameraModel::pinhole_from_hfov(128, 96, deg_to_rad(56.0));
  return *parse_rig(rig_to_yaml(rig), "<string>");
}

Image raw_image(int i, int c) {
  Image im(128, 96, PixelFormat::kMono8);
  std::mt19937 rng(static_cast<unsigned>(10 * i + c));
  for (int y = 0; y < im.height(); ++y)
    for (int x = 0; x < im.width(); ++x) im.row(y)[x] = static_cast<std::uint8_t>(x + y + rng() % 16);
  return im;
}

// A recording of kFrames stereo frames augmented here, with everything the recorder stores.
std::string write_recording(const std::string& dir, int frames = kFrames) {
  const Rig rig = small_rig();
  auto ctx = create_gl_context(GlBackend::kEglHeadless);
  EXPECT_TRUE(ctx) << ctx.error().message;
  Eigen::Vector3d receptacle;
  AugmentOptions options;
  options.receiver_model = std::make_shared<const Model>(make_builtin_receiver(&receptacle));
  auto augmenter = Augmenter::create(rig, options);
  EXPECT_TRUE(augmenter) << augmenter.error().message;
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(rig);
  auto rec = recorder::Recorder::create(dir, info);
  EXPECT_TRUE(rec) << rec.error().message;
  StereoResult result;
  for (int i = 0; i < frames; ++i) {
    recorder::FrameRecord r;
    r.raw.pair_sequence = static_cast<std::uint64_t>(i);
    r.raw.t_key_ns = kT0 + i * kPeriod;
    for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
      Frame& f = r.raw[id];
      f.camera = id;
      f.t_ns = r.raw.t_key_ns;
      f.clock = ClockDomain::kSim;
      f.sequence = static_cast<std::uint64_t>(i);
      f.image = raw_image(i, index_of(id));
    }
    const BoomArticulation a{deg_to_rad(26.0 + i % 8), deg_to_rad(i % 8 - 4.0), 1.0 + 0.3 * (i % 8)};
    const SceneState scene =
        scene_at_contact(rig, BoomDimensions{}, receptacle, a, Eigen::Vector3d(0, 0, 0.5));
    EXPECT_TRUE((*augmenter)->augment(r.raw, scene, result));
    result.stats.t_ns = r.raw.t_key_ns;
    for (int c = 0; c < 2; ++c) {
      const ViewResult& v = c == 0 ? result.left : result.right;
      r.augmented[c] = v.augmented;
      r.mask[c] = v.mask;
      r.T_cam_receiver[c] =
          rig.cameras[static_cast<std::size_t>(c)].T_body_cam.inverse() * scene.T_body_receiver;
    }
    r.T_body_receiver = scene.T_body_receiver;
    r.receiver_present = scene.receiver_present;
    r.boom = scene.boom;
    r.stats = result.stats;
    EXPECT_TRUE((*rec)->push(std::move(r)));
  }
  EXPECT_TRUE((*rec)->close());
  return dir;
}

// One recording per test process (CTest runs each test in its own process, in parallel).
const std::string& recording() {
  static const std::string dir =
      write_recording(output_dir(std::string("cmd_export_") +
                                 testing::UnitTest::GetInstance()->current_test_info()->name()) +
                      "/rec");
  return dir;
}

std::size_t lines_of(const std::string& path) {
  std::ifstream in(path);
  std::string l;
  std::size_t n = 0;
  while (std::getline(in, l)) ++n;
  return n;
}

// The first `bytes` of a recording's database, as `head -c` leaves a file copied half-way.
std::string truncated_copy(const std::string& from, const std::string& name, std::uintmax_t bytes) {
  const std::string dir = output_dir(name);
  std::ifstream in(from + "/recording.sqlite", std::ios::binary);
  std::string data(bytes, '\0');
  in.read(data.data(), static_cast<std::streamsize>(bytes));
  data.resize(static_cast<std::size_t>(in.gcount()));
  std::ofstream(dir + "/recording.sqlite", std::ios::binary) << data;
  return dir;
}

const std::string& long_recording() {
  // Per test, as recording(): CTest runs the tests of this file in parallel processes.
  static const std::string dir =
      write_recording(output_dir(std::string("cmd_export_long_") +
                                 testing::UnitTest::GetInstance()->current_test_info()->name()) +
                          "/rec",
                      60);
  return dir;
}

// A recording cut in half: export said "Exported 99 of 99" and exited 0 while the summary said
// 201. It must say what is missing, exit 1 and mark its output.
TEST(CmdExport, ATruncatedRecordingSaysWhatIsMissing) {
  const std::uintmax_t size = fs::file_size(long_recording() + "/recording.sqlite");
  const std::string half = truncated_copy(long_recording(), "cmd_export_truncated", size / 2);
  std::string log;
  const std::string out = output_dir("cmd_export_truncated_export");
  ASSERT_EQ(augrig("export " + half + " --format euroc " + out + " --no-plot", &log), 1) << log;
  EXPECT_NE(log.find("readable (60 recorded) stereo frame(s)"), std::string::npos) << log;
  EXPECT_NE(log.find("the export is incomplete"), std::string::npos) << log;
  std::ifstream marker(out + "/INCOMPLETE");
  ASSERT_TRUE(marker) << "the output is not marked incomplete";
  const std::string text((std::istreambuf_iterator<char>(marker)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("summary says 60 frames were recorded"), std::string::npos) << text;

  // Cut before the first frame: nothing to export, and it says so with exit 1.
  const std::string head = truncated_copy(long_recording(), "cmd_export_truncated_head", 3 * 65536);
  const std::string out2 = output_dir("cmd_export_truncated_head_export");
  EXPECT_EQ(augrig("export " + head + " --format euroc " + out2 + " --no-plot", &log), 1) << log;
  if (fs::exists(out2 + "/mav0")) {
    EXPECT_TRUE(fs::exists(out2 + "/INCOMPLETE")) << log;
  }
}

TEST(CmdExport, WritesTheEurocLayout) {
  const std::string out = output_dir("cmd_export_layout");
  const bool plot = !recorder::find_gnuplot().empty();
  std::string log;
  ASSERT_EQ(augrig("export " + recording() + " --format euroc " + out + (plot ? "" : " --no-plot"), &log), 0)
      << log;
  EXPECT_NE(log.find("Exported 8 of 8 stereo frame(s) to " + out +
                     "/mav0: cam0, cam1, cam0_augmented, cam1_augmented, cam0_mask, cam1_mask"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("note: no nav inputs in the recording: imu0 not written"), std::string::npos) << log;
  EXPECT_EQ(lines_of(out + "/mav0/cam0/data.csv"), 9u);
  EXPECT_EQ(lines_of(out + "/mav0/cam1_mask/data.csv"), 9u);
  EXPECT_TRUE(fs::exists(out + "/mav0/cam1/sensor.yaml"));
  EXPECT_EQ(lines_of(out + "/stats.csv"), 9u);
  EXPECT_GT(lines_of(out + "/poses.csv"), 16u);
  if (plot) {
    EXPECT_TRUE(fs::exists(out + "/stats.png"));
  }

  EXPECT_EQ(augrig("export " + recording() + " --format euroc " + out, &log), 1) << log;
  EXPECT_NE(log.find("augrig export: " + out + "/mav0: exists already"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + recording() + " --format kitti " + out, &log), 2) << log;
  EXPECT_NE(log.find("--format: expected euroc, got 'kitti'"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + recording() + " " + out, &log), 2) << log;
  EXPECT_NE(log.find("missing required option --format euroc"), std::string::npos) << log;
  EXPECT_EQ(augrig("export " + recording() + " --format euroc", &log), 2) << log;
  EXPECT_NE(log.find("expected DIR OUT, got '" + recording() + "'"), std::string::npos) << log;
  EXPECT_EQ(
      augrig("export " + output_dir("cmd_export_missing") + "/x --format=euroc " + out + "2", &log),
      1)
      << log;
  EXPECT_NE(log.find("/x: no such file"), std::string::npos) << log;
}

// A finished export leaves no marker; one killed part-way leaves OUT/INCOMPLETE next to what it
// wrote (it once left PNGs and empty data.csv files that looked like a finished export).
TEST(CmdExport, AKilledExportIsMarkedIncomplete) {
  const std::string done = output_dir("cmd_export_done");
  std::string log;
  ASSERT_EQ(augrig("export " + long_recording() + " --format euroc " + done + " --no-plot", &log), 0) << log;
  EXPECT_FALSE(fs::exists(done + "/INCOMPLETE"));
  int killed = 0;
  for (const char* after : {"0.15", "0.3", "0.6"}) {
    const std::string out = output_dir(std::string("cmd_export_killed_") + after);
    const int rc = run_command("timeout -s KILL " + std::string(after) + " " + augrig_binary() + " export " +
                                   long_recording() + " --format euroc " + out + " --no-plot",
                               &log);
    if (rc == 0) {
      EXPECT_FALSE(fs::exists(out + "/INCOMPLETE"));
      continue;
    }
    ++killed;
    if (fs::exists(out + "/mav0")) {
      EXPECT_TRUE(fs::exists(out + "/INCOMPLETE")) << "killed after " << after << " s";
    }
  }
  EXPECT_GT(killed, 0) << "no export was killed part-way: the test did not test";
}

}  // namespace
}  // namespace augrig
