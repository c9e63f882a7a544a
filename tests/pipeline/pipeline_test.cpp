// The runtime pipeline: each source with each sink, pose providers, player controls through the
// LiveView mailbox, stop conditions, and the ledger adding up (read = 2 x pairs + every row).
#include "pipeline/pipeline.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <thread>

#include <gtest/gtest.h>

#include "nav/logs.hpp"
#include "recorder/plot.hpp"
#include "recorder/reader.hpp"
#include "recorder/replay_source.hpp"
#include "sim/flight_source.hpp"
#include "tests/support/test_support.hpp"
#include "tests/support/pipeline_parts.hpp"

namespace augrig::pipeline {
namespace {

namespace fs = std::filesystem;

const std::string kScenario = "sim://" + test::data_path("scenarios/short_approach.yaml");

// A pipeline over `uri` with the simulation's truth (sim://) or the recorded poses (replay://).
PipelineParts parts_for(const std::string& uri) { return test::pipeline_parts(uri); }

// Every frame read is in a pair or a ledger row.
void expect_ledger_adds_up(const PipelineReport& r) {
  const StereoSourceStats& st = r.source;
  const std::uint64_t read = st.frames[0] + st.frames[1];
  const std::uint64_t accounted = 2 * (r.pairs + r.failed_pairs + r.skipped_no_pose + r.seek_skipped_pairs) +
                                  st.pairing.unpaired_left + st.pairing.unpaired_right + st.queue_drops[0] +
                                  st.queue_drops[1] + st.pending.count;
  EXPECT_EQ(read, accounted) << "pairs " << r.pairs << " unpaired " << st.pairing.unpaired_left << "+"
                             << st.pairing.unpaired_right << " pending " << st.pending.count;
}

std::size_t csv_rows(const fs::path& path) {
  std::ifstream in(path);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') ++n;
  return n;  // header included
}

std::size_t files_in(const fs::path& dir) {
  if (!fs::exists(dir)) return 0;
  return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), fs::directory_iterator()));
}

// The simulated flight into every sink at once, then its recording replayed through the same
// pipeline with the recorded poses: every pair reproduces the recorded statistics.
TEST(Pipeline, SimIntoEverySinkThenReplayReproducesIt) {
  const fs::path dir = test::output_dir("pipeline_every_sink");
  fs::remove_all(dir);
  fs::create_directories(dir);
  PipelineParts p = parts_for(kScenario + "?every=3&rate=0");
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(p.rig);
  auto rec = recorder::Recorder::create((dir / "rec").string(), info);
  ASSERT_TRUE(rec) << rec.error().message;
  p.recorder = std::move(*rec);
  auto csv = StatsCsvWriter::create(dir / "stats.csv");
  ASSERT_TRUE(csv) << csv.error().message;
  p.stats_csv = std::move(*csv);
  p.frame_files = FrameFiles{dir / "frames", 5, {}};
  p.view = std::make_shared<LiveView>();
  p.max_pairs = 12;
  const std::shared_ptr<LiveView> view = p.view;
  // A window stand-in: takes every pair it can and checks what it gets.
  std::atomic<std::uint64_t> taken{0};
  std::atomic<bool> whole{true};
  std::thread window([&] {
    LiveView::Shown shown;
    while (!view->finished()) {
      const std::uint64_t before = shown.id;
      view->take_newest(shown);
      if (shown.id != before) {
        ++taken;
        // The window gets whole augmented images, the raw frame's size.
        whole =
            whole && shown.result.left.augmented.width() == 1280 && shown.result.left.mask.width() == 1280;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });
  Pipeline pipeline(std::move(p));
  std::ostringstream out, err;
  auto r = pipeline.run(out, err);
  window.join();
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->pairs, 12u);
  EXPECT_EQ(r->failed_pairs, 0u) << err.str();
  expect_ledger_adds_up(*r);
  EXPECT_GT(taken.load(), 0u);
  EXPECT_TRUE(whole.load());
  EXPECT_TRUE(view->hud().occlusion.has_value()) << "the HUD's occlusion panel is filled";
  ASSERT_TRUE(r->recording_closed && *r->recording_closed);
  EXPECT_EQ(r->recorder_stats.frames_committed, 12u);
  EXPECT_EQ(csv_rows(dir / "stats.csv"), 13u);
  EXPECT_EQ(files_in(dir / "frames" / "left" / "mask"), 3u);  // pairs 1, 6 and 11
  std::ostringstream summary;
  pipeline.print_summary(*r, summary);
  EXPECT_NE(summary.str().find("run: 12 stereo frames augmented"), std::string::npos) << summary.str();
  // Time per stage for every pair augmented, and printed.
  EXPECT_EQ(r->stage_augment.count, 12u);
  EXPECT_EQ(r->stage_sinks.count, 12u);
  EXPECT_GT(r->stage_augment.p50_abs_ns(), 0);
  EXPECT_NE(summary.str().find("stages per pair, p50 / p99 ms: "), std::string::npos) << summary.str();

  // The recording back through the pipeline: the recorded poses drive it.
  PipelineParts q = parts_for("replay://" + (dir / "rec").string() + "?rate=fast");
  Pipeline replay(std::move(q));
  auto rr = replay.run(out, err);
  ASSERT_TRUE(rr) << rr.error().message;
  EXPECT_EQ(rr->pairs, 12u);
  EXPECT_EQ(rr->comparable, 12u);
  EXPECT_EQ(rr->reproduced, 12u) << "same pixel counts as recorded";
  EXPECT_EQ(rr->source.pairing.unpaired_left + rr->source.pairing.unpaired_right, 0u);
  expect_ledger_adds_up(*rr);
}

// The window's HUD shows the recorder's latency from mid-exposure (it was never filled: the HUD said
// "-" all run long). A paced flight, so that its frames have host times.
TEST(Pipeline, TheHudShowsTheRecordersLatency) {
  const fs::path dir = test::output_dir("pipeline_hud_recorder");
  fs::remove_all(dir);
  PipelineParts p = parts_for(kScenario + "?every=3");
  auto rec = recorder::Recorder::create((dir / "rec").string(), recorder::RecordingInfo{});
  ASSERT_TRUE(rec) << rec.error().message;
  p.recorder = std::move(*rec);
  p.view = std::make_shared<LiveView>();
  p.max_pairs = 6;
  const std::shared_ptr<LiveView> view = p.view;
  Pipeline pipeline(std::move(p));
  std::ostringstream out, err;
  auto r = pipeline.run(out, err);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->recorder_latency.count, 6u);
  const LatencyHud hud = view->hud().latency_recorder;
  ASSERT_FALSE(std::isnan(hud.p50_ms)) << "the HUD's recorder latency is filled";
  EXPECT_GT(hud.p50_ms, 0.0);
  EXPECT_LT(hud.p50_ms, 10'000.0);
}

// A recording played in a loop pairs again on every pass, though time goes back at each loop.
TEST(Pipeline, ReplayLoopsPairOnEveryPass) {
  const fs::path dir = test::output_dir("pipeline_loop");
  fs::remove_all(dir);
  PipelineParts p = parts_for(kScenario + "?every=6&rate=0");
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(p.rig);
  p.recorder = std::move(recorder::Recorder::create((dir / "rec").string(), info).value());
  p.max_pairs = 4;
  {
    Pipeline pipeline(std::move(p));
    std::ostringstream out, err;
    ASSERT_TRUE(pipeline.run(out, err));
  }
  Pipeline replay(parts_for("replay://" + (dir / "rec").string() + "?rate=fast&passes=3"));
  std::ostringstream out, err;
  auto r = replay.run(out, err);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->pairs, 12u);
  EXPECT_EQ(r->reproduced, 12u);
  expect_ledger_adds_up(*r);
}

// The player's controls through the mailbox, as the window's timeline uses them: pause holds the
// playback, a seek jumps to a recorded frame, steps advance one frame each.
TEST(Pipeline, ReplayPauseSeekAndStepFromTheView) {
  const fs::path dir = test::output_dir("pipeline_player");
  fs::remove_all(dir);
  {
    PipelineParts p = parts_for(kScenario + "?every=3&rate=0");
    recorder::RecordingInfo info;
    info.rig_yaml = rig_to_yaml(p.rig);
    p.recorder = std::move(recorder::Recorder::create((dir / "rec").string(), info).value());
    p.max_pairs = 15;
    Pipeline pipeline(std::move(p));
    std::ostringstream out, err;
    ASSERT_TRUE(pipeline.run(out, err));
  }
  PipelineParts q = parts_for("replay://" + (dir / "rec").string() + "?rate=2&late=keep");
  q.view = std::make_shared<LiveView>();
  const std::shared_ptr<LiveView> view = q.view;
  std::atomic<bool> stop{false};
  q.stop_flag = &stop;
  Pipeline pipeline(std::move(q));
  std::optional<Expected<PipelineReport>> result;
  std::ostringstream out, err;
  std::thread runner([&] { result = pipeline.run(out, err); });

  auto wait_for = [&](auto pred) {
    for (int i = 0; i < 1000 && !pred(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    return pred();
  };
  auto frame_shown = [&] {
    auto pb = view->playback();
    return pb ? std::optional<std::size_t>(pb->frame) : std::nullopt;
  };
  ASSERT_TRUE(wait_for([&] { return view->playback() && view->playback()->frame >= 1; }));
  PipelineCommands pause;
  pause.toggle_pause = true;
  view->post(pause);
  ASSERT_TRUE(wait_for([&] { return view->hud().paused; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const std::optional<std::size_t> held = frame_shown();
  std::this_thread::sleep_for(std::chrono::milliseconds(600));  // 2x real rate: ~4 frames would pass
  EXPECT_EQ(frame_shown(), held) << "paused: the playback holds";

  PipelineCommands seek;
  seek.seek_frame = 11;
  view->post(seek);
  EXPECT_TRUE(wait_for([&] { return frame_shown() == std::optional<std::size_t>(11); }));
  PipelineCommands step;
  step.steps = 2;
  view->post(step);
  EXPECT_TRUE(wait_for([&] { return frame_shown() == std::optional<std::size_t>(13); }));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(frame_shown(), std::optional<std::size_t>(13)) << "two steps, then held again";
  // The rate control: the playback reports the rate in force.
  PipelineCommands rate;
  rate.rate = 4.0;
  view->post(rate);
  EXPECT_TRUE(wait_for([&] { return view->playback() && view->playback()->rate == 4.0; }));
  // A seek back in time.
  seek.seek_frame = 2;
  view->post(seek);
  EXPECT_TRUE(wait_for([&] { return frame_shown() == std::optional<std::size_t>(2); }));
  stop = true;
  runner.join();
  ASSERT_TRUE(result && *result) << (result ? result->error().message : "no result");
  EXPECT_TRUE((*result)->stopped_by_signal);
  expect_ledger_adds_up(**result);
}

// A rig whose cameras are not the frames' size fails at the first frame, once, naming both sizes.
// A simulated flight's phases become events "phase: NAME" at the first pair of each phase, on the
// statistics' clock, printed and recorded (the export's plot marks them). The oracle: the
// simulator's own truth of each delivered frame (sim::frame_truths, Flight::phase).
TEST(Pipeline, SimPhasesAreRecordedAtTheirFirstPair) {
  const fs::path dir = test::output_dir("pipeline_phases");
  fs::remove_all(dir);
  fs::create_directories(dir);
  PipelineParts p = parts_for(kScenario + "?every=3&rate=0");
  const std::shared_ptr<const SimulatedFlight> sim = p.source_info.sim;
  ASSERT_TRUE(sim);
  std::map<TimestampNs, std::string> phase_at;  // left frame time -> the truth's phase
  for (const sim::FrameTruth& f : sim::frame_truths(sim->scenario, *sim->flight, sim->logs.cameras))
    if (f.camera == 0) phase_at[f.t_camera_ns] = sim->flight->phase(f.t_true_s);
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(p.rig);
  auto rec = recorder::Recorder::create((dir / "rec").string(), info);
  ASSERT_TRUE(rec) << rec.error().message;
  p.recorder = std::move(*rec);
  std::vector<recorder::PhaseEvent> expected;
  p.on_pair = [&](const StereoFrame& raw, const StereoResult& r, const SceneState&,
                  const FramePoses&) -> Status {
    const auto it = phase_at.find(raw.left.t_ns);
    EXPECT_NE(it, phase_at.end());
    if (it != phase_at.end() && (expected.empty() || expected.back().name != it->second))
      expected.push_back({r.stats.t_ns, it->second});
    return {};
  };
  Pipeline pipeline(std::move(p));
  std::ostringstream out, err;
  auto r = pipeline.run(out, err);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_GE(r->pairs, 15u);
  ASSERT_EQ(expected.size(), 2u) << "the flight passes from pre-contact to to-contact at 1 s";
  EXPECT_EQ(expected[0].name, "pre-contact");
  EXPECT_EQ(expected[1].name, "to-contact");
  EXPECT_NE(out.str().find("phase: to-contact from pair "), std::string::npos) << out.str();
  auto reader = recorder::RecordingReader::open((dir / "rec").string());
  ASSERT_TRUE(reader) << reader.error().message;
  auto events = (*reader)->events();
  ASSERT_TRUE(events) << events.error().message;
  const std::vector<recorder::PhaseEvent> got = recorder::phase_events(*events);
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(got[k].name, expected[k].name);
    EXPECT_EQ(got[k].t_ns, expected[k].t_ns) << "at the first pair of the phase, on the statistics' clock";
  }

  // Re-augmented by a replay into a new recording, the recording keeps its phases.
  PipelineParts q = parts_for("replay://" + (dir / "rec").string() + "?rate=fast");
  auto rec2 = recorder::Recorder::create((dir / "rec2").string(), info);
  ASSERT_TRUE(rec2) << rec2.error().message;
  q.recorder = std::move(*rec2);
  Pipeline replay(std::move(q));
  auto rr = replay.run(out, err);
  ASSERT_TRUE(rr) << rr.error().message;
  auto reader2 = recorder::RecordingReader::open((dir / "rec2").string());
  ASSERT_TRUE(reader2) << reader2.error().message;
  const std::vector<recorder::PhaseEvent> again = recorder::phase_events((*reader2)->events().value());
  ASSERT_EQ(again.size(), expected.size());
  for (std::size_t k = 0; k < again.size(); ++k) {
    EXPECT_EQ(again[k].name, expected[k].name);
    EXPECT_EQ(again[k].t_ns, expected[k].t_ns);
  }
}

// The camera look's updates go into the recording's look table as they come, not per frame: the
// light each time it is measured anew on the receiver (a pair every 0.5 s of frame time), each row
// stamped with a recorded pair's time and clock, the same update never twice in a row; the noise
// level functions likewise (this flight's textured frames give the estimator nothing: none; the
// noise rows are look_updates_test's). The plain look records none.
TEST(Pipeline, CameraLookUpdatesAreRecordedAsTheyCome) {
  const fs::path dir = test::output_dir("pipeline_look_updates");
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (Look look : {Look::kCamera, Look::kPlain}) {
    const std::string name = look == Look::kCamera ? "camera" : "plain";
    SCOPED_TRACE(name);
    PipelineParts p = parts_for(kScenario + "?every=3&rate=0");
    p.augment.look = look;
    recorder::RecordingInfo info;
    info.rig_yaml = rig_to_yaml(p.rig);
    auto rec = recorder::Recorder::create((dir / name).string(), info);
    ASSERT_TRUE(rec) << rec.error().message;
    p.recorder = std::move(*rec);
    Pipeline pipeline(std::move(p));
    std::ostringstream out, err;
    auto r = pipeline.run(out, err);
    ASSERT_TRUE(r) << r.error().message;
    ASSERT_GE(r->pairs, 15u) << err.str();
    ASSERT_TRUE(r->recording_closed && *r->recording_closed);
    auto reader = recorder::RecordingReader::open((dir / name).string());
    ASSERT_TRUE(reader) << reader.error().message;
    auto rows = (*reader)->look();
    ASSERT_TRUE(rows) << rows.error().message;
    if (look == Look::kPlain) {
      EXPECT_TRUE(rows->empty());
      continue;
    }
    std::map<TimestampNs, ClockDomain> pairs;  // t_key_ns -> the left camera's clock
    for (std::size_t i = 0; i < (*reader)->frame_count(); ++i) {
      auto f = (*reader)->read_frame_info(i);
      ASSERT_TRUE(f) << f.error().message;
      pairs[f->raw.t_key_ns] = f->raw.left.clock;
    }
    std::size_t noise[2] = {0, 0}, light = 0;
    std::optional<recorder::LookLight> last_light;
    std::optional<NoiseLevelFunction> last_noise[2];
    for (const recorder::LookRecord& u : *rows) {
      const auto at = pairs.find(u.t_ns);
      ASSERT_NE(at, pairs.end()) << "t_ns " << u.t_ns << " is no recorded pair's";
      EXPECT_EQ(u.clock, at->second);
      if (const auto* n = std::get_if<recorder::LookNoise>(&u.update)) {
        ASSERT_GE(n->camera, 0);
        ASSERT_LT(n->camera, 2);
        EXPECT_FALSE(n->configured);
        EXPECT_GT(n->frames, 0u);
        EXPECT_TRUE(n->nlf.channels == 1 || n->nlf.channels == 3);
        EXPECT_FALSE(last_noise[n->camera] && *last_noise[n->camera] == n->nlf) << "the same estimate twice";
        last_noise[n->camera] = n->nlf;
        ++noise[n->camera];
      } else {
        const auto& l = std::get<recorder::LookLight>(u.update);
        EXPECT_GT(l.samples, 0u);
        EXPECT_NEAR(l.towards_sun_body.norm(), 1.0, 1e-9);
        EXPECT_NE(l.source, LightSource::kFixed);
        EXPECT_FALSE(last_light && last_light->direct == l.direct && last_light->sky == l.sky &&
                     last_light->ground == l.ground && last_light->samples == l.samples && last_light->rms == l.rms)
            << "the same fit twice";
        last_light = l;
        ++light;
      }
    }
    EXPECT_GE(light, 1u) << "the receiver in view is measured";
    EXPECT_LT(rows->size(), r->pairs) << "updates, not rows per frame";
    EXPECT_EQ(noise[0], noise[1]) << "both cameras estimated at the same pairs";
    const recorder::CheckReport check = (*reader)->check();
    EXPECT_EQ(check.look_noise, noise[0] + noise[1]);
    EXPECT_EQ(check.look_light, light);
  }
}

// Capture only: the pairs recorded raw with their poses, nothing augmented (no augmented images,
// masks or statistics, no GL), every frame accounted for; the recording then augments in a replay
// with its recorded poses, the boom tracking the receptacle (no boom was recorded). A rig without a
// boom section captures but refuses to augment.
TEST(Pipeline, CaptureOnlyRecordsRawAndAugmentsLater) {
  const fs::path dir = test::output_dir("pipeline_capture_only");
  fs::remove_all(dir);
  fs::create_directories(dir);
  PipelineParts p = parts_for(kScenario + "?every=3&rate=0");
  Rig capture_rig = p.rig;
  capture_rig.boom.configured = false;
  p.rig = capture_rig;
  p.capture_only = true;
  recorder::RecordingInfo info;
  info.rig_yaml = rig_to_yaml(p.rig);
  auto rec = recorder::Recorder::create((dir / "rec").string(), info);
  ASSERT_TRUE(rec) << rec.error().message;
  p.recorder = std::move(*rec);
  p.max_pairs = 10;
  Pipeline pipeline(std::move(p));
  std::ostringstream out, err;
  auto r = pipeline.run(out, err);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->pairs, 10u);
  EXPECT_EQ(r->stage_augment.count, 0u) << "nothing augmented";
  EXPECT_FALSE(r->last_stats);
  expect_ledger_adds_up(*r);
  std::ostringstream summary;
  pipeline.print_summary(*r, summary);
  EXPECT_NE(summary.str().find("10 stereo frames captured (not augmented)"), std::string::npos)
      << summary.str();
  ASSERT_TRUE(r->recording_closed && *r->recording_closed);
  auto reader = recorder::RecordingReader::open((dir / "rec").string());
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_EQ((*reader)->frame_count(), 10u);
  for (std::size_t i = 0; i < 10; ++i) {
    auto f = (*reader)->read_frame(i);
    ASSERT_TRUE(f) << f.error().message;
    EXPECT_EQ(f->raw.left.image.width(), 1280);
    EXPECT_TRUE(f->augmented[0].empty() && f->augmented[1].empty() && !f->augmented_box[0]);
    EXPECT_TRUE(f->mask[0].empty() && f->mask[1].empty());
    EXPECT_FALSE(f->stats);
    EXPECT_FALSE(f->boom);
    EXPECT_TRUE(f->T_body_receiver && f->T_cam_receiver[0] && f->T_cam_receiver[1]) << "the truth's poses";
  }
  // The capture-only rig cannot augment the recording...
  {
    PipelineParts q = parts_for("replay://" + (dir / "rec").string() + "?rate=fast");
    EXPECT_FALSE(q.rig.boom.configured) << "the recorded rig";
    Pipeline replay(std::move(q));
    auto rr = replay.run(out, err);
    ASSERT_FALSE(rr);
    EXPECT_NE(rr.error().message.find("no boom section: a capture-only rig"), std::string::npos)
        << rr.error().message;
  }
  // ...a rig with a boom does, from the recorded poses, the boom tracking the receptacle.
  PipelineParts q = parts_for("replay://" + (dir / "rec").string() + "?rate=fast");
  q.rig.boom = Rig::paper_default().boom;
  q.poses = recorded_poses(q.rig);
  q.keep_all_stats = true;
  Pipeline replay(std::move(q));
  auto rr = replay.run(out, err);
  ASSERT_TRUE(rr) << rr.error().message;
  EXPECT_EQ(rr->pairs, 10u);
  EXPECT_EQ(rr->no_pose_pairs, 0u);
  ASSERT_EQ(rr->all_stats.size(), 10u);
  for (const OcclusionStats& st : rr->all_stats) {
    EXPECT_GT(st.boom_px_left, 0);
    EXPECT_GT(st.receiver_px_left, 0);
  }
}

TEST(Pipeline, FrameSizeNotTheRigsFailsAtTheFirstFrame) {
  PipelineParts p = parts_for(kScenario + "?every=3&rate=0");
  p.rig.cameras[0].model = CameraModel::pinhole_from_hfov(640, 480, 0.8);
  std::ostringstream out, err;
  Pipeline pipeline(std::move(p));
  auto r = pipeline.run(out, err);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("the left image is 1280x960, the rig's"), std::string::npos)
      << r.error().message;
  EXPECT_NE(r.error().message.find("camera is 640x480"), std::string::npos) << r.error().message;
  EXPECT_EQ(err.str(), "") << "one message, not one per frame";
}

// Poses from `augrig nav`'s CSV give the same masks as the truth they were written from; frames
// without a row are augmented with the boom alone, or skipped when asked, and counted either way.
TEST(Pipeline, PosesCsvDrivesTheAugmentation) {
  const fs::path dir = test::output_dir("pipeline_poses_csv");
  fs::remove_all(dir);
  fs::create_directories(dir);
  auto opened = open_sources(kScenario + "?every=3&rate=0");
  ASSERT_TRUE(opened);
  const SimulatedFlight& sim = *opened->sim;
  // Left-camera rows of the truth, every other frame only, without the boom (so it tracks).
  std::vector<nav::CameraPoseRow> rows;
  int k = 0;
  for (const sim::FrameTruth& f : sim::frame_truths(sim.scenario, *sim.flight, sim.logs.cameras)) {
    if (f.camera != 0 || f.sequence % 3 || (k++ % 2)) continue;
    nav::CameraPoseRow r = sim::pose_row(f);
    r.boom_elevation_deg = r.boom_azimuth_deg = r.boom_extension_m = nav::CameraPoseRow::kNaN;
    rows.push_back(r);
  }
  ASSERT_GT(rows.size(), 4u);
  ASSERT_TRUE(nav::write_camera_pose_csv((dir / "poses.csv").string(), rows));

  auto run = [&](bool csv_poses, bool skip) {
    PipelineParts p = parts_for(kScenario + "?every=3&rate=0");
    if (csv_poses) {
      auto provider = poses_csv((dir / "poses.csv").string(), p.rig, 0);
      EXPECT_TRUE(provider) << provider.error().message;
      p.poses = std::move(*provider);
    }
    p.skip_frames_without_pose = skip;
    p.keep_all_stats = true;
    p.max_pairs = 6;
    Pipeline pipeline(std::move(p));
    std::ostringstream out, err;
    auto r = pipeline.run(out, err);
    EXPECT_TRUE(r) << r.error().message;
    return *r;
  };
  const PipelineReport truth = run(false, false), csv = run(true, false), skipped = run(true, true);
  // Boom only where the CSV has no row: every other pair.
  EXPECT_EQ(csv.no_pose_pairs, 3u);
  EXPECT_EQ(skipped.skipped_no_pose, 5u) << "skipping: 6 with a pose augmented, the 5 between them skipped";
  EXPECT_EQ(skipped.pairs, 6u);
  expect_ledger_adds_up(skipped);
  // Where the CSV has the pose, the masks are the truth's.
  for (std::size_t i = 0; i < csv.all_stats.size(); i += 2) {
    EXPECT_EQ(csv.all_stats[i].receiver_px_left, truth.all_stats[i].receiver_px_left) << i;
    EXPECT_EQ(csv.all_stats[i].occluded_px_left, truth.all_stats[i].occluded_px_left) << i;
    EXPECT_EQ(csv.all_stats[i].boom_px_right, truth.all_stats[i].boom_px_right) << i;
  }
  EXPECT_EQ(csv.all_stats[1].receiver_px_left, 0) << "no pose: no receiver in the masks";
}

// Runs `p` until a "signal" that comes with the third pair, after holding the pipeline for `hold`
// (the cameras go on meanwhile); `seen` counts the pairs that reached the sinks, `summary` gets
// the run's output and its summary.
Expected<PipelineReport> run_signalled_at_third_pair(PipelineParts p, std::chrono::milliseconds hold,
                                                     int& seen, std::string& summary) {
  std::atomic<bool> stop{false};
  p.stop_flag = &stop;
  p.on_pair = [&](const StereoFrame&, const StereoResult&, const SceneState&, const FramePoses&) -> Status {
    if (++seen == 3) {
      std::this_thread::sleep_for(hold);
      stop = true;
    }
    return {};
  };
  Pipeline pipeline(std::move(p));
  std::ostringstream out, err;
  auto r = pipeline.run(out, err);
  if (r) pipeline.print_summary(*r, out);
  summary = out.str();
  return r;
}

// A stop by signal mid-run of a lossless source: whatever it had queued beyond the third pair is
// counted as pending (it is still in its file), and it adds up.
TEST(Pipeline, StopFlagEndsTheRunAndTheLedgerAddsUp) {
  int seen = 0;
  std::string summary;
  auto r = run_signalled_at_third_pair(parts_for(kScenario + "?every=1&rate=0"), std::chrono::milliseconds(0),
                                       seen, summary);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_TRUE(r->stopped_by_signal);
  EXPECT_EQ(r->pairs, 3u);
  EXPECT_EQ(r->pairs_after_stop, 0u);
  expect_ledger_adds_up(*r);
}

// A live source stopped (by a signal here; the duration and the window stop the same way): what
// the cameras had delivered before the stop is still augmented, so that only a frame whose partner
// never came can stay pending. The simulated cameras run paced (rate 1: live, not lossless); the
// pipeline holds at the third pair, so frames queue up behind it.
TEST(Pipeline, ALiveStopStillAugmentsWhatTheCamerasHadDelivered) {
  PipelineParts p = parts_for(kScenario + "?every=1&rate=1");
  ASSERT_FALSE(p.source->lossless());
  int seen = 0;
  std::string summary;
  auto r = run_signalled_at_third_pair(std::move(p), std::chrono::milliseconds(300), seen, summary);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_TRUE(r->stopped_by_signal);
  EXPECT_GE(r->pairs_after_stop, 1u) << summary;
  EXPECT_EQ(r->pairs, 3u + r->pairs_after_stop);
  EXPECT_EQ(static_cast<std::uint64_t>(seen), r->pairs) << "every pair after the stop went to the sinks";
  // One source delivers left then right: a stop between the two leaves at most the left pending.
  EXPECT_LE(r->source.pending.count, 1u) << summary;
  expect_ledger_adds_up(*r);
  EXPECT_NE(summary.find("stop: " + std::to_string(r->pairs_after_stop) + " pair(s)"), std::string::npos)
      << summary;
}

}  // namespace
}  // namespace augrig::pipeline
