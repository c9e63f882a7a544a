// The augrig commands. Flow of every command: parse the flags (usage errors exit 2), load and
// check every input file before the GL context exists (content errors exit 1 with file and line),
// then create the EGL headless context and the Augmenter and process frame by frame.
#include "app/commands.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

#include "app/cli.hpp"
#include "app/window_runner.hpp"
#include "capture/stereo_pairer.hpp"
#include "core/frame.hpp"
#include "pipeline/image_folder_source.hpp"
#include "pipeline/scene_file.hpp"
#include "pipeline/scene_folder_poses.hpp"
#include "pipeline/sources.hpp"
#include "render/augmenter.hpp"
#include "render/gl_context.hpp"
#include "render/image_file.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"
#include "render/visualize.hpp"
#include "sim/approach.hpp"

#ifndef AUGRIG_VERSION
#define AUGRIG_VERSION "unknown"
#endif

namespace augrig::app {
namespace {

// ---- augment ------------------------------------------------------------------------------------

const std::vector<OptionSpec>& augment_specs() {
  static const std::vector<OptionSpec> specs = {
      rig_option("", true),
      scene_option("", true),
      poses_option(),
      pose_tolerance_option(),
      {"left", ArgKind::kValue, "FILE|DIR", "left camera image, or a folder of them (paired by sorted name)"},
      {"right", ArgKind::kValue, "FILE|DIR", "right camera image, or a folder of them"},
      {"frames", ArgKind::kValue, "INDEX.csv",
       "a frame index (sequence,camera,t_ns,file; `augrig sim`'s frames/index.csv): the images, relative to "
       "it, paired by timestamp"},
      {"pair-tolerance-us", ArgKind::kValue, "US",
       "with --frames: pair left and right frames whose t_ns differ by at most US (default: half the median "
       "frame interval)"},
      {"out", ArgKind::kValue, "DIR", "output folder (created)", true},
      {"format", ArgKind::kValue, "png", "output image format (png, lossless)"},
      {"bayer", ArgKind::kValue, "RG|GR|GB|BG", "8-bit gray inputs are raw Bayer mosaics with this pattern"},
      {"no-receiver", ArgKind::kFlag, "",
       "do not render the receiver (no receiver mask bit, no stereo classes)"},
      receiver_draw_option(),
      look_option(),
      {"status-every", ArgKind::kValue, "S",
       "a status line (pairs, rate, drops) every S seconds (default 0: never)"},
      {"ground-truth", ArgKind::kFlag, "", kGroundTruthHelp},
      sink_option(),
  };
  return specs;
}

const char* kAugmentUsage =
    "augrig augment --rig RIG.yaml|default (--scene SCENE.yaml|DIR | --poses POSES.csv)\n"
    "                      (--left L --right R | --frames INDEX.csv) --out DIR [options]";
const char* kAugmentSummary =
    "Renders the virtual boom into a stereo pair, folders of pairs, or a whole sequence named by a frame\n"
    "index, and writes the augmented images, per-pixel masks (1 boom, 2 receiver, 3 both), visualisations\n"
    "and the occlusion statistics. Poses come from a scene file (or one per pair) or from `augrig nav`'s\n"
    "poses.csv. Frames without a partner or without a pose are counted and reported, not augmented.";

// The URI query cannot quote: a path with its separators would be read as something else.
std::string uri_path(const std::string& flag, const std::string& path) {
  if (path.find_first_of("?&") != std::string::npos)
    usage_error(flag + ": the path '" + path + "' has '?' or '&', which the files:// source cannot take");
  return path;
}

// Each pair's images are named after its input files' stems (the source's ImageFileAttachment).
FrameNames input_names(const StereoFrame& frame) {
  auto stem = [](const Frame& f) {
    const std::string path = f.attachment ? f.attachment->file_path() : std::string();
    return path.empty() ? std::to_string(f.sequence) : fs::path(path).stem().string();
  };
  return {stem(frame.left), stem(frame.right)};
}

// The flags that exclude or need each other, before anything is read.
void check_augment_args(const ParsedArgs& a, bool indexed) {
  if (a.get("format", "png") != "png") usage_error("--format: expected png, got '" + a.get("format") + "'");
  if (indexed && (a.has("left") || a.has("right")))
    usage_error("--frames and --left/--right exclude each other: give the images one way");
  if (!indexed && (!a.has("left") || !a.has("right")))
    usage_error(std::string("missing required option ") + (a.has("left") ? "--right R" : "--left L") +
                " (or give a frame index with --frames INDEX.csv)");
  if (a.has("scene") && a.has("poses")) usage_error("--scene and --poses exclude each other: give one pose source");
  if (!a.has("scene") && !a.has("poses"))
    usage_error("missing required option --scene SCENE.yaml|DIR (or --poses POSES.csv)");
  if (a.has("pose-tolerance-ms") && !a.has("poses")) usage_error("--pose-tolerance-ms needs --poses");
  if (a.has("pair-tolerance-us") && !indexed)
    usage_error("--pair-tolerance-us needs --frames (folders pair by sorted name)");
}

// The images as a files:// URI: a frame index (--frames) or two folders or files (--left/--right).
std::string images_uri(const ParsedArgs& a, bool indexed) {
  std::string params;
  auto param = [&](const std::string& k, const std::string& v) { params += (params.empty() ? "?" : "&") + k + "=" + v; };
  std::string uri;
  if (indexed) {
    if (a.has("pair-tolerance-us")) {
      const double us = parse_real("pair-tolerance-us", a.get("pair-tolerance-us"));
      if (!(us >= 0) || us > kMaxPairingToleranceUs)
        usage_error("--pair-tolerance-us: expected microseconds in [0, 1e7], got '" + a.get("pair-tolerance-us") + "'");
      param("tolerance_us", a.get("pair-tolerance-us"));
    }
    if (a.has("bayer")) param("bayer", a.get("bayer"));
    uri = "files://" + uri_path("--frames", a.get("frames"));
  } else {
    const std::string left = a.get("left"), right = a.get("right");
    std::error_code ec;
    const bool ldir = fs::is_directory(left, ec), rdir = fs::is_directory(right, ec);
    if (ldir != rdir) {
      usage_error("--left and --right must both be image files or both folders (--left " + left + " is " +
                  (ldir ? "a folder" : "not a folder") + ", --right " + right + " is " +
                  (rdir ? "a folder" : "not a folder") + ")");
    }
    param("left", uri_path("--left", left));
    param("right", uri_path("--right", right));
    if (a.has("bayer")) param("bayer", a.get("bayer"));
    uri = "files://folders";
  }
  return uri + params;
}

// The first image of each camera is read up front: the common mistakes (wrong file, size,
// depth) show here, naming the file, before the GL context exists.
void check_first_images(const ParsedArgs& a, const ImageFolderSource& files, const Rig& rig) {
  for (CameraId c : {CameraId::kLeft, CameraId::kRight}) {
    const auto e = std::find_if(files.entries().begin(), files.entries().end(),
                                [c](const ImageFolderEntry& x) { return x.camera == c; });
    const std::string where = files.from_index() ? files.where(*e) + ": " : std::string();
    const std::optional<PixelFormat> bayer =
        a.has("bayer") ? std::optional<PixelFormat>(parse_bayer(a.get("bayer"))) : std::nullopt;
    auto im = augrig::read_image_file(e->path, bayer);
    if (!im) runtime_error(where + user_message(im.error()));
    const RigCamera& cam = rig.cameras[static_cast<std::size_t>(index_of(c))];
    if (im->width() != cam.model.width_px || im->height() != cam.model.height_px)
      runtime_error(where + e->path + ": image is " + std::to_string(im->width()) + "x" +
                    std::to_string(im->height()) + ", the rig's " + cam.name + " camera is " +
                    std::to_string(cam.model.width_px) + "x" + std::to_string(cam.model.height_px));
  }
}

int augment(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const ParsedArgs a = [&] {
    auto p = parse_args(args, augment_specs());
    if (!p) usage_error(p.error().message);
    return *p;
  }();
  if (a.help) {
    out << format_help(kAugmentUsage, kAugmentSummary, augment_specs());
    return kExitOk;
  }
  const bool indexed = a.has("frames");
  check_augment_args(a, indexed);
  const TimestampNs pose_tolerance_ns = parse_pose_tolerance(a);
  const double status_s = a.has("status-every") ? parse_real("status-every", a.get("status-every")) : 0.0;
  if (!(status_s >= 0)) usage_error("--status-every: expected seconds >= 0");
  AugmentOptions options;
  options.receiver_draw = parse_receiver_draw(a.get("receiver-draw"));
  options.receiver_proxy = !a.has("no-receiver");
  options.stereo_classes = options.receiver_proxy;

  // Every input is read and checked before the GL context exists, so bad files fail fast.
  const Rig rig = load_rig_arg(a.get("rig"));
  if (rig.cameras.size() != 2)
    runtime_error(rig.source + ": the rig needs 2 cameras, has " + std::to_string(rig.cameras.size()));

  // The images: a files:// source either way (pipeline/image_folder_source.hpp).
  const std::string uri = images_uri(a, indexed);
  if (a.has("bayer")) parse_bayer(a.get("bayer"));  // a bad pattern is a usage error, not the URI's
  OpenedSource opened = unwrap(open_sources(uri));
  if (!opened.image_files) runtime_error("internal error: " + uri + " did not open an image folder source");
  const ImageFolderSource* files = opened.image_files;
  const std::size_t expected_pairs = files->pair_count();
  const std::size_t frame_count = files->image_count();

  const RigModels receiver = unwrap(load_rig_models(rig));
  options.receiver_model = receiver.receiver_model;
  if (receiver.boom_model) options.boom_model = receiver.boom_model;
  // The poses: a CSV, a scene file, or a folder of scene files (one per pair); the scene files'
  // t_ns for stats.csv (folders only: there a pair's t_ns is its index).
  PoseSources ps;
  ps.scene_path = a.get("scene", "");
  ps.scene_folder_ok = true;
  ps.poses_csv_path = a.get("poses", "");
  ps.pose_tolerance_ns = pose_tolerance_ns;
  ChosenPoses chosen = unwrap(choose_poses(ps, rig, receiver.receptacle_m));
  std::unique_ptr<PoseProvider> poses = std::move(chosen.provider);
  const std::vector<std::optional<TimestampNs>> scene_t_ns = std::move(chosen.scene_t_ns);
  std::error_code ec;
  if (!a.has("poses") && fs::is_directory(a.get("scene"), ec) && scene_t_ns.size() != expected_pairs)
    runtime_error(a.get("scene") + ": has " + std::to_string(scene_t_ns.size()) +
                  " scene file(s) (.yaml), expected one per pair (" + std::to_string(expected_pairs) + ")");
  check_first_images(a, *files, rig);

  const fs::path out_dir = a.get("out");
  make_dirs(out_dir);
  // Folders with scene files that give t_ns: stats.csv is written after the run, each pair's t_ns
  // (its index) replaced by its scene's. Otherwise the pipeline writes it row by row.
  const bool remap_t = !files->from_index() && std::any_of(scene_t_ns.begin(), scene_t_ns.end(),
                                                           [](const auto& t) { return t.has_value(); });

  PipelineParts parts;
  parts.rig = rig;
  parts.models = receiver;
  parts.source_info = opened;
  parts.poses = std::move(poses);
  apply_look_arg(a, rig, options);
  parts.augment = options;
  parts.skip_frames_without_pose = true;  // a pair without a pose is counted and reported, not guessed
  parts.keep_all_stats = true;  // stats.csv may be rewritten with the scene files' t_ns
  if (!remap_t) parts.stats_csv = unwrap(StatsCsvWriter::create(out_dir / "stats.csv"));
  parts.frame_files = FrameFiles{out_dir, 1, input_names, a.has("ground-truth")};
  parts.status_every_s = status_s;
  // "N of M pairs, X/s, ETA" about once a second, M the pairs the index (or the folders) hold.
  parts.progress_total = expected_pairs > 1 ? expected_pairs : 0;
  parts.stop_flag = install_stop_signals();
  parts.on_problem = [&err](const Error& e) { err << "augrig augment: " << user_message(e) << "\n"; };
  apply_sink_args(a, parts);  // --sink: further outputs (coco:DIR, yolo:DIR, kitti:DIR, ...)
  const StereoPairerConfig pairing = opened.options.pairing;
  parts.source = unwrap(start_stereo(std::move(opened)));
  out << "augment: " << frame_count << " images, " << expected_pairs << " stereo pair(s) "
      << (indexed ? "by timestamp (tolerance " + fmt_ms(static_cast<double>(pairing.tolerance_ns) / 1e3) + " us)"
                  : std::string("by sorted name"))
      << "; poses from " << parts.poses->describe() << "\n";
  Pipeline pipeline(std::move(parts));
  const PipelineReport r = run_pipeline(pipeline, false, out_dir.string(), out, err);

  if (remap_t) {
    StatsCsv csv(out_dir / "stats.csv");
    for (OcclusionStats s : r.all_stats) {
      const auto i = static_cast<std::size_t>(s.t_ns);
      const auto& t = scene_t_ns[scene_t_ns.size() == 1 ? 0 : std::min(i, scene_t_ns.size() - 1)];
      if (t) s.t_ns = *t;
      csv.add(s);
    }
  }
  if (r.all_stats.size() == 1) {
    const auto& e = files->entries();
    out << format_table1(r.all_stats.front(), "Occlusion statistics: " + (e.size() == 2 ? e[0].path + " | " + e[1].path
                                                                                     : std::string("one pair")));
  }
  const std::uint64_t unpaired_l = r.source.pairing.unpaired_left, unpaired_r = r.source.pairing.unpaired_right;
  if (unpaired_l + unpaired_r)
    out << "Frames without a partner (not augmented): left " << unpaired_l << ", right " << unpaired_r
        << (indexed ? " (pairing tolerance " + fmt_ms(static_cast<double>(pairing.tolerance_ns) / 1e3) + " us)"
                    : std::string())
        << "\n";
  if (r.skipped_no_pose)
    out << "Pairs without a pose (not augmented): " << r.skipped_no_pose << " (" << pipeline.parts().poses->describe()
        << ")\n";
  out << "Wrote " << r.pairs << " stereo frame(s) to " << out_dir.string();
  if (r.pairs)
    out << " (augmenter " << fmt_ms(r.augment_ms / static_cast<double>(r.pairs)) << " ms per stereo frame, "
        << to_string(r.rasterizer) << " rasteriser)";
  out << "\n";
  if (r.source_failed) runtime_error("the images could not all be read: " + user_message(Error{r.source_error}));
  if (r.failed_pairs) runtime_error(std::to_string(r.failed_pairs) + " pair(s) failed to augment (above)");
  if (r.stopped_by_signal) return kExitRuntime;
  if (r.pairs == 0) runtime_error("no stereo pair was augmented (above: why)");
  return kExitOk;
}

// ---- Top level ------------------------------------------------------------------------------------

const char* kTopHelp =
    "augrig: augments stereo flight-test images with a virtual refuelling boom, exact per-pixel masks\n"
    "and occlusion statistics.\n"
    "\n"
    "Usage: augrig <command> [options]     (augrig <command> --help for its options)\n"
    "\n"
    "Commands:\n"
    "  augment   augment a stereo pair, or folders of pairs, with a scene file\n"
    "  demo      fly a simulated approach end to end: sim, nav fusion, boom tracking, augmentation\n"
    "  sim       simulate a flight: truth, GPS/IMU logs (NMEA, CSV), rendered stereo frames\n"
    "  nav       fuse both aircraft's GPS/IMU logs into the receiver's pose in each camera per frame\n"
    "  check     check a recording: what it holds, what is damaged (exit 1 if anything is)\n"
    "  replay    replay a recording through the augmenter (recorded or another rig and scene)\n"
    "  export    export a recording as a EuRoC/ASL dataset with poses, statistics and their plot\n"
    "  evaluate  what the boom does to stereo matching: raw vs augmented pairs against the true disparity\n"
    "  cameras   list the GigE Vision, USB3 Vision and V4L2 cameras this machine sees\n"
    "  rig       rig show RIG: what a rig file resolves to (poses, baseline, field of view) and what looks wrong\n"
    "  run       the live pipeline from source URIs: capture, pairing, augmentation, recording\n"
    "  campaign  a campaign of recordings and variants on a cluster: plan (Slurm array), status, resume, merge\n"
    "\n"
    "Options:\n"
    "  --help, -h   this help\n"
    "  --version    print the version\n"
    "\n"
    "Exit codes: 0 ok, 1 runtime error (bad input content, OpenGL failure), 2 usage error.\n"
    "Documentation: docs/CLI.md\n";

}  // namespace

// ---- Argument parsing ---------------------------------------------------------------------------

std::vector<std::string> ParsedArgs::all(const std::string& name) const {
  std::vector<std::string> v;
  if (!has(name)) return v;
  std::istringstream in(get(name));
  for (std::string line; std::getline(in, line);) v.push_back(line);
  return v;
}

Expected<ParsedArgs> parse_args(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs) {
  ParsedArgs p;
  auto find = [&](const std::string& name) -> const OptionSpec* {
    for (const auto& s : specs)
      if (s.name == name) return &s;
    return nullptr;
  };
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      p.help = true;
      continue;
    }
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) {
      return make_error("unexpected argument '", arg, "' (options are --name VALUE; see --help)");
    }
    // "--name=value" or "--name [value]".
    const auto eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    const OptionSpec* spec = find(name);
    if (!spec) return make_error("unknown option '--", name, "'");
    if (p.has(name) && !spec->repeatable) return make_error("option '--", name, "' given twice");
    std::string value;
    if (eq != std::string::npos) {
      if (spec->kind == ArgKind::kFlag) return make_error("option '--", name, "' takes no value");
      value = arg.substr(eq + 1);
    } else if (spec->kind == ArgKind::kValue) {
      if (i + 1 >= args.size())
        return make_error("option '--", name, "' needs a value: --", name, " ", spec->metavar);
      value = args[++i];
    }
    if (spec->kind == ArgKind::kValue && value.empty()) {
      return make_error("option '--", name, "' needs a non-empty value: --", name, " ", spec->metavar);
    }
    p.values[name] = p.has(name) ? p.values[name] + '\n' + value : value;  // repeatable: one per line
  }
  if (!p.help) {
    for (const auto& s : specs) {
      if (s.required && !p.has(s.name))
        return make_error("missing required option --", s.name, " ", s.metavar);
    }
  }
  return p;
}

std::string format_help(const std::string& usage, const std::string& summary,
                        const std::vector<OptionSpec>& specs) {
  std::ostringstream o;
  o << "Usage: " << usage << "\n\n" << summary << "\n\nOptions:\n";
  for (const auto& s : specs) {
    std::string left = "  --" + s.name;
    if (!s.metavar.empty()) left += (s.kind == ArgKind::kOptionalValue ? "" : " ") + s.metavar;
    o << left;
    if (left.size() < 36) {
      o << std::string(36 - left.size(), ' ');
    } else {
      o << "\n" << std::string(36, ' ');
    }
    o << s.help << (s.required ? " (required)" : "") << "\n";
  }
  o << "  --help, -h" << std::string(24, ' ') << "this help\n";
  return o.str();
}

// ---- Images -------------------------------------------------------------------------------------

Expected<Image> read_image_file(const std::string& path, std::optional<PixelFormat> bayer) {
  return augrig::read_image_file(path, bayer);
}

Status write_image_file(const std::string& path, const Image& image, int png_compression) {
  std::error_code ec;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  if (ec) return make_error(parent.string(), ": cannot create the folder (", ec.message(), ")");
  return write_png_file(path, image, png_compression);
}

// ---- Commands -----------------------------------------------------------------------------------

int cmd_augment(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("augment", err, [&] { return augment(args, out, err); });
}

int run_cli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  if (args.empty()) {
    err << kTopHelp;
    return kExitUsage;
  }
  const std::string& command = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (command == "--help" || command == "-h" || command == "help") {
    out << kTopHelp;
    return kExitOk;
  }
  if (command == "--version") {
    out << "augrig " << AUGRIG_VERSION << "\n";
    return kExitOk;
  }
  if (command == "augment") return cmd_augment(rest, out, err);
  if (command == "demo") return cmd_demo(rest, out, err);
  if (command == "sim") return cmd_sim(rest, out, err);
  if (command == "nav") return cmd_nav(rest, out, err);
  if (command == "check") return cmd_check(rest, out, err);
  if (command == "replay") return cmd_replay(rest, out, err);
  if (command == "export") return cmd_export(rest, out, err);
  if (command == "evaluate") return cmd_evaluate(rest, out, err);
  if (command == "rig") return cmd_rig(rest, out, err);
  if (command == "cameras") return cmd_cameras(rest, out, err);
  if (command == "run") return cmd_run(rest, out, err);
  if (command == "campaign") return cmd_campaign(rest, out, err);
  err << "augrig: unknown command '" << command
      << "'; commands: augment, demo, sim, nav, check, replay, export, evaluate, cameras, rig, run, campaign (see augrig --help)\n";
  return kExitUsage;
}

}  // namespace augrig::app
