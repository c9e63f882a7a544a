// augrig export DIR --format euroc OUT: a recording in the EuRoC/ASL layout, with its poses,
// statistics and their plot (docs/REPLAY.md). The recording is opened (and so checked to be one)
// first; OUT/INCOMPLETE marks an export that has not finished cleanly.
#include <fstream>

#include "app/cli.hpp"
#include "recorder/euroc.hpp"
#include "recorder/reader.hpp"

namespace augrig::app {
namespace {

// ---- export -------------------------------------------------------------------------------------

const std::vector<OptionSpec>& export_specs() {
  static const std::vector<OptionSpec> specs = {
      {"format", ArgKind::kValue, "euroc", "output layout: euroc (EuRoC/ASL, docs/REPLAY.md)", true},
      {"rig", ArgKind::kValue, "RIG.yaml|default",
       "intrinsics and extrinsics for sensor.yaml (default: the recorded rig)"},
      {"imu-stream", ArgKind::kValue, "NAME",
       "nav input stream exported as imu0 (default: imu, else tanker.imu)"},
      {"no-augmented", ArgKind::kFlag, "", "leave out cam0_augmented and cam1_augmented"},
      {"no-masks", ArgKind::kFlag, "", "leave out cam0_mask and cam1_mask"},
      {"no-plot", ArgKind::kFlag, "", "do not plot the statistics (stats.png needs gnuplot)"},
  };
  return specs;
}

int export_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  std::vector<std::string> pos;
  const ParsedArgs a = parse_with_positionals(args, export_specs(), {"DIR", "OUT"}, pos);
  if (a.help) {
    out << format_help(
        "augrig export DIR --format euroc OUT [options]",
        "Writes a recording in the EuRoC/ASL layout: OUT/mav0/cam0, cam1 (raw), cam0_augmented,\n"
        "cam1_augmented, cam0_mask, cam1_mask (data.csv, data/<t_ns>.png, sensor.yaml) and imu0, plus\n"
        "OUT/poses.csv (recorded T_cam_receiver), OUT/stats.csv and OUT/stats.png (gnuplot).",
        export_specs());
    return kExitOk;
  }
  if (a.get("format") != "euroc") usage_error("--format: expected euroc, got '" + a.get("format") + "'");
  recorder::EurocExportOptions o;
  if (a.has("rig")) o.rig = load_rig_arg(a.get("rig"));
  o.imu_stream = a.get("imu-stream");
  o.augmented = !a.has("no-augmented");
  o.masks = !a.has("no-masks");
  o.plot = !a.has("no-plot");
  const auto reader = open_recording(pos[0]);
  const fs::path out_dir = pos[1];
  // OUT/INCOMPLETE exists until the export has finished without a problem: a killed or failed
  // export is marked as such, and what is missing is written into it.
  const fs::path marker = out_dir / "INCOMPLETE";
  auto write_marker = [&](const std::vector<std::string>& lines) {
    std::ofstream m(marker);
    m << "augrig export " << pos[0] << " -> " << pos[1] << " is incomplete";
    m << (lines.empty() ? ": it was still running or was stopped before the end\n" : ":\n");
    for (const std::string& l : lines) m << l << "\n";
    if (!m) runtime_error(marker.string() + ": cannot be written");
  };
  if (!fs::exists(out_dir / "mav0")) {  // export_euroc refuses an existing mav0: no marker for that
    make_dirs(out_dir);
    write_marker({});
  }
  recorder::EurocExportReport r;
  if (Status s = recorder::export_euroc(*reader, pos[1], o, r); !s) {
    if (fs::exists(marker)) write_marker({user_message(s.error())});
    check(s);
  }
  // The recording's own damage (a truncated file: frames its summary counts but no row holds).
  for (auto p = reader->problems().rbegin(); p != reader->problems().rend(); ++p)
    r.problems.insert(r.problems.begin(), recording_problem(*reader, *p));

  const std::string summary_frames = reader->meta("summary.frames");
  out << "Exported " << r.frames_written << " of "
      << (summary_frames.empty() || summary_frames == std::to_string(r.frames)
              ? std::to_string(r.frames)
              : std::to_string(r.frames) + " readable (" + summary_frames + " recorded)")
      << " stereo frame(s) to " << (out_dir / "mav0").string() << ": cam0, cam1";
  if (r.augmented_written) out << ", cam0_augmented, cam1_augmented";
  if (r.masks_written) out << ", cam0_mask, cam1_mask";
  if (r.imu_samples) out << ", imu0 (" << r.imu_samples << " samples of '" << r.imu_stream << "')";
  out << "; " << r.rate_hz << " Hz\n";
  if (r.pose_rows) out << "Wrote " << (out_dir / "poses.csv").string() << " (" << r.pose_rows << " rows)\n";
  if (r.stats_rows) out << "Wrote " << (out_dir / "stats.csv").string() << " (" << r.stats_rows << " rows)\n";
  if (r.plotted) out << "Wrote " << (out_dir / "stats.png").string() << "\n";
  for (const std::string& n : r.notes) out << "note: " << n << "\n";
  for (const std::string& p : r.problems) err << "augrig export: " << p << "\n";
  if (!r.problems.empty()) {
    write_marker(r.problems);
    runtime_error("the export is incomplete: " + std::to_string(r.problems.size()) +
                  " problem(s) (above; listed in " + marker.string() + ")");
  }
  fs::remove(marker);
  return kExitOk;
}

}  // namespace

int cmd_export(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("export", err, [&] { return export_command(args, out, err); });
}

}  // namespace augrig::app
