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
#include "app/scene_file.hpp"
#include "recorder/euroc.hpp"
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
      {"loop", ArgKind::kValue, "N", "play the range N times in all (default 1)"},
      {"out", ArgKind::kValue, "DIR", "write stats.csv and the images of every --every-th frame here"},
      {"every", ArgKind::kValue, "K", "with --out: images of every K-th replayed frame (default 30)"},
      {"rig", ArgKind::kValue, "RIG.yaml|default", "augment with this rig (default: the recorded rig)"},
      {"scene", ArgKind::kValue, "SCENE.yaml",
       "one fixed scene for every frame (default: each frame's recorded boom and receiver pose)"},
      {"receiver-draw", ArgKind::kValue, "mask|wireframe|translucent",
       "how the receiver shows in the augmented image (default mask: not drawn)"},
      {"boom", ArgKind::kValue, "track|fixed:EL,AZ,EXT|script:FILE.csv",
       "another boom over the recorded receiver poses (default: the recorded boom)"},
      {"record", ArgKind::kValue, "DIR", "record the re-augmented run (a new recording, docs/RECORDING.md)"},
      {"pair-tolerance-ns", ArgKind::kValue, "NS",
       "EuRoC folders: pair left and right frames whose timestamps differ by at most NS (default 0)"},
  };
  return specs;
}

// The scene recorded with a frame: its boom articulation and the receiver's pose in the tanker
// body frame (or, when only the camera-relative pose was recorded, through the recorded rig).
std::optional<SceneState> recorded_scene(const recorder::FrameRecord& r, const Rig* recorded_rig) {
  if (!r.boom) return std::nullopt;
  SceneState s;
  s.boom = *r.boom;
  if (r.T_body_receiver) {
    s.T_body_receiver = *r.T_body_receiver;
  } else if (r.T_cam_receiver[0] && recorded_rig) {
    s.T_body_receiver = recorded_rig->left().T_body_cam * *r.T_cam_receiver[0];
  } else {
    s.receiver_present = false;
  }
  if (r.receiver_present && !*r.receiver_present) s.receiver_present = false;
  return s;
}

bool same_counts(const OcclusionStats& a, const OcclusionStats& b) {
  return a.receiver_px_left == b.receiver_px_left && a.receiver_px_right == b.receiver_px_right &&
         a.boom_px_left == b.boom_px_left && a.boom_px_right == b.boom_px_right &&
         a.boom_overlap_px == b.boom_overlap_px && a.occluded_px_left == b.occluded_px_left &&
         a.occluded_px_right == b.occluded_px_right && a.stereo_both_px == b.stereo_both_px &&
         a.left_only_px == b.left_only_px && a.right_only_px == b.right_only_px &&
         a.neither_px == b.neither_px;
}

// A EuRoC/ASL folder (mav0/cam0, cam1): no recorded scene, so --scene gives it; the rig is --rig
// (default: the paper's). Pairs by timestamp within --pair-tolerance-ns.
int replay_euroc(const std::string& dir, const ParsedArgs& a, std::ostream& out) {
  if (!a.has("scene")) usage_error("a EuRoC folder has no recorded scene: give one with --scene SCENE.yaml");
  recorder::EurocOptions eo;
  if (a.has("pair-tolerance-ns"))
    eo.pair_tolerance_ns = parse_integer("pair-tolerance-ns", a.get("pair-tolerance-ns"), 0, 1LL << 40);
  auto source = unwrap(recorder::EurocSource::open(dir, eo));
  const Rig rig = load_rig_arg(a.get("rig", "default"));
  const ReceiverSetup receiver = receiver_setup(rig);
  const SceneState scene = unwrap(load_scene(a.get("scene"), rig, BoomDimensions{}, receiver.receptacle_m));
  AugmentOptions options;
  options.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  options.augmented_output = AugmentedOutput::kChangedBox;  // whole images only for the PNG files
  options.receiver_model = receiver.model;
  std::optional<StatsCsv> csv;
  if (a.has("out")) {
    make_dirs(a.get("out"));
    csv.emplace(fs::path(a.get("out")) / "stats.csv");
  }
  out << "replay: " << source->uri() << ", " << source->pair_count() << " stereo pairs ("
      << source->unpaired() << " frames without a partner), scene " << a.get("scene") << "\n";
  const auto gl = make_gl_context();
  const auto augmenter = unwrap(Augmenter::create(rig, options));
  std::unique_ptr<recorder::Recorder> rec_out;
  if (a.has("record")) {
    recorder::RecordingInfo info;
    info.rig_yaml = rig_to_yaml(rig);
    info.scene = a.get("scene");
    info.extra["re_augmented_from"] = source->uri();
    rec_out = unwrap(recorder::Recorder::create(a.get("record"), info));
  }
  StereoFrame frame;
  StereoResult result;
  std::vector<OcclusionStats> all;
  for (;;) {
    if (unwrap(source->read(frame.left, std::chrono::seconds(1))) != ReadStatus::kFrame) break;
    if (unwrap(source->read(frame.right, std::chrono::seconds(1))) != ReadStatus::kFrame) break;
    frame.t_key_ns = frame.left.t_ns + (frame.right.t_ns - frame.left.t_ns) / 2;
    frame.skew_ns = frame.right.t_ns - frame.left.t_ns;
    check(augmenter->augment(frame, scene, result));
    result.stats.t_ns = frame.t_key_ns;
    if (csv) csv->add(result.stats);
    if (rec_out) {
      recorder::FrameRecord fr = frame_record(result);
      fr.raw = frame;
      fr.T_body_receiver = scene.T_body_receiver;
      fr.boom = scene.boom;
      rec_out->push(std::move(fr));
    }
    all.push_back(result.stats);
  }
  if (!all.empty()) out << format_run_summary(all);
  out << "Replayed " << all.size() << " stereo frame(s)\n";
  if (rec_out) {
    const Status closed = rec_out->close();
    out << "Recorded " << rec_out->stats().frames_committed << " stereo frame(s) to " << rec_out->path()
        << "\n";
    if (!closed) runtime_error("the recording stopped: " + user_message(closed.error()));
  }
  return kExitOk;
}

int replay_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> pos;
  const ParsedArgs a = parse_with_positionals(args, replay_specs(), {"DIR"}, pos);
  if (a.help) {
    out << format_help(
        "augrig replay DIR [--rate X|--fast] [--seek T_S|--from-frame N] [--loop N] [--out DIR] [--rig RIG] "
        "[--scene SCENE.yaml]",
        "DIR may also be a EuRoC/ASL folder (mav0/cam0, cam1): then --scene is required.\n"
        "Plays a recording's raw frames back (replay://DIR) through the Augmenter again: with the recorded\n"
        "rig and each frame's recorded scene (boom and receiver pose), or with another rig or one fixed\n"
        "scene. Prints the occlusion statistics, how many frames reproduce the recorded statistics, and\n"
        "with --out writes stats.csv and the images of every K-th frame. Damaged frames are reported and\n"
        "skipped (exit 1 at the end).",
        replay_specs());
    return kExitOk;
  }
  if (pos[0].rfind("euroc://", 0) == 0 || fs::is_directory(fs::path(pos[0]) / "mav0") ||
      fs::path(pos[0]).filename() == "mav0")
    return replay_euroc(pos[0], a, out);
  if (a.has("rate") && a.has("fast")) usage_error("--rate and --fast exclude each other");
  if (a.has("seek") && a.has("from-frame")) usage_error("--seek and --from-frame exclude each other");
  recorder::ReplayOptions o;
  if (a.has("rate")) {
    o.mode = recorder::ReplayMode::kRealRate;
    o.rate = parse_real("rate", a.get("rate"));
    if (!(o.rate > 0)) usage_error("--rate: expected a number above 0, got '" + a.get("rate") + "'");
  }
  if (a.has("seek")) {
    const double t = parse_real("seek", a.get("seek"));
    if (t < 0)
      usage_error("--seek: expected seconds from the first frame (>= 0), got '" + a.get("seek") + "'");
    o.start_offset_ns = s_to_ns(t);
  }
  if (a.has("from-frame"))
    o.start_frame = static_cast<std::size_t>(parse_integer("from-frame", a.get("from-frame"), 0, 1LL << 40));
  o.passes = a.has("loop") ? static_cast<int>(parse_integer("loop", a.get("loop"), 1, 1000000)) : 1;
  const int every =
      a.has("every") ? static_cast<int>(parse_integer("every", a.get("every"), 1, 1000000)) : 30;
  if (a.has("every") && !a.has("out")) usage_error("--every needs --out (where the images go)");
  AugmentOptions options;
  options.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  options.augmented_output = AugmentedOutput::kChangedBox;  // whole images only for the PNG files

  // The recording, the rig and the scene are read and checked before the GL context exists.
  auto source = unwrap(recorder::ReplaySource::open(pos[0], o));
  const recorder::RecordingReader& reader = source->reader();
  // A truncated or damaged recording: what is missing is said now, the readable frames are
  // replayed, and the exit status is 1.
  for (const std::string& p : reader.problems())
    err << "augrig replay: " << recording_problem(reader, p) << "\n";
  if (source->frame_count() == 0)
    runtime_error(reader.path() + ": the recording holds no readable frames" +
                  (reader.problems().empty() ? std::string() : " (above: what is damaged or missing)"));
  std::optional<Rig> recorded_rig;
  if (const std::string yaml = reader.meta("rig_yaml"); !yaml.empty())
    recorded_rig = unwrap(parse_rig(yaml, reader.path() + " (meta rig_yaml)"));
  if (!a.has("rig") && !recorded_rig)
    runtime_error(reader.path() +
                  ": the recording stores no rig (meta rig_yaml is empty); give one with --rig");
  const Rig rig = a.has("rig") ? load_rig_arg(a.get("rig")) : *recorded_rig;
  if (rig.cameras.size() != 2)
    runtime_error(rig.source + ": the rig needs 2 cameras, has " + std::to_string(rig.cameras.size()));
  const ReceiverSetup receiver = receiver_setup(rig);
  options.receiver_model = receiver.model;
  std::optional<SceneState> fixed_scene;
  if (a.has("scene")) {
    fixed_scene = unwrap(load_scene(a.get("scene"), rig, BoomDimensions{}, receiver.receptacle_m));
  } else if (auto first = reader.read_frame_info(source->start_frame()); first && !first->boom) {
    runtime_error(reader.path() + ": frame " + std::to_string(source->start_frame()) +
                  " has no recorded scene (boom articulation); give one with --scene SCENE.yaml");
  }

  std::optional<BoomArg> boom_arg;
  if (a.has("boom")) boom_arg = parse_boom_arg(a.get("boom"));
  const BoomDimensions boom_dims;
  // A boom script's t_s counts from the recording's first frame.
  const TimestampNs first_t_ns = [&] {
    auto f = reader.read_frame_info(0);
    return f ? f->raw.left.t_ns : TimestampNs{0};
  }();

  // The re-augmented run as a new recording: the same raw frames, the new augmentation.
  std::unique_ptr<recorder::Recorder> rec_out;
  if (a.has("record")) {
    recorder::RecordingInfo info;
    info.rig_yaml = rig_to_yaml(rig);
    info.scene = fixed_scene ? a.get("scene") : std::string("as recorded in ") + reader.path();
    info.clock_domains = reader.meta("clock_domains");
    info.extra["re_augmented_from"] = reader.path();
    if (boom_arg) info.extra["boom"] = a.get("boom");
    rec_out = unwrap(recorder::Recorder::create(a.get("record"), info));
  }

  const fs::path out_dir = a.get("out");
  std::optional<StatsCsv> csv;
  if (a.has("out")) {
    make_dirs(out_dir);
    csv.emplace(out_dir / "stats.csv");
  }
  out << "replay: " << source->uri() << ", " << source->frame_count() << " stereo frames, from frame "
      << source->start_frame() << ", "
      << (o.mode == recorder::ReplayMode::kRealRate ? "real rate x" + fmt_ms(o.rate)
                                                    : std::string("as fast as possible"))
      << (o.passes > 1 ? ", " + std::to_string(o.passes) + " passes" : std::string()) << "; rig "
      << (a.has("rig") ? rig.source : std::string("as recorded")) << ", scene "
      << (fixed_scene ? a.get("scene") : std::string("as recorded per frame")) << "\n";

  const auto gl = make_gl_context();
  const auto augmenter = unwrap(Augmenter::create(rig, options));

  StereoResult result;
  std::vector<OcclusionStats> all;
  std::size_t damaged = 0, no_scene = 0, one_camera = 0, comparable = 0, reproduced = 0;
  double augment_ms = 0;
  bool sizes_checked = false;
  StereoFrame frame;
  std::optional<std::size_t> left_index;
  Frame f;
  for (;;) {
    auto st = source->read(f, std::chrono::seconds(1));
    if (!st) {
      err << "augrig replay: " << user_message(st.error()) << "\n";
      ++damaged;
      continue;
    }
    if (*st == ReadStatus::kTimeout) continue;
    if (*st == ReadStatus::kEndOfStream) break;
    const recorder::FrameRecord& rec = source->current();
    if (f.camera == CameraId::kLeft) {
      if (left_index) ++one_camera;  // the previous stereo frame had no right image
      frame.left = std::move(f);
      left_index = source->current_index();
      if (!rec.raw.right.image.empty()) continue;
      ++one_camera;
      left_index.reset();
      continue;
    }
    if (!left_index || *left_index != source->current_index()) {
      ++one_camera;  // a right image without its left one
      left_index.reset();
      continue;
    }
    left_index.reset();
    frame.right = std::move(f);
    frame.t_key_ns = rec.raw.t_key_ns;
    frame.skew_ns = rec.raw.skew_ns;
    frame.pair_sequence = rec.raw.pair_sequence;
    const std::size_t index = *source->current_index();

    std::optional<SceneState> scene =
        fixed_scene ? fixed_scene : recorded_scene(rec, recorded_rig ? &*recorded_rig : nullptr);
    if (!scene) {
      if (no_scene++ < 5)
        err << "augrig replay: frame " << index << " has no recorded scene; not augmented\n";
      continue;
    }
    if (!sizes_checked) {
      for (CameraId id : {CameraId::kLeft, CameraId::kRight}) {
        const Image& im = frame[id].image;
        const RigCamera& cam = rig.cameras[static_cast<std::size_t>(index_of(id))];
        if (im.width() != cam.model.width_px || im.height() != cam.model.height_px) {
          runtime_error(reader.path() + ": frame " + std::to_string(index) + ": the " +
                        std::string(to_string(id)) + " image is " + std::to_string(im.width()) + "x" +
                        std::to_string(im.height()) + ", the rig's " + cam.name + " camera is " +
                        std::to_string(cam.model.width_px) + "x" + std::to_string(cam.model.height_px));
        }
      }
      sizes_checked = true;
    }
    if (boom_arg) {
      // Tracking aims at the receptacle where the recorded pose puts it.
      const BoomCommand tracked = track_point(scene->T_body_receiver * receiver.receptacle_m,
                                              rig.boom.pivot_body_m, boom_dims, rig.boom.limits);
      scene->boom =
          boom_arg->command(ns_to_s(frame.left.t_ns - first_t_ns), tracked, rig.boom.limits).articulation;
    }
    check(augmenter->augment(frame, *scene, result));
    augment_ms += augmenter->timings().total_ms;
    result.stats.t_ns = frame.t_key_ns;
    if (rec_out) {
      recorder::FrameRecord fr = frame_record(result);
      fr.raw = frame;
      fr.T_body_receiver = scene->T_body_receiver;
      fr.receiver_present = scene->receiver_present;
      for (int c = 0; c < 2; ++c)
        fr.T_cam_receiver[c] = rig.cameras[c].T_body_cam.inverse() * scene->T_body_receiver;
      fr.sigma_pos_m = rec.sigma_pos_m, fr.sigma_att_deg = rec.sigma_att_deg;
      fr.boom = scene->boom;
      rec_out->push(std::move(fr));
    }
    if (rec.stats) {
      ++comparable;
      reproduced += same_counts(result.stats, *rec.stats);
    }
    if (csv) {
      csv->add(result.stats);
      if (all.size() % static_cast<std::size_t>(every) == 0) {
        std::ostringstream stem;
        if (o.passes > 1) stem << "pass" << source->pass() << "_";
        stem << std::setw(6) << std::setfill('0') << index;
        write_frame_outputs(out_dir, {stem.str(), stem.str()}, frame, result);
      }
    }
    all.push_back(result.stats);
  }

  if (!all.empty()) {
    out << (all.size() == 1 ? format_table1(all.front(), "Occlusion statistics") : format_run_summary(all));
  }
  out << "Replayed " << all.size() << " stereo frame(s)";
  if (!all.empty())
    out << " (augmenter " << fmt_ms(augment_ms / static_cast<double>(all.size())) << " ms per stereo frame, "
        << to_string(augmenter->rasterizer()) << " rasteriser)";
  out << "\n";
  if (comparable)
    out << "Recorded statistics reproduced exactly (same pixel counts) in " << reproduced << " of "
        << comparable << " frame(s)\n";
  if (no_scene) out << no_scene << " frame(s) had no recorded scene and were not augmented (give --scene)\n";
  if (one_camera)
    out << one_camera << " recorded frame(s) had only one camera's image and were not augmented\n";
  if (csv)
    out << "Wrote " << (out_dir / "stats.csv").string() << " and the images of 1 in " << every << " frames\n";
  if (rec_out) {
    const Status closed = rec_out->close();
    const recorder::RecorderStats rs = rec_out->stats();
    out << "Recorded " << rs.frames_committed << " stereo frame(s) to " << rec_out->path() << " ("
        << rs.frames_dropped << " dropped by the recorder)\n";
    if (!closed) runtime_error("the recording stopped: " + user_message(closed.error()));
  }
  if (!reader.problems().empty())
    runtime_error(
        "the recording is incomplete (above); " +
        (damaged ? std::to_string(damaged) + " listed frame(s) could not be read, " : std::string()) +
        "the others were replayed");
  if (damaged)
    runtime_error(std::to_string(damaged) + " frame(s) could not be read (above); the others were replayed");
  return kExitOk;
}

}  // namespace

int cmd_check(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("check", err, [&] { return check_command(args, out); });
}

int cmd_replay(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("replay", err, [&] { return replay_command(args, out, err); });
}

}  // namespace augrig::app
