// The commands on recordings (docs/REPLAY.md, docs/RECORDING.md):
//   augrig check DIR                      what a recording holds and what is damaged (exit 1 if any);
//   augrig replay DIR [options]           the recorded raw frames through the Augmenter again, with
//                                         the recorded rig and scene or others: stats.csv, images;
// A recording is opened (and so checked to be one) before anything else is done; damaged frames
// are reported one line each on stderr and skipped, and the command then exits 1.
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "app/cli.hpp"
#include "app/window_runner.hpp"
#include "pipeline/scene_file.hpp"
#include "pipeline/sources.hpp"
#include "recorder/mcap_source.hpp"
#include "recorder/reader.hpp"
#include "recorder/recorder.hpp"
#include "recorder/replay_source.hpp"

namespace augrig::app {
namespace {

// ---- check --------------------------------------------------------------------------------------

int check_command(const std::vector<std::string>& args, std::ostream& out) {
  static const std::vector<OptionSpec> specs;
  std::vector<std::string> pos;
  const ParsedArgs a = parse_with_positionals(args, specs, {"DIR"}, pos);
  if (a.help) {
    out << format_help(
        "augrig check DIR",
        "Reads every frame of a recording and decodes every image (sizes, checksums), runs SQLite's\n"
        "integrity check and prints what the recording holds and what is damaged. Exit 0 when\n"
        "everything reads, 1 when something is damaged or the folder is no recording.",
        specs);
    return kExitOk;
  }
  const auto reader = open_recording(pos[0]);
  const recorder::CheckReport report = reader->check();
  const std::string text = report.to_string();
  out << text;
  if (!text.empty() && text.back() != '\n') out << "\n";
  return report.ok() ? kExitOk : kExitRuntime;
}

// ---- replay -------------------------------------------------------------------------------------

const std::vector<OptionSpec>& replay_specs() {
  static const std::vector<OptionSpec> specs = {
      {"rate", ArgKind::kValue, "X",
       "real rate: recorded time runs X times as fast as wall time (1: as recorded)"},
      {"fast", ArgKind::kFlag, "", "as fast as the augmenter goes, every frame (the default)"},
      {"seek", ArgKind::kValue, "T_S", "start at the first frame T_S seconds or more after the first frame"},
      {"from-frame", ArgKind::kValue, "N", "start at frame N (0: the first)"},
      {"frames", ArgKind::kValue, "N",
       "replay N stereo frames from the start (frames START..START+N-1 of a recording or EuRoC folder, "
       "whatever in them is skipped; not with --loop)"},
      {"loop", ArgKind::kValue, "N", "play the range N times in all (default 1)"},
      {"out", ArgKind::kValue, "DIR", "write stats.csv and the images of every --every-th frame here"},
      {"every", ArgKind::kValue, "K", "with --out: images of every K-th replayed frame (default 30)"},
      {"ground-truth", ArgKind::kFlag, "",
       "with --out: " + std::string(kGroundTruthHelp) +
           "; with --record: store each frame's receiver depth in the new recording (export --ground-truth "
           "writes the rest from it)"},
      rig_option("the recorded rig"),
      scene_option("each frame's recorded boom and receiver pose"),
      poses_option(
          "e.g. fused from the logs an export of this recording wrote; the boom tracks the receptacle "
          "unless --boom"),
      pose_tolerance_option(),
      receiver_draw_option(),
      look_option(),
      sink_option(),
      boom_option("the recorded boom; track where none was recorded"),
      {"record", ArgKind::kValue, "DIR", "record the re-augmented run (a new recording, docs/RECORDING.md)"},
      {"overwrite", ArgKind::kFlag, "", "with --record: replace a recording already in DIR"},
      {"headless", ArgKind::kFlag, "", "no window even when a display is present"},
      {"screenshot-at", ArgKind::kValue, "N",
       "with the window: a screenshot once the N-th pair is shown (into --out)"},
      {"status-every", ArgKind::kValue, "S", "print a status line every S seconds (default 0: never)"},
      {"pair-tolerance-ns", ArgKind::kValue, "NS",
       "EuRoC folders: pair left and right frames whose timestamps differ by at most NS (default 0)"},
      allow_damaged_option(),
  };
  return specs;
}

// --every K (default 30).
int replay_every(const ParsedArgs& a) {
  return a.has("every") ? static_cast<int>(parse_integer("every", a.get("every"), 1, 1000000)) : 30;
}

// --frames N: how many stereo frames from the start (0: to the end). Not with --loop: a pass
// that ends after N frames would make "N frames" mean two things.
std::size_t replay_frames(const ParsedArgs& a) {
  if (!a.has("frames")) return 0;
  if (a.has("loop")) usage_error("--frames and --loop exclude each other (--frames N replays N frames once)");
  return static_cast<std::size_t>(parse_integer("frames", a.get("frames"), 1, 1LL << 40));
}

// Where a replay's poses come from, for its banner.
std::string replay_poses_text(const ParsedArgs& a) {
  return a.has("scene")   ? "scene " + a.get("scene")
         : a.has("poses") ? "poses " + a.get("poses")
                          : std::string("scene as recorded per frame");
}

// What every replay (a recording, an MCAP file, a EuRoC folder) configures the same way from its
// flags once its source is open: the rig (--rig, else the one stored with the frames), its models,
// the poses (--scene, --poses, else those recorded per frame), the boom, the receiver drawing,
// --out's files, --record's new recording (`from` in its metadata and in messages), the window.
struct ReplayConfig {
  std::string from;                     // the recording's path, the MCAP file, euroc://DIR
  std::optional<Rig> stored_rig;        // the rig stored with the frames
  bool paper_rig_by_default = false;    // none stored: the paper's (a EuRoC folder) rather than an error
  bool recorded_poses = true;           // the frames carry their scene (not a EuRoC folder)
  std::string clock_domains;            // for the new recording's metadata
  const AddSinks* add_sinks = nullptr;  // the calling command's own sinks (replay_into)
  std::string replayed = {};            // a recording replayed: its path (a sink's nav option)
};
void configure_replay(PipelineParts& parts, const ParsedArgs& a, const ReplayConfig& c) {
  if (!a.has("rig") && !c.stored_rig && !c.paper_rig_by_default)
    runtime_error(c.from + ": no rig is stored with the frames; give one with --rig");
  parts.rig = a.has("rig") ? load_rig_arg(a.get("rig")) : c.stored_rig ? *c.stored_rig : Rig::paper_default();
  if (parts.rig.cameras.size() != 2)
    runtime_error(parts.rig.source + ": the rig needs 2 cameras, has " +
                  std::to_string(parts.rig.cameras.size()));
  parts.models = unwrap(load_rig_models(parts.rig));
  parts.augment.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  apply_look_arg(a, parts.rig, parts.augment);
  apply_sink_args(a, parts, c.replayed);
  if (c.add_sinks && *c.add_sinks) (*c.add_sinks)(parts);
  if (a.has("scene") && a.has("poses")) usage_error("--scene and --poses are two sources of poses: give one");
  if (a.has("pose-tolerance-ms") && !a.has("poses")) usage_error("--pose-tolerance-ms needs --poses");
  PoseSources ps;
  ps.scene_path = a.get("scene", "");
  ps.poses_csv_path = a.get("poses", "");
  ps.pose_tolerance_ns = parse_pose_tolerance(a);
  ps.recorded = c.recorded_poses;
  ps.recorded_rig = c.stored_rig;
  ChosenPoses chosen = unwrap(choose_poses(ps, parts.rig, parts.models.receptacle_m));
  if (!chosen.provider)
    usage_error(c.from + " has no recorded scene: give one with --scene SCENE.yaml or --poses POSES.csv");
  parts.poses = std::move(chosen.provider);
  // A frame without its CSV row or its recorded scene is reported, not guessed.
  parts.skip_frames_without_pose = chosen.may_miss_frames;
  // A boom script's t_s counts from the recording's (EuRoC folder's) first frame, not the first
  // frame replayed: a replay from frame N flies the boom as the whole replay does there.
  if (a.has("boom")) parts.boom = parse_boom_arg(a.get("boom"));
  if (a.has("every") && !a.has("out")) usage_error("--every needs --out (where the images go)");
  if (a.has("out")) {
    const fs::path out_dir = a.get("out");
    make_dirs(out_dir);
    parts.stats_csv = unwrap(StatsCsvWriter::create(out_dir / "stats.csv"));
    parts.frame_files = FrameFiles{out_dir, replay_every(a), {}, a.has("ground-truth")};
  }
  // The re-augmented run as a new recording: the same raw frames, the new augmentation.
  if (a.has("record")) {
    recorder::RecordingInfo info;
    info.rig_yaml = rig_to_yaml(parts.rig);
    info.scene = a.has("scene")   ? a.get("scene")
                 : a.has("poses") ? "the poses " + a.get("poses")
                                  : "as recorded in " + c.from;
    info.clock_domains = c.clock_domains;
    info.extra["re_augmented_from"] = c.from;
    if (a.has("boom")) info.extra["boom"] = a.get("boom");
    parts.recorder = create_recorder(a.get("record"), info, a.has("overwrite"));
    parts.record_ground_truth = a.has("ground-truth");
  }
  if (!a.has("headless") && display_present()) parts.view = std::make_shared<LiveView>();
  parts.stop_flag = install_stop_signals();
}

// A EuRoC/ASL folder (mav0/cam0, cam1) through the same pipeline: no recorded scene, so --scene
// gives it; the rig is --rig (default: the paper's). Pairs by timestamp within
// --pair-tolerance-ns; --seek and --from-frame choose the start, --loop the passes are not
// supported (a dataset has no player).
int replay_euroc(const std::string& dir, const ParsedArgs& a, const AddSinks& add_sinks, std::ostream& out,
                 std::ostream& err) {
  if (a.has("loop")) usage_error("--loop: a EuRoC folder plays once (replay a recording to loop)");
  if (a.has("seek") && a.has("from-frame")) usage_error("--seek and --from-frame exclude each other");
  std::string params =
      "?tolerance_ns=" +
      std::to_string(a.has("pair-tolerance-ns")
                         ? parse_integer("pair-tolerance-ns", a.get("pair-tolerance-ns"), 0, 1LL << 40)
                         : 0);
  if (a.has("seek")) {
    if (parse_real("seek", a.get("seek")) < 0)
      usage_error("--seek: expected seconds from the first frame (>= 0), got '" + a.get("seek") + "'");
    params += "&seek_s=" + a.get("seek");
  }
  if (a.has("from-frame"))
    params += "&from_frame=" + std::to_string(parse_integer("from-frame", a.get("from-frame"), 0, 1LL << 40));
  const std::size_t frames = replay_frames(a);
  const std::string target = dir.rfind("euroc://", 0) == 0 ? dir.substr(8) : dir;
  OpenedSource opened = unwrap(open_sources("euroc://" + target + params));
  FrameSource& euroc = *opened.sources.front();
  if (frames) check(euroc.set_range_end(euroc.range_start() + std::min(frames, euroc.pair_count())));
  const std::size_t pairs = euroc.pair_count();
  const std::uint64_t unpaired = euroc.frames_dropped();  // before reading: the frames without a partner
  PipelineParts parts;
  configure_replay(parts, a, {"euroc://" + target, std::nullopt, true, false, "", &add_sinks});
  out << "replay: euroc://" << target << ", " << pairs << " stereo pairs (" << unpaired
      << " frames without a partner), " << replay_poses_text(a) << "\n";
  parts.source_info = opened;
  parts.source = unwrap(start_stereo(std::move(opened)));
  parts.progress_total = pairs;
  parts.on_problem = [&err](const Error& e) { err << "augrig replay: " << user_message(e) << "\n"; };
  Pipeline pipeline(std::move(parts));
  const PipelineReport r = run_pipeline(pipeline, !a.has("headless"), a.get("out", "."), out, err);
  out << "Replayed " << r.pairs << " stereo frame(s)\n";
  if (r.recording_closed) {
    out << "Recorded " << r.recorder_stats.frames_committed << " stereo frame(s) to " << a.get("record")
        << "\n";
    if (!*r.recording_closed)
      runtime_error("the recording stopped: " + user_message(r.recording_closed->error()));
  }
  const std::uint64_t unreadable =
      r.source.camera_drops > unpaired ? (r.source.camera_drops - unpaired) / 2 : 0;
  if (unreadable)
    input_damage(a, "replay",
                 std::to_string(unreadable) + " pair(s) could not be read (above); the others were replayed",
                 err);
  return kExitOk;
}

// An MCAP file written by augrig export --format mcap: its raw frames with the recorded scene
// (poses, boom) through the same pipeline, as fast as possible, once; the rig is the one the file
// stores (metadata augrig_recording) unless --rig gives another.
int replay_mcap(const std::string& file, const ParsedArgs& a, const AddSinks& add_sinks, std::ostream& out,
                std::ostream& err) {
  for (const char* flag : {"rate", "seek", "from-frame", "loop", "pair-tolerance-ns"})
    if (a.has(flag))
      usage_error(std::string("--") + flag +
                  ": an MCAP file plays once, from its first frame, as fast as possible");
  const std::string path = file.rfind("replay://", 0) == 0 ? file.substr(9) : file;
  OpenedSource opened = unwrap(open_sources("replay://" + path + "?rate=fast"));
  const FrameSource& mcap = *opened.sources.front();
  const std::size_t frames = mcap.pair_count();
  std::optional<Rig> recorded_rig;
  if (const auto meta = mcap.metadata(); meta.count("rig_yaml"))
    recorded_rig = unwrap(parse_rig(meta.at("rig_yaml"), path + " (metadata augrig_recording, rig_yaml)"));
  PipelineParts parts;
  configure_replay(parts, a, {path, recorded_rig, false, true, "", &add_sinks});
  parts.max_pairs = replay_frames(a);  // the first N augmented
  out << "replay: " << path << " (MCAP), " << frames << " stereo frames; rig "
      << (a.has("rig") ? parts.rig.source : std::string("as recorded")) << ", " << replay_poses_text(a)
      << "\n";
  parts.source_info = opened;
  parts.source = unwrap(start_stereo(std::move(opened)));
  parts.progress_total = parts.max_pairs ? std::min<std::uint64_t>(frames, parts.max_pairs) : frames;
  std::size_t problems = 0;  // read errors: a damaged frame or file
  parts.on_problem = [&err, &problems](const Error& e) {
    ++problems;
    err << "augrig replay: " << user_message(e) << "\n";
  };
  Pipeline pipeline(std::move(parts));
  const PipelineReport r = run_pipeline(pipeline, !a.has("headless"), a.get("out", "."), out, err);
  out << "Replayed " << r.pairs << " stereo frame(s)\n";
  if (r.comparable)
    out << "Recorded statistics reproduced exactly (same pixel counts) in " << r.reproduced << " of "
        << r.comparable << " frame(s)\n";
  if (r.skipped_no_pose)
    out << r.skipped_no_pose << " frame(s) had no recorded scene and were not augmented (give --scene)\n";
  if (r.recording_closed) {
    out << "Recorded " << r.recorder_stats.frames_committed << " stereo frame(s) to " << a.get("record")
        << "\n";
    if (!*r.recording_closed)
      runtime_error("the recording stopped: " + user_message(r.recording_closed->error()));
  }
  if (problems || r.source_failed)
    input_damage(
        a, "replay",
        path + ": the MCAP file is damaged or could not be read (above); the frames before were replayed",
        err);
  return kExitOk;
}

int replay_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> pos;
  const ParsedArgs a = parse_with_positionals(args, replay_specs(), {"DIR"}, pos);
  if (a.help) {
    out << format_help(
        "augrig replay DIR [--rate X|--fast] [--seek T_S|--from-frame N] [--frames N|--loop N] [--out DIR] "
        "[--rig RIG] "
        "[--scene SCENE.yaml] [--record DIR] [--headless]",
        "DIR may also be a EuRoC/ASL folder (mav0/cam0, cam1): then --scene is required.\n"
        "Plays a recording's raw frames back (replay://DIR) through the pipeline again: with the recorded\n"
        "rig and each frame's recorded scene (boom and receiver pose), or with another rig, boom or one\n"
        "fixed scene. With a display, in the live window with a timeline (pause, step, seek, scrub).\n"
        "Prints the occlusion statistics, how many frames reproduce the recorded statistics, and with\n"
        "--out writes stats.csv and the images of every K-th frame. Damaged frames are reported and\n"
        "skipped (exit 1 at the end).",
        replay_specs());
    return kExitOk;
  }
  if (a.has("ground-truth") && !a.has("out") && !a.has("record"))
    usage_error(
        "--ground-truth needs --out DIR (where the files go) or --record DIR (stored in the new recording)");
  return replay_into(pos[0], a, nullptr, out, err);
}

// A recording (replay://DIR): the player's settings in the URI, the range in the source.
int replay_recording(const std::string& input, const ParsedArgs& a, const AddSinks& add_sinks,
                     std::ostream& out, std::ostream& err) {
  if (a.has("rate") && a.has("fast")) usage_error("--rate and --fast exclude each other");
  if (a.has("seek") && a.has("from-frame")) usage_error("--seek and --from-frame exclude each other");
  // The replay:// URI carries the player's settings (pipeline/sources.hpp, docs/REPLAY.md).
  std::string params;
  auto param = [&](const std::string& k, const std::string& v) {
    params += (params.empty() ? "?" : "&") + k + "=" + v;
  };
  double rate = 0;
  if (a.has("rate")) {
    rate = parse_real("rate", a.get("rate"));
    if (!(rate > 0)) usage_error("--rate: expected a number above 0, got '" + a.get("rate") + "'");
    param("rate", a.get("rate"));
    param("late", "keep");  // every frame, paced; none skipped for being late
  } else {
    param("rate", "fast");
  }
  if (a.has("seek")) {
    const double t = parse_real("seek", a.get("seek"));
    if (t < 0)
      usage_error("--seek: expected seconds from the first frame (>= 0), got '" + a.get("seek") + "'");
    param("seek_s", a.get("seek"));
  }
  if (a.has("from-frame"))
    param("from_frame", std::to_string(parse_integer("from-frame", a.get("from-frame"), 0, 1LL << 40)));
  const std::size_t frames = replay_frames(a);
  const int passes = a.has("loop") ? static_cast<int>(parse_integer("loop", a.get("loop"), 1, 1000000)) : 1;
  param("passes", std::to_string(passes));
  const int every = replay_every(a);

  // The recording, the rig and the scene are read and checked before the GL context exists.
  const std::string dir = input.rfind("replay://", 0) == 0 ? input.substr(9) : input;
  OpenedSource opened = unwrap(open_sources("replay://" + dir + params));
  recorder::ReplaySource& source = *opened.replay;
  // The range ends in the source, not after N augmented pairs: a frame skipped (damaged, without a
  // scene) does not move the end, so consecutive ranges replay each frame once.
  if (frames) check(source.set_end_frame(source.start_frame() + std::min(frames, source.frame_count())));
  const recorder::RecordingReader& reader = source.reader();
  // A truncated or damaged recording: what is missing is said now, the readable frames are
  // replayed, and the exit status is 1.
  for (const std::string& p : reader.problems())
    err << "augrig replay: " << recording_problem(reader, p) << "\n";
  if (source.frame_count() == 0)
    runtime_error(reader.path() + ": the recording holds no readable frames" +
                  (reader.problems().empty() ? std::string() : " (above: what is damaged or missing)"));
  std::optional<Rig> recorded_rig;
  if (const std::string yaml = reader.meta("rig_yaml"); !yaml.empty())
    recorded_rig = unwrap(parse_rig(yaml, reader.path() + " (meta rig_yaml)"));
  // The first frame replayed must carry a scene unless one is given.
  if (!a.has("scene") && !a.has("poses"))
    if (auto first = reader.read_frame_info(source.start_frame());
        first && !first->boom && !first->T_body_receiver && !first->T_cam_receiver[0])
      runtime_error(
          reader.path() + ": frame " + std::to_string(source.start_frame()) +
          " has no recorded scene (boom articulation, receiver pose); give one with --scene SCENE.yaml "
          "or --poses POSES.csv");
  PipelineParts parts;
  configure_replay(
      parts, a,
      {reader.path(), recorded_rig, false, true, reader.meta("clock_domains"), &add_sinks, reader.path()});
  parts.source_info = opened;
  const fs::path out_dir = a.get("out");
  out << "replay: " << source.uri() << ", " << source.frame_count() << " stereo frames, from frame "
      << source.start_frame() << (frames ? " to " + std::to_string(source.end_frame() - 1) : std::string())
      << ", " << (rate > 0 ? "real rate x" + fmt_ms(rate) : std::string("as fast as possible"))
      << (passes > 1 ? ", " + std::to_string(passes) + " passes" : std::string()) << "; rig "
      << (a.has("rig") ? parts.rig.source : std::string("as recorded")) << ", " << replay_poses_text(a)
      << "\n";
  parts.on_problem = [&err](const Error& e) { err << "augrig replay: " << user_message(e) << "\n"; };
  parts.source = unwrap(start_stereo(std::move(opened)));
  parts.status_every_s = a.has("status-every") ? parse_real("status-every", a.get("status-every")) : 0;
  // Progress over the range replayed, every pass.
  parts.progress_total = (source.end_frame() - source.start_frame()) * static_cast<std::uint64_t>(passes);
  Pipeline pipeline(std::move(parts));
  const PipelineReport r =
      run_pipeline(pipeline, !a.has("headless"), a.get("out", "."), out, err, parse_screenshot_at(a));

  if (r.pairs == 1 && r.last_stats) out << format_table1(*r.last_stats, "Occlusion statistics");
  out << "Replayed " << r.pairs << " stereo frame(s)";
  if (r.pairs)
    out << " (augmenter " << fmt_ms(r.augment_ms / static_cast<double>(r.pairs)) << " ms per stereo frame, "
        << to_string(r.rasterizer) << " rasteriser)";
  out << "\n";
  if (r.comparable)
    out << "Recorded statistics reproduced exactly (same pixel counts) in " << r.reproduced << " of "
        << r.comparable << " frame(s)\n";
  if (r.skipped_no_pose)
    out << r.skipped_no_pose << " frame(s) had no recorded scene and were not augmented (give --scene)\n";
  const std::uint64_t one_camera = r.source.pairing.unpaired_left + r.source.pairing.unpaired_right;
  if (one_camera)
    out << one_camera << " recorded frame(s) had only one camera's image and were not augmented\n";
  if (a.has("out"))
    out << "Wrote " << (out_dir / "stats.csv").string() << " and the images of 1 in " << every << " frames\n";
  if (r.recording_closed) {
    out << "Recorded " << r.recorder_stats.frames_committed << " stereo frame(s) to " << a.get("record")
        << " (" << r.recorder_stats.frames_dropped << " dropped by the recorder)\n";
    if (!*r.recording_closed)
      runtime_error("the recording stopped: " + user_message(r.recording_closed->error()));
  }
  recording_damage(a, "replay", !reader.problems().empty(),
                   pipeline.parts().source_info.replay->damaged_frames(), "replayed", err);
  if (r.stopped_by_signal) return kExitRuntime;
  return kExitOk;
}

}  // namespace

int replay_into(const std::string& input, const ParsedArgs& a, const AddSinks& add_sinks, std::ostream& out,
                std::ostream& err) {
  if (input.rfind("euroc://", 0) == 0 || fs::is_directory(fs::path(input) / "mav0") ||
      fs::path(input).filename() == "mav0")
    return replay_euroc(input, a, add_sinks, out, err);
  const std::string path = input.rfind("replay://", 0) == 0 ? input.substr(9) : input;
  if (!fs::is_directory(path) && recorder::is_mcap_path(path))
    return replay_mcap(input, a, add_sinks, out, err);
  return replay_recording(input, a, add_sinks, out, err);
}

int cmd_check(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("check", err, [&] { return check_command(args, out); });
}

int cmd_replay(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("replay", err, [&] { return replay_command(args, out, err); });
}

}  // namespace augrig::app
