// export_euroc() (euroc.hpp): the order of the export's steps and the files made from what the
// frames gave (recorder/euroc_export_detail.hpp names the other steps' files). EurocSource reads
// the export back (euroc_source.cpp).
#include "recorder/euroc.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "nav/logs.hpp"
#include "recorder/euroc_export_detail.hpp"
#include "recorder/plot.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder {

namespace fs = std::filesystem;

// ---- Helpers the export's parts share (recorder/euroc_export_detail.hpp) ----------------------------

namespace euroc_detail {

std::string num(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest text that reads back exactly
  return std::string(buf, r.ptr);
}

std::string strip_function(const std::string& m) {
  const auto p = m.find("(): ");
  if (p != std::string::npos && p < 64 && m.find(' ') > p) return m.substr(p + 4);
  return m;
}

Status write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) return make_error(path.string(), ": cannot write the file");
  return {};
}

namespace {

// A rotation's entries come from its quaternion (Pose), a few ulps off where they are exactly 0
// or +-1 (a camera looking straight aft: -0.9999999999999999, 1.7e-16): those are written exact.
double snap_unit(double v) {
  for (double u : {0.0, 1.0, -1.0})
    if (std::abs(v - u) < 1e-14) return u;
  return v;
}

}  // namespace

std::string matrix_row_major(const Eigen::Matrix4d& T) {
  std::string s = "[";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      s += (r || c ? ", " : "") + num(r < 3 && c < 3 ? snap_unit(T(r, c)) : T(r, c));
  return s + "]";
}

double median_rate_hz(std::vector<TimestampNs> t) {
  std::sort(t.begin(), t.end());
  std::vector<TimestampNs> d;
  for (std::size_t i = 1; i < t.size(); ++i)
    if (t[i] > t[i - 1]) d.push_back(t[i] - t[i - 1]);
  if (d.empty()) return 0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  const double hz = 1e9 / static_cast<double>(d[d.size() / 2]);
  return std::round(hz * 1000.0) / 1000.0;
}

Eigen::Vector3d central_difference_mps(const std::vector<TimestampNs>& t_ns,
                                       const std::vector<Eigen::Vector3d>& p_m, std::size_t i) {
  const std::size_t n = t_ns.size();
  const std::size_t a = i > 0 ? i - 1 : i, b = i + 1 < n ? i + 1 : i;
  if (b == a || t_ns[b] == t_ns[a]) return Eigen::Vector3d::Zero();
  return (p_m[b] - p_m[a]) / (static_cast<double>(t_ns[b] - t_ns[a]) * 1e-9);
}

bool is_nmea_line(const std::string& s) {
  return !s.empty() && (s.front() == '$' || s.front() == '!');
}

Error no_depth_error(const RecordingReader& reader, std::size_t i, std::uint64_t pair_sequence,
                     const std::string& how_many) {
  const fs::path db(reader.path());
  const std::string dir =
      db.filename() == "recording.sqlite" && db.has_parent_path() ? db.parent_path().string() : db.string();
  return make_error(reader.path(), ": frame ", i, " (pair_sequence ", pair_sequence,
                    ") holds no receiver depth", how_many,
                    ", and the ground truth is made from it: the recording was made without --ground-truth. "
                    "Store it by replaying the recording into a new one: augrig replay ",
                    dir, " --record NEW --ground-truth --headless; then export NEW --ground-truth");
}

ExportProgress::ExportProgress(const EurocExportOptions& options, std::size_t frames_total)
    : options_(options), total_(frames_total), start_(std::chrono::steady_clock::now()), last_(start_) {}

void ExportProgress::update(const EurocExportReport& report, std::size_t skipped, bool final) {
  if (!options_.progress) return;
  const auto now = std::chrono::steady_clock::now();
  if (!final && std::chrono::duration<double>(now - last_).count() < options_.progress_interval_s) return;
  last_ = now;
  EurocExportProgress p;
  p.frames_total = total_;
  p.frames_written = report.frames_written;
  p.frames_skipped = skipped;
  p.frames_done = p.frames_written + p.frames_skipped;
  p.elapsed_s = std::chrono::duration<double>(now - start_).count();
  p.frames_per_s = p.elapsed_s > 0 ? static_cast<double>(p.frames_done) / p.elapsed_s : 0;
  p.eta_s = p.frames_per_s > 0 ? static_cast<double>(total_ - p.frames_done) / p.frames_per_s : 0;
  p.final = final;
  options_.progress(p);
}

}  // namespace euroc_detail

using namespace euroc_detail;

// ---- Export -----------------------------------------------------------------------------------------

std::string euroc_camera_yaml(const RigCamera& camera, const std::string& side, const std::string& stream,
                              double rate_hz, PixelFormat format, ClockDomain clock) {
  const CameraModel& m = camera.model;
  std::string model = "radial-tangential";
  std::vector<double> coeffs = {0, 0, 0, 0};
  if (m.distortion == DistortionModel::kRadTan) {
    coeffs = {m.coeffs[0], m.coeffs[1], m.coeffs[2], m.coeffs[3]};
    if (m.coeffs[4] != 0) coeffs.push_back(m.coeffs[4]);  // k3: OpenCV's fifth coefficient
  } else if (m.distortion == DistortionModel::kEquidistant) {
    model = "equidistant";
    coeffs = {m.coeffs[0], m.coeffs[1], m.coeffs[2], m.coeffs[3]};
  }
  std::string c = "[";
  for (std::size_t i = 0; i < coeffs.size(); ++i) c += (i ? ", " : "") + num(coeffs[i]);
  c += "]";
  std::ostringstream o;
  o << "# augrig export: the " << side << " camera ('" << camera.name << "'), " << stream << " images.\n"
    << "# T_BS: sensor S = the camera's OpenCV frame (x right, y down, z along the optical axis) in the\n"
    << "# body frame B = the tanker body frame (FRD: x forward, y right, z down): p_B = T_BS * p_S,\n"
    << "# 4x4, row-major, metres. Pixel (0, 0) is the centre of the top-left pixel.\n"
    << "sensor_type: camera\n"
    << "comment: \"augrig " << side << " camera, " << stream << "\"\n"
    << "T_BS:\n  cols: 4\n  rows: 4\n  data: " << matrix_row_major(camera.T_body_cam.matrix()) << "\n"
    << "rate_hz: " << num(rate_hz) << "\n"
    << "resolution: [" << m.width_px << ", " << m.height_px << "]\n"
    << "camera_model: pinhole\n"
    << "intrinsics: [" << num(m.fx_px) << ", " << num(m.fy_px) << ", " << num(m.cx_px) << ", " << num(m.cy_px)
    << "]  # fu, fv, cu, cv\n"
    << "distortion_model: " << model << "\n"
    << "distortion_coefficients: " << c
    << (model == "equidistant" ? "  # k1, k2, k3, k4"
        : coeffs.size() == 5   ? "  # k1, k2, p1, p2, k3"
                               : "  # k1, k2, p1, p2")
    << "\n"
    << "# How the PNGs decode: a Bayer mosaic is stored as 8-bit gray, the pattern is pixel_format.\n"
    << "augrig:\n  stream: " << stream << "\n  pixel_format: " << to_string(format)
    << "\n  clock: " << to_string(clock) << "\n  near_m: " << num(camera.near_m)
    << "\n  far_m: " << num(camera.far_m) << "\n";
  return o.str();
}

namespace {

void write_marker(const fs::path& marker, const std::string& recording, const std::string& out,
                  const std::vector<std::string>& lines) {
  std::ofstream m(marker, std::ios::binary);
  m << "augrig export " << recording << " -> " << out << " is incomplete";
  m << (lines.empty() ? ": it was still running or was stopped before the end\n" : ":\n");
  for (const std::string& l : lines) m << l << "\n";
}

// mav0/state_groundtruth_estimate0 in EuRoC's layout and columns, for the receiver: R (EuRoC's
// reference frame) is the tanker body frame (FRD), S the receiver body frame (FRD); p_RS_R and q_RS
// from the recorded T_body_receiver, v_RS_R by central differences of the positions (one-sided at
// the ends), the IMU biases 0 (augrig estimates none). sensor.yaml says so.
Status write_receiver_states(const fs::path& dir, const std::vector<std::pair<TimestampNs, Pose>>& states) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return make_error(dir.string(), ": cannot create the folder (", ec.message(), ")");
  std::string csv =
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
      "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad "
      "s^-1], "
      "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n";
  std::vector<TimestampNs> times;
  std::vector<Eigen::Vector3d> positions;
  for (const auto& [t, T] : states) {
    times.push_back(t);
    positions.push_back(T.translation_m);
  }
  for (std::size_t i = 0; i < states.size(); ++i) {
    const auto& [t, T] = states[i];
    const Eigen::Vector3d v = central_difference_mps(times, positions, i);
    const Eigen::Quaterniond q = T.rotation.normalized();
    csv += std::to_string(t);
    for (double x : {T.translation_m.x(), T.translation_m.y(), T.translation_m.z(), q.w(), q.x(), q.y(),
                     q.z(), v.x(), v.y(), v.z()})
      csv += "," + num(x);
    csv += ",0,0,0,0,0,0\n";
  }
  if (auto s = write_text(dir / "data.csv", csv); !s) return s;
  return write_text(
      dir / "sensor.yaml",
      "# The receiver's pose relative to the tanker, as recorded (augrig export; docs/REPLAY.md).\n"
      "# EuRoC's columns: R = the tanker body frame (FRD: x forward, y right, z down), S = the receiver\n"
      "# body frame (FRD); p_RS_R the receiver's origin in R (m), q_RS its rotation (Hamilton, w first),\n"
      "# v_RS_R central differences of p_RS_R over the exported frames, biases 0: not estimated.\n"
      "# Timestamps: the left camera's (cam0) t_ns of each stereo frame, on the export's clock.\n"
      "sensor_type: groundtruth\ncomment: receiver pose relative to the tanker body frame\n");
}

// OUT/frames.csv (the frame index) and OUT/rig.yaml.
Status write_index_and_rig(const ExportContext& cx, const FrameTables& tables) {
  if (!tables.index.rows.empty()) {
    if (auto s = nav::write_frame_index_csv((cx.out / "frames.csv").string(), tables.index); !s)
      return make_error(strip_function(s.error().message));
    cx.report.frame_index_rows = tables.index.rows.size();
  }
  return write_text(cx.out / "rig.yaml", rig_to_yaml(cx.rig));
}

// OUT/poses.csv and mav0/state_groundtruth_estimate0 from the recorded poses.
Status write_poses(const ExportContext& cx, const FrameTables& tables, ClockDomain clock) {
  if (!tables.poses.empty()) {
    nav::CsvWriteOptions o;
    o.clock = clock;
    o.metadata["content"] = "T_cam_receiver as recorded (augrig export)";
    o.metadata["t_nav_ns"] = "not recorded: equals t_ns";
    if (auto s = nav::write_camera_pose_csv((cx.out / "poses.csv").string(), tables.poses, o); !s)
      return make_error(strip_function(s.error().message));
    cx.report.pose_rows = tables.poses.size();
  } else {
    cx.report.notes.push_back("no poses in the recording: poses.csv not written");
  }
  if (tables.receiver_states.empty()) {
    cx.report.notes.push_back(
        "no receiver poses in the recording: mav0/state_groundtruth_estimate0 not written");
    return {};
  }
  return write_receiver_states(cx.mav0 / "state_groundtruth_estimate0", tables.receiver_states);
}

// OUT/phases.csv: the flight's phases recorded beside the statistics ("phase: NAME" events), on
// the export's clock; t_s from the first statistics row. Returns them for the plot's markers.
Expected<std::vector<PhaseEvent>> write_phases(const ExportContext& cx, const ExportClock& clk,
                                               const std::vector<EventRecord>& events, TimestampNs t0_ns) {
  std::vector<PhaseEvent> phases = phase_events(events);
  for (PhaseEvent& ph : phases) ph.t_ns = clk.map(0, ph.t_ns);
  if (phases.empty()) return phases;
  std::ofstream pcsv(cx.out / "phases.csv", std::ios::binary);
  pcsv << "#t_ns,t_s,phase\n";
  for (const PhaseEvent& ph : phases) {
    char t_s[32];
    std::snprintf(t_s, sizeof t_s, "%.6f", ns_to_s(ph.t_ns - t0_ns));
    pcsv << ph.t_ns << ',' << t_s << ',' << ph.name << '\n';
  }
  pcsv.close();
  if (!pcsv) return make_error((cx.out / "phases.csv").string(), ": cannot write the file");
  cx.report.phases = phases.size();
  return phases;
}

// OUT/stats.csv, OUT/phases.csv and the plot OUT/stats.png (a plot that fails is a problem, not
// an error: the export's data are complete without it).
Status write_stats(const ExportContext& cx, const ExportClock& clk, const std::vector<OcclusionStats>& stats,
                   const std::vector<EventRecord>& events) {
  EurocExportReport& report = cx.report;
  if (stats.empty()) {
    report.notes.push_back("no occlusion statistics in the recording: stats.csv and stats.png not written");
    return {};
  }
  std::ofstream csv(cx.out / "stats.csv", std::ios::binary);
  write_stats_csv_header(csv);
  for (const OcclusionStats& s : stats) write_stats_csv_row(csv, s);
  csv.close();
  if (!csv) return make_error((cx.out / "stats.csv").string(), ": cannot write the file");
  report.stats_rows = stats.size();
  auto phases = write_phases(cx, clk, events, stats.front().t_ns);
  if (!phases) return phases.error();
  if (!cx.options.plot) return {};
  StatsPlotOptions po;
  po.title = "Occlusion statistics: " +
             (cx.reader ? fs::path(cx.reader->path()).parent_path().filename().string() : cx.from);
  po.phases = phase_markers(*phases, stats.front().t_ns, stats.back().t_ns);
  if (auto s = plot_occlusion_stats(stats, (cx.out / "stats.png").string(), po); !s)
    report.problems.push_back(strip_function(s.error().message));
  else
    report.plotted = true;
  return {};
}

}  // namespace

// ---- EurocWriter -----------------------------------------------------------------------------------

// The export's steps in the order their files and the report's notes come: the clock from every
// frame's metadata first (create), then the images (add), then the files made from what the frames
// gave (finish). Errors come back without the function's name; export_euroc() adds it.
struct EurocWriter::Impl {
  EurocExportOptions options;
  Rig rig;
  const RecordingReader* recording = nullptr;
  std::string from;
  fs::path out, mav0, marker;
  EurocExportReport* report = nullptr;
  std::optional<ExportContext> cx;  // refers to the members above
  std::optional<ExportProgress> progress;
  ExportClock clk;
  NavStreams nav;
  FrameTables tables;
  std::unique_ptr<FrameWriter> frames;  // made once the clock is known
  std::vector<TimestampNs> t_key_ns;    // a run's pair times, for the rate
  bool done = false;

  void choose_clock(const RecordingReader& r);
  void start_frames(ClockDomain own_clock);
  Status write_files(const std::vector<EventRecord>& events);
};

// The clock chosen over a recording's frames and its (or options.nav_from's) nav inputs.
void EurocWriter::Impl::choose_clock(const RecordingReader& r) {
  const FrameInfos infos = read_frame_infos(r, *report);
  if (const RecordingReader* n = cx->nav_reader()) read_nav_streams(*n, nav, *report);
  clk = choose_export_clock(r, infos, nav, *report);
  frames = std::make_unique<FrameWriter>(*cx, clk, *progress, tables);
}

// A run's pairs without a recording to choose a clock over: their own.
void EurocWriter::Impl::start_frames(ClockDomain own_clock) {
  clk.clock = own_clock;
  report->clock = own_clock;
  report->clock_note = "the frames' own clock (a run's pairs)";
  frames = std::make_unique<FrameWriter>(*cx, clk, *progress, tables);
}

Expected<std::unique_ptr<EurocWriter>> EurocWriter::create(const std::string& out_dir,
                                                           const EurocExportOptions& options, const Rig& rig,
                                                           const RecordingReader* recording,
                                                           const std::string& from,
                                                           EurocExportReport& report) {
  std::unique_ptr<EurocWriter> w(new EurocWriter);
  w->impl_ = std::make_unique<Impl>();
  Impl& m = *w->impl_;
  m.options = options;
  m.rig = rig;
  m.recording = recording;
  m.from = from;
  m.report = &report;
  m.out = out_dir;
  m.mav0 = m.out / "mav0";
  m.marker = m.out / "INCOMPLETE";
  std::error_code ec;
  if (fs::exists(m.mav0, ec))
    return make_error(m.mav0.string(), ": exists already; export into a new folder (exports never mix)");
  fs::create_directories(m.out, ec);
  if (ec) return make_error(m.out.string(), ": cannot create the folder (", ec.message(), ")");
  // OUT/INCOMPLETE before OUT/mav0 and anything in it: an export killed at any moment is marked.
  write_marker(m.marker, from, out_dir, {});
  if (!fs::exists(m.marker, ec)) return make_error(m.marker.string(), ": cannot write the file");
  fs::create_directories(m.mav0, ec);
  if (ec) return make_error(m.mav0.string(), ": cannot create the folder (", ec.message(), ")");
  m.cx.emplace(ExportContext{recording, from, m.out, m.mav0, m.options, m.rig, report});
  m.progress.emplace(m.options, recording ? recording->frame_count() : 0);
  if (recording) {
    // The recording's own damage (a truncated file: frames its summary counts but no row holds).
    for (const std::string& p : recording->problems())
      report.problems.push_back(p.rfind(recording->path(), 0) == 0 ? p : recording->path() + ": " + p);
    report.frames = recording->frame_count();
    m.choose_clock(*recording);
  } else if (m.options.nav_from) {
    m.choose_clock(*m.options.nav_from);  // the frames replayed from it keep its times
  }
  return w;
}

EurocWriter::~EurocWriter() = default;

unsigned EurocWriter::parts() const {
  const EurocExportOptions& o = impl_->options;
  unsigned p = kPartRaw;
  if (o.augmented) p |= kPartAugmented;
  if (o.masks) p |= kPartMasks;
  if (o.ground_truth) p |= kPartDepth | kPartMasks;  // the ground truth: the depth and the masks
  return p;
}

Status EurocWriter::add(std::size_t index, Expected<FrameRecord> frame) {
  Impl& m = *impl_;
  if (!m.recording) {
    ++m.report->frames;
    if (frame) m.t_key_ns.push_back(frame->raw.t_key_ns);
  }
  if (!m.frames) m.start_frames(frame ? frame->raw.left.clock : ClockDomain::kUnknown);
  return m.frames->add(index, std::move(frame));
}

Status EurocWriter::Impl::write_files(const std::vector<EventRecord>& events) {
  if (!frames) start_frames(ClockDomain::kUnknown);  // no frame came: the streams' files say so
  if (!recording && !options.nav_from) report->rate_hz = median_rate_hz(t_key_ns);
  if (auto s = frames->finish(); !s) return s;
  if (cx->nav_reader() && nav.rows) {
    if (auto s = write_imu0(*cx, nav, clk.clock); !s) return s;
    if (auto s = write_nav_logs(*cx, nav); !s) return s;
  }
  if (auto s = write_index_and_rig(*cx, tables); !s) return s;
  if (auto s = write_poses(*cx, tables, clk.clock); !s) return s;
  if (auto s = write_stats(*cx, clk, tables.stats, events); !s) return s;
  progress->update(*report, tables.skipped, true);
  return {};
}

Status EurocWriter::finish(const std::vector<EventRecord>& events) {
  Impl& m = *impl_;
  if (m.done) return {};
  m.done = true;
  if (Status s = m.write_files(events); !s) {
    fail(s.error());
    return s;
  }
  if (!m.report->problems.empty()) {
    write_marker(m.marker, m.from, m.out.string(), m.report->problems);
    return {};
  }
  std::error_code ec;
  fs::remove(m.marker, ec);
  if (ec) return make_error(m.marker.string(), ": cannot remove it (", ec.message(), ")");
  return {};
}

void EurocWriter::fail(const Error& e) {
  impl_->done = true;
  write_marker(impl_->marker, impl_->from, impl_->out.string(), {e.message});
}

// ---- export_euroc ----------------------------------------------------------------------------------

Status export_euroc(const RecordingReader& reader, const std::string& out_dir,
                    const EurocExportOptions& options, EurocExportReport& report) {
  const std::string where = "recorder::export_euroc(): ";
  report = {};
  Rig rig;
  if (options.rig) {
    rig = *options.rig;
  } else {
    const std::string yaml = reader.meta("rig_yaml");
    if (yaml.empty())
      return make_error(where, reader.path(),
                        ": the recording stores no rig (meta rig_yaml is empty); give one");
    auto r = parse_rig(yaml, reader.path() + " (meta rig_yaml)");
    if (!r) return make_error(where, strip_function(r.error().message));
    rig = std::move(*r);
  }
  if (rig.cameras.size() < 2)
    return make_error(where, rig.source, ": the rig needs 2 cameras, has ", rig.cameras.size());
  // Every frame needs its recorded depth: said before anything is written.
  if (options.ground_truth) {
    std::size_t missing = 0, first = 0;
    for (std::size_t i = 0; i < reader.frame_count(); ++i)
      if (!reader.has_depth(i) && missing++ == 0) first = i;
    if (missing) {
      const auto info = reader.read_frame_info(first);
      return make_error(where, no_depth_error(reader, first, info ? info->raw.pair_sequence : first,
                                              " (" + std::to_string(missing) + " of " +
                                                  std::to_string(reader.frame_count()) + " frames hold none)")
                                   .message);
    }
  }
  auto writer = EurocWriter::create(out_dir, options, rig, &reader, reader.path(), report);
  if (!writer) return make_error(where, writer.error().message);
  EurocWriter& w = **writer;
  for (std::size_t i = 0; i < reader.frame_count(); ++i)
    if (Status s = w.add(i, reader.read_frame(i, w.parts())); !s) {
      const Error e = make_error(where, s.error().message);
      w.fail(e);
      return e;
    }
  std::vector<EventRecord> events;
  if (auto ev = reader.events()) events = std::move(*ev);
  if (Status s = w.finish(events); !s) {
    const Error e = make_error(where, s.error().message);
    w.fail(e);  // the marker says it with the function's name
    return e;
  }
  return {};
}

}  // namespace augrig::recorder
