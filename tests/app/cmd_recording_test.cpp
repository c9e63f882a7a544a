// augrig check, replay and export through the real binary, on a recording this test writes with
// recorder::Recorder from frames it augments itself (so the recording holds the real augmenter's
// images, masks and statistics): replay reproduces the recorded statistics, seeks, loops, paces,
// re-augments with another scene or rig, reports a damaged frame and goes on; exit codes and
// messages of bad inputs and flags. The export command's tests are in tests/app/cmd_export_test.cpp.
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "app/commands.hpp"
#include "recorder/plot.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder/store.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "tests/support/recording_fixture.hpp"
#include "tests/support/test_support.hpp"
#include "tests/support/window_shot.hpp"

namespace augrig {
namespace {

namespace fs = std::filesystem;
using test::augrig_binary;
using test::output_dir;
using test::run_command;
using test::small_rig;
using test::truncated_copy;

int augrig(const std::string& args, std::string* output = nullptr) {
  return test::run_augrig(args, output);
}

// One recording per test process (CTest runs each test in its own process, in parallel).
const std::string& recording() {
  return test::recording_of_this_test("cmd_recording_");
}

// A copy of the recording with frame 3's left raw blob damaged.
std::string damaged_copy(const std::string& name) {
  const std::string dir = output_dir(name);
  fs::copy_file(recording() + "/recording.sqlite", dir + "/recording.sqlite");
  auto d = recorder::Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
  EXPECT_TRUE(d);
  EXPECT_TRUE(
      d->exec("UPDATE frames SET left_raw = CAST(substr(left_raw, 1, 100) || x'00' || "
              "substr(left_raw, 102) AS BLOB) WHERE pair_sequence = 3"));
  return dir;
}

std::size_t lines_of(const std::string& path) {
  std::ifstream in(path);
  std::string l;
  std::size_t n = 0;
  while (std::getline(in, l)) ++n;
  return n;
}

TEST(CmdRecording, TopHelpListsTheCommands) {
  std::string log;
  EXPECT_EQ(augrig("--help", &log), 0);
  for (const char* c : {"  check ", "  replay ", "  export "})
    EXPECT_NE(log.find(c), std::string::npos) << log;
}

TEST(CmdRecording, CheckReportsAndExitsByDamage) {
  std::string log;
  ASSERT_EQ(augrig("check " + recording(), &log), 0) << log;
  EXPECT_NE(log.find("frames: 8 (8 intact, 8 augmented, 8 with masks, 8 with statistics)"), std::string::npos)
      << log;
  EXPECT_NE(log.find("problems: none"), std::string::npos) << log;

  const std::string bad = damaged_copy("cmd_recording_check_damaged");
  ASSERT_EQ(augrig("check " + bad, &log), 1) << log;
  EXPECT_NE(log.find("problems: 1"), std::string::npos) << log;
  EXPECT_NE(log.find("frame 3: left raw blob"), std::string::npos) << log;
}

TEST(CmdRecording, CheckErrors) {
  std::string log;
  const std::string missing = output_dir("cmd_recording_missing") + "/nope";
  EXPECT_EQ(augrig("check " + missing, &log), 1) << log;
  EXPECT_NE(log.find("augrig check: " + missing + ": no such file"), std::string::npos) << log;
  const std::string empty = output_dir("cmd_recording_empty");
  EXPECT_EQ(augrig("check " + empty, &log), 1) << log;
  EXPECT_NE(log.find("recording.sqlite: no such file (a recording folder holds recording.sqlite)"),
            std::string::npos)
      << log;
  const std::string junk = output_dir("cmd_recording_junk");
  std::ofstream(junk + "/recording.sqlite") << std::string(5000, 'x');
  EXPECT_EQ(augrig("check " + junk, &log), 1) << log;
  EXPECT_NE(log.find("augrig check: " + junk + "/recording.sqlite: not a readable augrig recording"),
            std::string::npos)
      << log;

  EXPECT_EQ(augrig("check", &log), 2) << log;
  EXPECT_NE(log.find("augrig check: expected DIR, got none (see augrig check --help)"), std::string::npos)
      << log;
  EXPECT_EQ(augrig("check a b", &log), 2) << log;
  EXPECT_NE(log.find("expected DIR, got 'a', 'b'"), std::string::npos) << log;
  EXPECT_EQ(augrig("check " + recording() + " --deep", &log), 2) << log;
  EXPECT_NE(log.find("unknown option '--deep'"), std::string::npos) << log;
  EXPECT_EQ(augrig("check --help", &log), 0) << log;
  EXPECT_NE(log.find("Usage: augrig check DIR"), std::string::npos) << log;
}

TEST(CmdRecording, ReplayReproducesTheRecordedStatistics) {
  const std::string out = output_dir("cmd_recording_replay");
  std::string log;
  // The recording's augmented images were made with the plain look (write_recording).
  ASSERT_EQ(augrig("replay " + recording() + " --out " + out + " --every 3 --look plain", &log), 0) << log;
  EXPECT_NE(log.find("Replayed 8 stereo frame(s)"), std::string::npos) << log;
  EXPECT_NE(log.find("Recorded statistics reproduced exactly (same pixel counts) in 8 of 8 frame(s)"),
            std::string::npos)
      << log;
  EXPECT_EQ(lines_of(out + "/stats.csv"), 9u);
  for (const char* f : {"000000", "000003", "000006"}) {
    EXPECT_TRUE(fs::exists(out + "/left/augmented/" + f + ".png")) << f;
    EXPECT_TRUE(fs::exists(out + "/right/mask/" + f + ".png")) << f;
  }
  EXPECT_FALSE(fs::exists(out + "/left/augmented/000001.png"));
  // The replayed augmented image is the recorded one.
  auto rd = recorder::RecordingReader::open(recording());
  ASSERT_TRUE(rd);
  auto rec = (*rd)->read_frame(3);
  ASSERT_TRUE(rec) << rec.error().message;
  auto png = app::read_image_file(out + "/left/augmented/000003.png");
  ASSERT_TRUE(png) << png.error().message;
  EXPECT_TRUE(pixels_equal(*png, rec->augmented[0]));
}

// replay in the window under Xvfb: the screenshot of a shown pair has the boom where the masks of
// that pair (re-recorded by the same replay) say, and the occlusion panel filled.
TEST(CmdRecording, ReplayInTheWindowShowsTheBoomWhereTheMasksSay) {
  if (run_command("command -v xvfb-run > /dev/null") != 0) GTEST_SKIP() << "xvfb-run is not installed";
  const std::string dir = output_dir("cmd_recording_replay_window");
  std::string log;
  ASSERT_EQ(
      augrig("run --source 'sim://demo?every=30&rate=0' --frames 4 --headless --status-every 0 --record " +
                 dir + "/rec",
             &log),
      0)
      << log;
  ASSERT_EQ(run_command("xvfb-run -a " + augrig_binary() + " replay " + dir +
                            "/rec --screenshot-at 3 --out " + dir + "/out --record " + dir + "/again 2>&1",
                        &log),
            0)
      << log;
  EXPECT_NE(log.find("Recorded statistics reproduced exactly (same pixel counts) in 4 of 4 frame(s)"),
            std::string::npos)
      << log;
  const auto shot = test::parse_window_shot(log);
  ASSERT_TRUE(shot) << log;
  auto reader = recorder::RecordingReader::open(dir + "/again");
  ASSERT_TRUE(reader) << reader.error().message;
  auto frame = (*reader)->read_frame(shot->pair - 1);
  ASSERT_TRUE(frame) << frame.error().message;
  test::check_window_shot(*shot, *frame);
}

TEST(CmdRecording, ReplaySeekLoopFromFrameAndRate) {
  std::string log;
  // Frames are 33 ms apart: 0.1 s after the first is frame 4; 4 frames, twice.
  ASSERT_EQ(augrig("replay " + recording() + " --seek 0.1 --loop 2 --rate 4", &log), 0) << log;
  EXPECT_NE(log.find("from frame 4, real rate x4.0, 2 passes"), std::string::npos) << log;
  EXPECT_NE(log.find("Replayed 8 stereo frame(s)"), std::string::npos) << log;
  ASSERT_EQ(augrig("replay " + recording() + " --from-frame 6 --fast", &log), 0) << log;
  EXPECT_NE(log.find("Replayed 2 stereo frame(s)"), std::string::npos) << log;
  EXPECT_NE(log.find("in 2 of 2 frame(s)"), std::string::npos) << log;
}

TEST(CmdRecording, ReplayWithAnotherSceneOrRig) {
  std::string log;
  ASSERT_EQ(augrig("replay " + recording() + " --scene " + test::data_path("scenes/absent.yaml"), &log), 0)
      << log;
  EXPECT_NE(log.find("scene " + test::data_path("scenes/absent.yaml")), std::string::npos) << log;
  EXPECT_NE(log.find("Replayed 8 stereo frame(s)"), std::string::npos) << log;
  EXPECT_NE(log.find("in 0 of 8 frame(s)"), std::string::npos) << log;  // no receiver: other counts

  EXPECT_EQ(augrig("replay " + recording() + " --rig default", &log), 1) << log;
  EXPECT_NE(log.find("frame 0: the left image is 128x96, the rig's left camera is 1280x960"),
            std::string::npos)
      << log;
  EXPECT_EQ(augrig("replay " + recording() + " --scene " + test::data_path("scenes/bad_syntax.yaml"), &log),
            1)
      << log;
  EXPECT_NE(log.find("bad_syntax.yaml"), std::string::npos) << log;
}

TEST(CmdRecording, ReplayWithAnotherBoomRecordsTheResult) {
  const std::string out = output_dir("cmd_recording_reaugment") + "/rec";
  std::string log;
  ASSERT_EQ(augrig("replay " + recording() + " --boom fixed:35,5,2 --record " + out, &log), 0) << log;
  EXPECT_NE(log.find("Recorded 8 stereo frame(s)"), std::string::npos) << log;
  auto src = recorder::RecordingReader::open(recording());
  auto dst = recorder::RecordingReader::open(out);
  ASSERT_TRUE(src && dst);
  ASSERT_EQ((*dst)->frame_count(), 8u);
  EXPECT_EQ((*dst)->meta("re_augmented_from"), (*src)->path());
  for (std::size_t i = 0; i < 8; ++i) {
    auto a = (*src)->read_frame(i);
    auto b = (*dst)->read_frame(i);
    ASSERT_TRUE(a && b);
    // The raw frames carry over bit for bit; the boom is the one asked for.
    EXPECT_TRUE(pixels_equal(a->raw.left.image, b->raw.left.image)) << i;
    EXPECT_TRUE(pixels_equal(a->raw.right.image, b->raw.right.image)) << i;
    EXPECT_EQ(a->raw.left.t_ns, b->raw.left.t_ns);
    ASSERT_TRUE(b->boom);
    EXPECT_NEAR(rad_to_deg(b->boom->elevation_rad), 35.0, 1e-9);
    EXPECT_NEAR(b->boom->extension_m, 2.0, 1e-12);
    ASSERT_TRUE(b->stats);
  }
  std::string check;
  EXPECT_EQ(augrig("check " + out, &check), 0) << check;
}

TEST(CmdRecording, ReplayReportsADamagedFrameAndGoesOn) {
  const std::string bad = damaged_copy("cmd_recording_replay_damaged");
  std::string log;
  ASSERT_EQ(augrig("replay " + bad, &log), 1) << log;
  EXPECT_NE(log.find("augrig replay: " + bad + "/recording.sqlite: frame 3: left raw blob"),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("Replayed 7 stereo frame(s)"), std::string::npos) << log;
  EXPECT_NE(log.find("augrig replay: 1 frame(s) could not be read (above); the others were replayed"),
            std::string::npos)
      << log;
}

TEST(CmdRecording, ReplayFlagErrors) {
  std::string log;
  const std::string r = recording();
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--rate 2 --fast", "--rate and --fast exclude each other"},
           {"--rate 0", "--rate: expected a number above 0, got '0'"},
           {"--rate abc", "--rate: expected a number, got 'abc'"},
           {"--seek -1", "--seek: expected seconds from the first frame (>= 0), got '-1'"},
           {"--seek 1 --from-frame 2", "--seek and --from-frame exclude each other"},
           {"--loop 0", "--loop: expected a whole number from 1 to 1000000, got '0'"},
           {"--every 2", "--every needs --out"},
           {"--receiver-draw solid", "--receiver-draw: expected one of mask, wireframe, translucent"},
           {"--bogus", "unknown option '--bogus'"},
       }) {
    EXPECT_EQ(augrig("replay " + r + " " + args, &log), 2) << args << "\n" << log;
    EXPECT_NE(log.find("augrig replay: " + message), std::string::npos) << args << "\n" << log;
    EXPECT_NE(log.find("(see augrig replay --help)"), std::string::npos) << log;
  }
  EXPECT_EQ(augrig("replay", &log), 2) << log;
  EXPECT_NE(log.find("expected DIR, got none"), std::string::npos) << log;
  EXPECT_EQ(augrig("replay " + output_dir("cmd_recording_replay_missing") + "/x", &log), 1) << log;
  EXPECT_NE(log.find("/x: no such file"), std::string::npos) << log;
  EXPECT_EQ(augrig("replay " + r + " --seek 100", &log), 1) << log;
  EXPECT_NE(log.find("no frame at or after t_ns"), std::string::npos) << log;
  EXPECT_EQ(augrig("replay " + r + " --from-frame 8", &log), 1) << log;
  EXPECT_NE(log.find("start frame 8 is past the last frame (8 frames)"), std::string::npos) << log;
}

TEST(CmdRecording, ReplaysAnExportedEurocFolderWithAScene) {
  const std::string dir = output_dir("cmd_recording_euroc_replay");
  std::string log;
  ASSERT_EQ(augrig("export " + recording() + " --format euroc " + dir + "/euroc --no-plot", &log), 0) << log;
  {
    std::ofstream rig(dir + "/rig.yaml");
    rig << rig_to_yaml(small_rig());
  }
  EXPECT_EQ(augrig("replay " + dir + "/euroc --rig " + dir + "/rig.yaml", &log), 2) << log;  // no --scene
  EXPECT_NE(log.find("--scene"), std::string::npos) << log;
  ASSERT_EQ(augrig("replay " + dir + "/euroc --rig " + dir + "/rig.yaml --scene " +
                       test::data_path("scenes/body.yaml") + " --record " + dir + "/rec",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("Replayed 8 stereo frame(s)"), std::string::npos) << log;
  // --from-frame and --seek choose where a EuRoC folder starts (frames are 33 ms apart).
  ASSERT_EQ(augrig("replay " + dir + "/euroc --rig " + dir + "/rig.yaml --scene " +
                       test::data_path("scenes/body.yaml") + " --from-frame 5 --headless",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("Replayed 3 stereo frame(s)"), std::string::npos) << log;
  ASSERT_EQ(augrig("replay " + dir + "/euroc --rig " + dir + "/rig.yaml --scene " +
                       test::data_path("scenes/body.yaml") + " --seek 0.1 --headless",
                   &log),
            0)
      << log;
  EXPECT_NE(log.find("Replayed 4 stereo frame(s)"), std::string::npos) << log;
  EXPECT_EQ(augrig("replay " + dir + "/euroc --rig " + dir + "/rig.yaml --scene " +
                       test::data_path("scenes/body.yaml") + " --from-frame 8",
                   &log),
            1)
      << log;
  EXPECT_NE(log.find("is past the last pair (8 pairs)"), std::string::npos) << log;
  // The raw frames that went through EuRoC PNGs come back bit for bit.
  auto src = recorder::RecordingReader::open(recording());
  auto dst = recorder::RecordingReader::open(dir + "/rec");
  ASSERT_TRUE(src && dst);
  ASSERT_EQ((*dst)->frame_count(), 8u);
  for (std::size_t i = 0; i < 8; ++i) {
    auto a = (*src)->read_frame(i, recorder::kPartRaw);
    auto b = (*dst)->read_frame(i, recorder::kPartRaw);
    ASSERT_TRUE(a && b);
    EXPECT_TRUE(pixels_equal(a->raw.left.image, b->raw.left.image)) << i;
    EXPECT_EQ(a->raw.right.t_ns, b->raw.right.t_ns) << i;
  }
}

// The rows of a stats.csv after its header (which must be there).
std::vector<std::string> stats_rows(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> rows;
  std::string l;
  EXPECT_TRUE(std::getline(in, l)) << path;
  EXPECT_EQ(l.rfind("t_ns,", 0), 0u) << path << ": " << l;
  while (std::getline(in, l)) rows.push_back(l);
  return rows;
}

// The rows of replays of consecutive ranges [from, from + frames), one after the other. `exit`:
// the exit status every part is expected to end with.
std::vector<std::string> replay_parts(const std::string& source, const std::string& args,
                                      const std::string& dir, const std::vector<std::pair<int, int>>& ranges,
                                      int exit = 0) {
  std::vector<std::string> rows;
  for (const auto& [from, frames] : ranges) {
    const std::string out = dir + "/part" + std::to_string(from);
    std::string log;
    EXPECT_EQ(augrig("replay " + source + " " + args + " --headless --from-frame " + std::to_string(from) +
                         " --frames " + std::to_string(frames) + " --out " + out,
                     &log),
              exit)
        << log;
    for (std::string& r : stats_rows(out + "/stats.csv")) rows.push_back(std::move(r));
  }
  return rows;
}

// A campaign's parts: replaying frames [A, A + N) gives exactly the whole replay's rows of those
// frames, so consecutive parts concatenate to the whole replay; also when a frame in a part cannot
// be read (the range ends in the recording, not after N augmented frames).
TEST(CmdRecording, ReplayFramesRangesConcatenateToTheWholeReplay) {
  const std::string dir = output_dir("cmd_recording_replay_frames");
  std::string log;
  ASSERT_EQ(augrig("replay " + recording() + " --headless --out " + dir + "/whole", &log), 0) << log;
  const std::vector<std::string> whole = stats_rows(dir + "/whole/stats.csv");
  ASSERT_EQ(whole.size(), 8u);
  // The last part asks for more frames than are left: it ends with the recording.
  EXPECT_EQ(replay_parts(recording(), "", dir, {{0, 3}, {3, 4}, {7, 5}}), whole);
  ASSERT_EQ(augrig("replay " + recording() + " --headless --from-frame 2 --frames 3", &log), 0) << log;
  EXPECT_NE(log.find("from frame 2 to 4,"), std::string::npos) << log;
  EXPECT_NE(log.find("Replayed 3 stereo frame(s)"), std::string::npos) << log;

  // Frame 3 damaged: the whole replay and the part holding it skip it, and no part reads into the next.
  const std::string bad = damaged_copy("cmd_recording_replay_frames_damaged");
  ASSERT_EQ(augrig("replay " + bad + " --headless --out " + dir + "/whole_damaged", &log), 1) << log;
  const std::vector<std::string> whole_damaged = stats_rows(dir + "/whole_damaged/stats.csv");
  ASSERT_EQ(whole_damaged.size(), 7u);
  std::vector<std::string> parts = replay_parts(bad, "", dir + "/damaged", {{0, 3}});
  for (std::string& r : replay_parts(bad, "", dir + "/damaged", {{3, 2}}, 1)) parts.push_back(std::move(r));
  for (std::string& r : replay_parts(bad, "", dir + "/damaged", {{5, 3}})) parts.push_back(std::move(r));
  EXPECT_EQ(parts, whole_damaged);

  EXPECT_EQ(augrig("replay " + recording() + " --frames 2 --loop 2", &log), 2) << log;
  EXPECT_NE(log.find("--frames and --loop exclude each other"), std::string::npos) << log;
  EXPECT_EQ(augrig("replay " + recording() + " --frames 0", &log), 2) << log;
  EXPECT_NE(log.find("--frames: expected a whole number"), std::string::npos) << log;
}

// A scripted boom's clock starts at the recording's first frame, not at the first frame replayed:
// parts of a replay (--from-frame) fly the boom where the whole replay does at each frame.
TEST(CmdRecording, AScriptedBoomKeepsTheRecordingsClockFromAnyStart) {
  const std::string dir = output_dir("cmd_recording_replay_script");
  {
    std::ofstream f(dir + "/boom.csv");
    f << "t_s,elevation_deg,azimuth_deg,extension_m\n0,24,-6,0.8\n0.25,34,6,3.2\n";
  }
  const std::string boom = "--boom script:" + dir + "/boom.csv";
  std::string log;
  ASSERT_EQ(augrig("replay " + recording() + " " + boom + " --headless --out " + dir + "/whole", &log), 0)
      << log;
  const std::vector<std::string> whole = stats_rows(dir + "/whole/stats.csv");
  ASSERT_EQ(whole.size(), 8u);
  // The boom moves: frame 3's counts are not frame 0's (with the clock from the first frame
  // replayed, the part from frame 3 would have frame 0's boom).
  auto counts = [](const std::string& row) { return row.substr(row.find(',')); };
  EXPECT_NE(counts(whole[3]), counts(whole[0]));
  EXPECT_NE(counts(whole[4]), counts(whole[1]));
  EXPECT_EQ(replay_parts(recording(), boom, dir, {{0, 3}, {3, 5}}), whole);

  // The same for a EuRoC folder (its first pair is the clock's origin).
  ASSERT_EQ(augrig("export " + recording() + " --format euroc " + dir + "/euroc --no-plot", &log), 0) << log;
  {
    std::ofstream rig(dir + "/rig.yaml");
    rig << rig_to_yaml(small_rig());
  }
  const std::string euroc_args =
      boom + " --rig " + dir + "/rig.yaml --scene " + test::data_path("scenes/body.yaml");
  ASSERT_EQ(
      augrig("replay " + dir + "/euroc " + euroc_args + " --headless --out " + dir + "/euroc_whole", &log), 0)
      << log;
  const std::vector<std::string> euroc_whole = stats_rows(dir + "/euroc_whole/stats.csv");
  ASSERT_EQ(euroc_whole.size(), 8u);
  EXPECT_NE(counts(euroc_whole[5]), counts(euroc_whole[0]));
  EXPECT_EQ(replay_parts(dir + "/euroc", euroc_args, dir + "/euroc_parts", {{0, 5}, {5, 3}}), euroc_whole);
}

const std::string& long_recording() {
  return test::recording_of_this_test("cmd_recording_long_", 60);
}

// A recording cut in half: replay said "Replayed 99" and exited 0 while the summary said 201. It
// must say what is missing and exit 1 (the export's half is in tests/app/cmd_export_test.cpp).
TEST(CmdRecording, ReplayOfATruncatedRecordingSaysWhatIsMissing) {
  const std::uintmax_t size = fs::file_size(long_recording() + "/recording.sqlite");
  const std::string half = truncated_copy(long_recording(), "cmd_recording_truncated", size / 2);
  std::string log;
  EXPECT_EQ(augrig("check " + half, &log), 1) << log;
  EXPECT_NE(log.find("the recording's summary says 60 frames were recorded"), std::string::npos) << log;

  ASSERT_EQ(augrig("replay " + half, &log), 1) << log;
  EXPECT_NE(log.find("the recording's summary says 60 frames were recorded"), std::string::npos) << log;
  EXPECT_NE(log.find("augrig replay: the recording is incomplete (above)"), std::string::npos) << log;
  // evaluate as replay: exit 1, or 0 with --allow-damaged (a campaign's shards), the damage said.
  ASSERT_EQ(augrig("evaluate " + half + " --out " + half + "/eval --no-plot", &log), 1) << log;
  EXPECT_NE(log.find("augrig evaluate: the recording is incomplete (above)"), std::string::npos) << log;
  ASSERT_EQ(augrig("evaluate " + half + " --out " + half + "/eval --no-plot --allow-damaged", &log), 0)
      << log;
  EXPECT_NE(log.find("the others were evaluated (--allow-damaged: the command succeeds)"), std::string::npos)
      << log;

  // Cut before the first frame: nothing to replay, and it says so with exit 1.
  const std::string head = truncated_copy(long_recording(), "cmd_recording_truncated_head", 3 * 65536);
  EXPECT_EQ(augrig("replay " + head, &log), 1) << log;
  EXPECT_EQ(log.find("Replayed"), std::string::npos) << log;
}

// A recording as schema 1 wrote it (no depth table, no shadow columns, no look table, schema_version
// 1): check, replay and export work as before; replay --record --ground-truth turns it into one
// holding the depth per frame.
TEST(CmdRecording, SchemaOneRecordingChecksReplaysAndExportsAndGainsDepthByReplay) {
  const std::string dir = output_dir("cmd_recording_schema1");
  fs::copy_file(recording() + "/recording.sqlite", dir + "/recording.sqlite");
  {
    auto d = recorder::Database::open(dir + "/recording.sqlite", SQLITE_OPEN_READWRITE);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->exec(
        "DROP TABLE depth; DROP TABLE look; UPDATE meta SET value = '1' WHERE key = 'schema_version'; "
        "DELETE FROM meta WHERE key = 'codec.depth'"));
    for (const std::string& c : recorder::frame_columns_added_after(1))
      ASSERT_TRUE(d->exec("ALTER TABLE frames DROP COLUMN " + c)) << c;
  }
  std::string log;
  ASSERT_EQ(augrig("check " + dir, &log), 0) << log;
  EXPECT_NE(log.find("schema version: 1"), std::string::npos) << log;
  EXPECT_NE(log.find("receiver depth: 0 frames (record with --ground-truth to store it)"), std::string::npos)
      << log;
  ASSERT_EQ(augrig("export " + dir + " --format euroc " + dir + "/export --no-plot 2>&1", &log), 0) << log;
  EXPECT_TRUE(fs::exists(dir + "/export/mav0/cam0/data.csv"));
  EXPECT_EQ(
      augrig("export " + dir + " --format euroc " + dir + "/export_gt --ground-truth --no-plot 2>&1", &log),
      1)
      << log;
  EXPECT_NE(log.find("frame 0 (pair_sequence 0) holds no receiver depth (8 of 8 frames hold none)"),
            std::string::npos)
      << log;
  ASSERT_EQ(augrig("replay " + dir + " --headless --record " + dir + "/gt --ground-truth 2>&1", &log), 0)
      << log;
  EXPECT_NE(log.find("Recorded statistics reproduced exactly (same pixel counts) in 8 of 8"),
            std::string::npos)
      << log;
  auto rd = recorder::RecordingReader::open(dir + "/gt");
  ASSERT_TRUE(rd) << rd.error().message;
  ASSERT_EQ((*rd)->frame_count(), 8u);
  for (std::size_t i = 0; i < 8; ++i) {
    auto f = (*rd)->read_frame(i);
    ASSERT_TRUE(f) << f.error().message;
    ASSERT_FALSE(f->receiver_depth[0].empty()) << i;
    ASSERT_FALSE(f->receiver_depth[1].empty()) << i;
    // Finite exactly where the re-recorded mask has the receiver bit.
    for (int c = 0; c < 2; ++c) {
      const DepthImage z = f->receiver_depth[c].image();
      const Image& m = f->mask[c];
      std::size_t mismatched = 0;
      for (int y = 0; y < m.height(); ++y)
        for (int x = 0; x < m.width(); ++x)
          mismatched += ((m.row(y)[x] & kMaskReceiver) != 0) != std::isfinite(z.at(x, y));
      EXPECT_EQ(mismatched, 0u) << "frame " << i << " camera " << c;
    }
  }
}

}  // namespace
}  // namespace augrig
