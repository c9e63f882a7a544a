// augrig export DIR --format euroc OUT: a recording in the EuRoC/ASL layout, with its poses,
// statistics and their plot, and per aircraft the nav logs `augrig nav` fuses again, all on one
// clock (docs/REPLAY.md). The recording is opened (and so checked to be one) first;
// recorder::export_euroc() keeps OUT/INCOMPLETE until it has finished cleanly. A rate line with the
// ETA goes to stderr about once a second. --format mcap writes one MCAP file of ROS 2 messages
// instead (recorder/mcap_export.hpp, docs/MCAP.md); --format kitti|middlebury the stereo benchmarks'
// layouts (always augmented again: pipeline/sinks/stereo_benchmark_sink.cpp), --format coco|yolo the
// keypoint labels (augmented again: pipeline/sinks/labels_sink.cpp). --reaugment replays
// the input through the pipeline into the format's writer instead of exporting the recorded
// augmentation.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <iomanip>

#include "app/cli.hpp"
#include "recorder/euroc.hpp"
#include "recorder/mcap_export.hpp"
#include "pipeline/sinks/registry.hpp"
#include "recorder/reader.hpp"

namespace augrig::app {
namespace {

// ---- export -------------------------------------------------------------------------------------

const std::vector<OptionSpec>& export_specs() {
  static const std::vector<OptionSpec> specs = {
      {"format", ArgKind::kValue, "euroc|mcap|kitti|middlebury|coco|yolo",
       "output layout: euroc (EuRoC/ASL folder, docs/REPLAY.md), mcap (one MCAP file of ROS 2 messages, "
       "docs/MCAP.md), or the stereo benchmarks' kitti and middlebury (rectified pairs with the true "
       "disparity, always augmented again; docs/BENCHMARKS.md), or coco and yolo (receiver keypoints with "
       "their occlusion, boxes and masks for pose estimation, always augmented again; docs/LABELS.md); "
       "default: mcap when OUT ends in .mcap, else euroc"},
      {"rig", ArgKind::kValue, "RIG.yaml|default",
       "intrinsics and extrinsics for sensor.yaml (default: the recorded rig); with --reaugment also the "
       "augmentation's"},
      {"imu-stream", ArgKind::kValue, "NAME",
       "nav input stream exported as imu0 (default: imu, else tanker.imu)"},
      {"aircraft", ArgKind::kValue, "tanker=FILE,receiver=FILE",
       "aircraft.yaml of each aircraft for OUT/nav/<aircraft>/ (default: the recording's, if it holds them)"},
      {"threads", ArgKind::kValue, "N", "threads encoding the images (default: one per core)"},
      {"no-augmented", ArgKind::kFlag, "", "leave out cam0_augmented and cam1_augmented"},
      {"no-masks", ArgKind::kFlag, "", "leave out cam0_mask and cam1_mask"},
      {"images", ArgKind::kValue, "raw|jpeg|h264",
       "--format mcap: the raw and augmented images as they are (raw, default), as JPEG "
       "(sensor_msgs/msg/CompressedImage on .../compressed; lossy, a tenth of the size) or as H.264 "
       "(foxglove_msgs/msg/CompressedVideo on .../h264; lossy, smaller still); masks stay lossless"},
      {"jpeg-quality", ArgKind::kValue, "Q", "with --images jpeg: the JPEG quality, 1..100 (default 90)"},
      {"h264-crf", ArgKind::kValue, "N",
       "with --images h264: x264's quality, 0 (lossless) .. 51 (default 23)"},
      {"keyframe-interval", ArgKind::kValue, "N",
       "with --images h264: an IDR keyframe every N frames of each topic (default 30)"},
      {"no-plot", ArgKind::kFlag, "", "do not plot the statistics (stats.png needs gnuplot)"},
      {"ground-truth", ArgKind::kFlag, "",
       "also each frame's ground truth from its recorded receiver depth (docs/GROUND_TRUTH.md): cam0_depth, "
       "cam1_depth (.npy), cam0_depth_mm, cam1_depth_mm (16-bit PNG), cam0_right_px (.npy), "
       "cam0_stereo_class; "
       "needs a recording made with --ground-truth (or --reaugment)"},
      {"reaugment", ArgKind::kFlag, "",
       "augment the raw frames again through the pipeline (with --rig and the options below) instead of "
       "exporting the recorded augmentation; DIR may then be a recording, an MCAP file or a EuRoC folder"},
      scene_option("each frame's recorded scene; implies --reaugment"),
      poses_option("implies --reaugment"),
      pose_tolerance_option(),
      boom_option("the recorded boom; implies --reaugment"),
      look_option(),
      receiver_draw_option(),
  };
  return specs;
}

// --images raw|jpeg|h264, --jpeg-quality Q, --h264-crf N and --keyframe-interval N (--format mcap only).
void apply_image_args(const ParsedArgs& a, recorder::McapExportOptions& o) {
  const std::string images = a.get("images", "raw");
  if (images != "raw" && images != "jpeg" && images != "h264")
    usage_error("--images: expected raw, jpeg or h264, got '" + images + "'");
  o.jpeg = images == "jpeg";
  o.h264 = images == "h264";
  if (a.has("jpeg-quality")) {
    if (!o.jpeg) usage_error("--jpeg-quality needs --images jpeg");
    o.jpeg_quality = static_cast<int>(parse_integer("jpeg-quality", a.get("jpeg-quality"), 1, 100));
  }
  for (const char* flag : {"h264-crf", "keyframe-interval"})
    if (a.has(flag) && !o.h264) usage_error(std::string("--") + flag + " needs --images h264");
  if (a.has("h264-crf")) o.h264_crf = static_cast<int>(parse_integer("h264-crf", a.get("h264-crf"), 0, 51));
  if (a.has("keyframe-interval"))
    o.h264_gop_frames =
        static_cast<int>(parse_integer("keyframe-interval", a.get("keyframe-interval"), 1, 100000));
}

// The mcap sink's options for the same flags (export --reaugment --format mcap).
std::string image_sink_options(const ParsedArgs& a) {
  recorder::McapExportOptions o;
  apply_image_args(a, o);
  if (o.h264) return ",h264=" + std::to_string(o.h264_crf) + ",gop=" + std::to_string(o.h264_gop_frames);
  return o.jpeg ? ",jpeg=" + std::to_string(o.jpeg_quality) : "";
}

// --format mcap: the recording as one MCAP file (written as OUT.part, renamed when complete).
int export_mcap_command(const ParsedArgs& a, const std::vector<std::string>& pos, std::ostream& out,
                        std::ostream& err) {
  for (const char* flag : {"imu-stream", "aircraft", "threads", "no-plot", "ground-truth"})
    if (a.has(flag)) usage_error(std::string("--") + flag + ": only for --format euroc");
  recorder::McapExportOptions o;
  if (a.has("rig")) o.rig = load_rig_arg(a.get("rig"));
  o.augmented = !a.has("no-augmented");
  o.masks = !a.has("no-masks");
  apply_image_args(a, o);
  const auto reader = open_recording(pos[0]);
  auto last = std::chrono::steady_clock::now();
  o.progress = [&err, &last](std::size_t done, std::size_t total) {
    const auto now = std::chrono::steady_clock::now();
    if (done == total || now - last < std::chrono::seconds(1)) return;
    last = now;
    err << "export: " << done << "/" << total << " frames\n" << std::flush;
  };
  recorder::McapExportReport r;
  check(recorder::export_mcap(*reader, pos[1], o, r));
  out << "Exported " << r.frames_written << " of " << r.frames << " stereo frame(s) to " << pos[1] << ": "
      << r.messages << " messages in " << r.chunks << " zstd chunk(s), " << r.bytes << " bytes\n";
  for (const auto& [topic, n] : r.messages_by_topic) out << "  " << topic << ": " << n << "\n";
  for (const std::string& n : r.notes) out << "note: " << n << "\n";
  for (const std::string& p : r.problems) err << "augrig export: " << p << "\n";
  if (!r.problems.empty())
    runtime_error("the export is incomplete: " + std::to_string(r.problems.size()) + " problem(s) (above)");
  return kExitOk;
}

// The EuRoC options the flags give (the rig: --rig, unless the export augments again, whose rig
// is the replay's).
recorder::EurocExportOptions euroc_options(const ParsedArgs& a, bool rig_from_flag) {
  recorder::EurocExportOptions o;
  if (a.has("rig") && rig_from_flag) o.rig = load_rig_arg(a.get("rig"));
  o.imu_stream = a.get("imu-stream");
  o.augmented = !a.has("no-augmented");
  o.masks = !a.has("no-masks");
  o.plot = !a.has("no-plot");
  o.ground_truth = a.has("ground-truth");
  if (a.has("threads")) o.threads = static_cast<int>(parse_integer("threads", a.get("threads"), 1, 64));
  if (a.has("aircraft")) {
    std::stringstream ss(a.get("aircraft"));
    std::string item;
    while (std::getline(ss, item, ',')) {
      const auto eq = item.find('=');
      const std::string who = eq == std::string::npos ? "" : item.substr(0, eq);
      if (who != "tanker" && who != "receiver")
        usage_error("--aircraft: expected tanker=FILE or receiver=FILE, got '" + item + "'");
      const std::string file = item.substr(eq + 1);
      std::ifstream in(file, std::ios::binary);
      if (!in) runtime_error("--aircraft: " + file + ": cannot open the file");
      o.aircraft_yaml[who] = std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    }
  }
  return o;
}

int report_euroc(const recorder::EurocExportReport& r, const fs::path& out_dir, const std::string& summary_frames,
                 std::ostream& out, std::ostream& err);

// --format euroc: the recording as a EuRoC/ASL folder, with a rate line about once a second (the
// library prints nothing itself).
int export_euroc_command(const ParsedArgs& a, const std::vector<std::string>& pos, std::ostream& out,
                         std::ostream& err) {
  const auto reader = open_recording(pos[0]);
  recorder::EurocExportOptions o = euroc_options(a, true);
  o.progress = [&err](const recorder::EurocExportProgress& p) {
    if (p.final) return;
    std::ostringstream line;
    line << "export: " << p.frames_done << "/" << p.frames_total << " frames, " << std::fixed
         << std::setprecision(1) << p.frames_per_s << "/s, ETA ";
    const long eta = std::lround(p.eta_s);
    if (eta >= 60) line << eta / 60 << " min ";
    line << eta % 60 << " s\n";
    err << line.str() << std::flush;
  };
  recorder::EurocExportReport r;
  check(recorder::export_euroc(*reader, pos[1], o, r));
  return report_euroc(r, pos[1], reader->meta("summary.frames"), out, err);
}

// What an export to EuRoC wrote, and its problems (exit 1 after everything else was written).
int report_euroc(const recorder::EurocExportReport& r, const fs::path& out_dir, const std::string& summary_frames,
                 std::ostream& out, std::ostream& err) {
  out << "Exported " << r.frames_written << " of "
      << (summary_frames.empty() || summary_frames == std::to_string(r.frames)
              ? std::to_string(r.frames)
              : std::to_string(r.frames) + " readable (" + summary_frames + " recorded)")
      << " stereo frame(s) to " << (out_dir / "mav0").string() << ": cam0, cam1";
  if (r.augmented_written) out << ", cam0_augmented, cam1_augmented";
  if (r.masks_written) out << ", cam0_mask, cam1_mask";
  if (r.ground_truth_written)
    out << ", cam0_depth, cam1_depth, cam0_depth_mm, cam1_depth_mm, cam0_right_px, cam0_stereo_class ("
        << r.ground_truth_written << " frames)";
  if (r.imu_samples) out << ", imu0 (" << r.imu_samples << " samples of '" << r.imu_stream << "')";
  out << "; " << r.rate_hz << " Hz\n";
  out << "Clock: " << to_string(r.clock) << " for every timestamp exported (" << r.clock_note << ")\n";
  for (const std::string& who : r.nav_logs)
    out << "Wrote " << (out_dir / "nav" / who).string() << " (gps.nmea, imu.csv"
        << (fs::exists(out_dir / "nav" / who / "aircraft.yaml") ? ", aircraft.yaml" : "") << ")\n";
  if (r.frame_index_rows)
    out << "Wrote " << (out_dir / "frames.csv").string() << " (" << r.frame_index_rows << " rows)\n";
  if (r.nav_logs.size() == 2 && r.frame_index_rows) {
    out << "Re-fuse with: augrig nav --tanker " << (out_dir / "nav" / "tanker").string() << " --receiver "
        << (out_dir / "nav" / "receiver").string() << " --rig " << (out_dir / "rig.yaml").string() << " --frames "
        << (out_dir / "frames.csv").string() << " --out POSES.csv";
    // augrig nav refuses an aircraft folder without aircraft.yaml unless the defaults are asked for.
    if (!fs::exists(out_dir / "nav" / "tanker" / "aircraft.yaml") ||
        !fs::exists(out_dir / "nav" / "receiver" / "aircraft.yaml"))
      out << " --default-aircraft\n  (no aircraft.yaml exported: nav's defaults stand in for the lever arms and IMU "
             "noise; export with --aircraft tanker=FILE,receiver=FILE to fuse with the aircraft's own)";
    out << "\n";
  }
  if (r.pose_rows) out << "Wrote " << (out_dir / "poses.csv").string() << " (" << r.pose_rows << " rows)\n";
  if (r.stats_rows) out << "Wrote " << (out_dir / "stats.csv").string() << " (" << r.stats_rows << " rows)\n";
  if (r.phases) out << "Wrote " << (out_dir / "phases.csv").string() << " (" << r.phases << " phases)\n";
  if (r.plotted) out << "Wrote " << (out_dir / "stats.png").string() << "\n";
  for (const std::string& n : r.notes) out << "note: " << n << "\n";
  for (const std::string& p : r.problems) err << "augrig export: " << p << "\n";
  if (!r.problems.empty()) {
    runtime_error("the export is incomplete: " + std::to_string(r.problems.size()) + " problem(s) (above; listed in " +
                  (out_dir / "INCOMPLETE").string() + ")");
  }
  return kExitOk;
}

// The formats written by a sink of their own name (export_benchmark), always augmented again.
bool sink_format(const std::string& format) {
  return format == "kitti" || format == "middlebury" || format == "coco" || format == "yolo";
}

// Whether the export augments again: --reaugment, or an option that only a new augmentation uses.
bool reaugmenting(const ParsedArgs& a) {
  for (const char* k : {"reaugment", "scene", "poses", "pose-tolerance-ms", "boom", "look", "receiver-draw"})
    if (a.has(k)) return true;
  return false;
}

// --format kitti|middlebury|coco|yolo: the input through the pipeline into that format's sink
// (pipeline/sinks/stereo_benchmark_sink.cpp, labels_sink.cpp); the EuRoC and MCAP options have no
// place there.
int export_benchmark(const ParsedArgs& replay, const std::vector<std::string>& pos, const std::string& format,
                     const ParsedArgs& a, std::ostream& out, std::ostream& err) {
  for (const char* flag : {"imu-stream", "aircraft", "threads", "no-plot", "ground-truth", "no-augmented", "no-masks"})
    if (a.has(flag)) usage_error(std::string("--") + flag + ": only for --format euroc or mcap");
  return replay_into(pos[0], replay,
                     [&](PipelineParts& parts) {
                       auto sink = make_sink(format + ":" + pos[1], {parts.rig});
                       if (!sink) runtime_error(sink.error().message);
                       parts.sinks.push_back(std::move(*sink));
                     },
                     out, err);
}

// export --reaugment: the input through the pipeline again (replay_into, headless, as fast as it
// goes) with the augmentation's options, into the format's sink (pipeline/sinks/): the mcap sink
// or the euroc sink, each with the input recording's nav inputs (and for EuRoC its clock).
int export_reaugmented(const ParsedArgs& a, const std::vector<std::string>& pos, const std::string& format,
                       std::ostream& out, std::ostream& err) {
  ParsedArgs replay;
  for (const char* k : {"rig", "scene", "poses", "pose-tolerance-ms", "boom", "look", "receiver-draw"})
    if (a.has(k)) replay.values[k] = a.get(k);
  replay.values["headless"] = "";
  // A recording's nav inputs and meta go with the export (an MCAP file or a EuRoC folder has none).
  const fs::path in = pos[0].rfind("replay://", 0) == 0 ? pos[0].substr(9) : pos[0];
  std::unique_ptr<recorder::RecordingReader> nav_from;
  if (fs::is_directory(in) && !fs::exists(in / "mav0") && in.filename() != "mav0") nav_from = open_recording(in);
  if (sink_format(format)) return export_benchmark(replay, pos, format, a, out, err);
  if (format == "mcap") {
    for (const char* flag : {"imu-stream", "aircraft", "threads", "no-plot", "ground-truth"})
      if (a.has(flag)) usage_error(std::string("--") + flag + ": only for --format euroc");
    std::map<std::string, std::string> meta;
    if (nav_from) meta = nav_from->meta();
    meta["re_augmented_from"] = pos[0];
    const std::string spec = "mcap:" + pos[1] + (a.has("no-augmented") ? ",no-augmented" : "") +
                             (a.has("no-masks") ? ",no-masks" : "") + image_sink_options(a);
    return replay_into(pos[0], replay,
                       [&](PipelineParts& parts) {
                         auto sink = make_sink(spec, {parts.rig, meta, nav_from.get()});
                         if (!sink) runtime_error(sink.error().message);
                         parts.sinks.push_back(std::move(*sink));
                       },
                       out, err);
  }
  // EuRoC: the euroc sink, with the input recording's nav inputs and its clock.
  const recorder::EurocExportOptions o = euroc_options(a, false);
  recorder::EurocExportReport r;
  const int rc = replay_into(pos[0], replay,
                             [&](PipelineParts& parts) {
                               auto sink = make_euroc_sink(pos[1], o, {parts.rig, {}, nav_from.get()}, &r);
                               if (!sink) runtime_error(sink.error().message);
                               parts.sinks.push_back(std::move(*sink));
                             },
                             out, err);
  if (rc != kExitOk) return rc;
  return report_euroc(r, pos[1], "", out, err);
}

int export_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> pos;
  const ParsedArgs a = parse_with_positionals(args, export_specs(), {"DIR", "OUT"}, pos);
  if (a.help) {
    out << format_help(
        "augrig export DIR --format euroc OUT [options]\n       augrig export DIR --format mcap OUT.mcap [options]\n"
        "       augrig export IN OUT --format kitti|middlebury|coco|yolo [--rig R] [--scene S|--poses P] [--boom B] [--look L]\n"
        "       augrig export IN OUT --reaugment [--rig R] [--scene S|--poses P] [--boom B] [--look L] [options]",
        "Writes a recording in the EuRoC/ASL layout: OUT/mav0/cam0, cam1 (raw), cam0_augmented,\n"
        "cam1_augmented, cam0_mask, cam1_mask (data.csv, data/<t_ns>.png, sensor.yaml) and imu0, plus\n"
        "OUT/poses.csv (recorded T_cam_receiver), OUT/stats.csv and OUT/stats.png (gnuplot); with nav\n"
        "inputs, OUT/nav/<aircraft>/ (gps.nmea, imu.csv, aircraft.yaml) and the frame index OUT/frames.csv\n"
        "for augrig nav. Every timestamp is on one clock: GPS time when the recording allows it.\n"
        "With --ground-truth, the receiver depth, the true correspondence and the stereo classes too.\n"
        "--format mcap: one MCAP file for ros2 bag and Foxglove (ROS 2 messages in CDR, zstd chunks, indexed):\n"
        "per camera image_raw, image_augmented, mask, camera_info, receiver_pose; /tf_static, /tf,\n"
        "/augrig/frame, /augrig/occlusion_stats and the nav inputs (docs/MCAP.md). augrig replay OUT.mcap\n"
        "plays it back.\n"
        "--reaugment (or --scene, --poses, --boom, --look, --receiver-draw): DIR (a recording, an MCAP\n"
        "file or a EuRoC folder) is augmented again through the pipeline, with the rig and scene recorded\n"
        "or given, into either format (docs/REPLAY.md).\n"
        "--format kitti|middlebury: IN augmented again (as --reaugment), each pair rectified, raw and\n"
        "augmented, in the stereo benchmark's layout with the receiver's true disparity, the calibration\n"
        "files and the boom masks (docs/BENCHMARKS.md).\n"
        "--format coco|yolo: IN augmented again, each camera's augmented image with the receiver's keypoints\n"
        "(visible, hidden by the boom or by the receiver), boxes and masks of receiver and boom, in COCO's\n"
        "keypoint JSON or YOLO's pose layout (docs/LABELS.md).",
        export_specs());
    return kExitOk;
  }
  // Without --format, OUT's name says which: a .mcap file, else a EuRoC folder.
  const bool mcap_name = fs::path(pos[1]).extension() == ".mcap";
  const std::string format = a.has("format") ? a.get("format") : mcap_name ? "mcap" : "euroc";
  if (format != "euroc" && format != "mcap" && !sink_format(format))
    usage_error("--format: expected euroc, mcap, kitti, middlebury, coco or yolo, got '" + format + "'");
  for (const char* flag : {"images", "jpeg-quality", "h264-crf", "keyframe-interval"})
    if (a.has(flag) && format != "mcap") usage_error(std::string("--") + flag + ": only for --format mcap");
  // The benchmarks' true disparity and the labels come from the masks and receiver depth a new
  // augmentation draws.
  if (reaugmenting(a) || sink_format(format))
    return export_reaugmented(a, pos, format, out, err);
  if (format == "mcap") return export_mcap_command(a, pos, out, err);
  return export_euroc_command(a, pos, out, err);
}

}  // namespace

int cmd_export(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("export", err, [&] { return export_command(args, out, err); });
}

}  // namespace augrig::app
