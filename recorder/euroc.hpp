// EuRoC / ASL dataset layout (docs/REPLAY.md), the writer: export of a recording into it.
// EurocSource (euroc_source.hpp) plays such a dataset (ours or anyone's) back.
//
//   OUT/mav0/cam0/data.csv            "#timestamp [ns],filename", one row per image
//   OUT/mav0/cam0/data/<t_ns>.png     the left camera's raw images (cam1: the right camera)
//   OUT/mav0/cam0/sensor.yaml         T_BS, rate_hz, resolution, pinhole intrinsics, distortion
//   OUT/mav0/cam0_augmented/...       the augmented images, same layout (cam1_augmented)
//   OUT/mav0/cam0_mask/...            the Mono8 masks (kMaskBoom | kMaskReceiver), same layout
//   OUT/mav0/cam0_depth/...           with ground_truth: the receiver depth (data/<t_ns>.npy), and
//                                     cam1_depth, cam{0,1}_depth_mm (.png), cam0_right_px (.npy),
//                                     cam0_stereo_class (.png); data.csv and sensor.yaml each
//   OUT/mav0/imu0/data.csv            "#timestamp [ns],w_RS_S_x [rad s^-1],...,a_RS_S_z [m s^-2]"
//   OUT/mav0/imu0/sensor.yaml         T_BS (identity: the IMU axes are the body axes), rate_hz
//   OUT/poses.csv                     the recorded T_cam_receiver per frame and camera
//                                     (nav/logs.hpp camera pose CSV)
//   OUT/stats.csv, OUT/stats.png      occlusion statistics (render/stats.hpp) and their plot
//   OUT/phases.csv                    the flight's phases recorded with them ("#t_ns,t_s,phase": when
//                                     each began; the plot marks them), when the recording has any
//   OUT/nav/<aircraft>/               per aircraft with GPS and IMU streams (tanker.gps, tanker.imu,
//                                     ...): gps.nmea (the sentences with "<arrival_ns> " prefixes),
//                                     imu.csv (nav/logs.hpp) and aircraft.yaml: what `augrig nav` fuses
//   OUT/frames.csv                    the frame index (nav/logs.hpp) on the export's clock, for
//                                     `augrig nav --frames`; OUT/rig.yaml the rig used
//   OUT/INCOMPLETE                    while the export runs, and after one that did not finish cleanly
//
// Frames: the body frame B of every T_BS is the tanker body frame (FRD, core/conventions.hpp);
// a camera's sensor frame S is its OpenCV frame, so T_BS is the rig's T_body_cam, written as a
// 4x4 row-major matrix. Pixel coordinates follow OpenCV's (and Kalibr's): the centre of the
// top-left pixel is (0, 0).
//
// Images: PNG, lossless. Mono8 and Bayer mosaics are 8-bit gray PNGs (a Bayer mosaic is written
// as it is, not debayered; sensor.yaml's `augrig: pixel_format` says which pattern, and
// EurocSource reads it back as that format), RGB8 a colour PNG, RGBA8 a colour PNG with alpha.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/frame.hpp"
#include "recorder/euroc_source.hpp"  // for now: its includers that read EuRoC datasets compile unchanged
#include "recorder/reader.hpp"
#include "render/rig.hpp"

namespace augrig::recorder {

// How far an export has come (EurocExportOptions::progress). frames_done = frames_written +
// frames_skipped; the last call has frames_done == frames_total and final set.
struct EurocExportProgress {
  std::size_t frames_done = 0, frames_total = 0;
  std::size_t frames_written = 0, frames_skipped = 0;  // skipped: damaged, not exported
  double elapsed_s = 0;
  double frames_per_s = 0;  // since the start
  double eta_s = 0;         // at that rate
  bool final = false;
};

struct EurocExportOptions {
  // The cameras' intrinsics and extrinsics; default: the rig stored in the recording (meta
  // "rig_yaml"). An error when neither is there.
  std::optional<Rig> rig;
  bool augmented = true;  // cam0_augmented, cam1_augmented (when the recording has them)
  bool masks = true;      // cam0_mask, cam1_mask (when the recording has them)
  // The ground truth (docs/GROUND_TRUTH.md) of every frame from its recorded receiver depth:
  // cam0_depth, cam1_depth (.npy), cam0_depth_mm, cam1_depth_mm (16-bit PNG), cam0_right_px (.npy)
  // and cam0_stereo_class (PNG), each with data.csv and sensor.yaml. A recording made without
  // --ground-truth holds no depth: then export_euroc() fails before writing anything, naming the
  // recording and the first such frame and how to store it (replay --record NEW --ground-truth).
  bool ground_truth = false;
  // The nav input stream exported as imu0; empty: "imu", else "tanker.imu", else the only stream
  // whose name ends in "imu". Its rows are recorder::imu_input() CSV rows or augrig IMU datagrams
  // (nav/imu_stream.hpp), as `augrig run --nav` records them.
  std::string imu_stream;
  // Per aircraft ("tanker", "receiver"): the aircraft.yaml text written into OUT/nav/<aircraft>/
  // (lever arm, IMU noise, time offsets; docs/NAV_FORMATS.md). Default: the recording's meta
  // "aircraft_yaml.<aircraft>"; without either, none is written (augrig nav then uses defaults).
  std::map<std::string, std::string> aircraft_yaml;
  // The recording whose nav inputs (imu0, OUT/nav/, the clock's GPS link) and aircraft.yaml are
  // exported; null: the one exported. export --reaugment re-augments into a new recording of the
  // same raw frames and exports it with the original's nav inputs.
  const RecordingReader* nav_from = nullptr;
  bool plot = true;  // OUT/stats.png through gnuplot (recorder/plot.hpp)
  // PNG: 0 stored (no compression, fastest, largest), 1 fast (Huffman coding of the Sub-filtered
  // rows; masks run-length coded), 2..9 zlib's levels. Every setting is lossless.
  int png_compression = 1;
  // Threads that encode and write the images; 0: one per core (at least 2); 1: all on the caller's.
  int threads = 0;
  // Called on the caller's thread every progress_interval_s at most, and once at the end.
  std::function<void(const EurocExportProgress&)> progress;
  double progress_interval_s = 1.0;
};

struct EurocExportReport {
  std::size_t frames = 0;          // in the recording
  std::size_t frames_written = 0;  // stereo frames exported (raw)
  std::size_t augmented_written = 0, masks_written = 0;
  std::size_t ground_truth_written = 0;       // stereo frames whose ground truth was written
  double rate_hz = 0;                         // the frames' median rate
  ClockDomain clock = ClockDomain::kUnknown;  // the clock of every exported timestamp
  std::string clock_note;                     // how the frames were put on it
  std::string imu_stream;                     // exported as imu0 ("" when none)
  std::size_t imu_samples = 0;
  std::vector<std::string> nav_logs;  // aircraft whose log folder OUT/nav/<aircraft> was written
  std::size_t frame_index_rows = 0;   // OUT/frames.csv
  std::size_t pose_rows = 0, stats_rows = 0;
  std::size_t phases = 0;  // OUT/phases.csv rows (the flight's recorded phases)
  bool plotted = false;
  std::vector<std::string> notes;     // what was left out and why (no augmented images, ...)
  std::vector<std::string> problems;  // damaged frames skipped, a plot that failed: output incomplete
};

// The EuRoC writer both EuRoC outputs share: export_euroc() (a recording's frames) and the euroc
// sink (a run's pairs, pipeline/sinks/euroc_sink.cpp). create() checks OUT (OUT/mav0 must not
// exist yet), writes OUT/INCOMPLETE and makes OUT/mav0; add() queues one stereo frame to the
// encoding threads; finish() writes what the frames gave (each stream's data.csv and sensor.yaml,
// poses.csv, stats.csv, phases.csv and the plot, frames.csv, rig.yaml, the receiver's states) and
// the nav inputs of options.nav_from, else of the recording exported (imu0, OUT/nav/), and removes
// OUT/INCOMPLETE when nothing went wrong (report.problems empty).
class EurocWriter {
 public:
  // `recording`: the recording exported: every timestamp goes on the clock chosen over all its
  // frames (below, export_euroc()). Null for a run's pairs: the frames' own clock, or, when
  // options.nav_from names the recording they were replayed from, the clock chosen over that
  // recording's frames. `from` names the input in messages, the marker and the plot's title.
  // `report` must outlive the writer.
  static Expected<std::unique_ptr<EurocWriter>> create(const std::string& out_dir,
                                                       const EurocExportOptions& options, const Rig& rig,
                                                       const RecordingReader* recording,
                                                       const std::string& from, EurocExportReport& report);
  ~EurocWriter();
  EurocWriter(const EurocWriter&) = delete;
  EurocWriter& operator=(const EurocWriter&) = delete;
  // The parts of a recorded frame it writes (RecordingReader::read_frame's `parts`).
  unsigned parts() const;
  // Stereo frame `index` (in its recording, or the run's count); an Error is a damaged frame,
  // listed in report.problems and skipped.
  Status add(std::size_t index, Expected<FrameRecord> frame);
  // `events`: the run's or recording's events (its "phase: NAME" events become phases.csv).
  Status finish(const std::vector<EventRecord>& events);
  // An error that stopped the export: OUT/INCOMPLETE says it.
  void fail(const Error& e);

 private:
  EurocWriter() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Joins EuRoC folders that the euroc sink wrote over consecutive ranges of one recording (a
// campaign's shards: `augrig replay REC --from-frame A --frames N --sink euroc:DIR,nav,no-plot`)
// into `out_dir`, the folder one export of the whole range gives (export REC OUT --reaugment with
// the same options): each stream's images hard-linked (copied where the file system cannot link;
// nothing is moved, the parts stay), its data.csv joined; poses.csv, stats.csv, frames.csv joined
// row by row under the header the parts share; what every part wrote alike (sensor.yaml, rig.yaml,
// imu0, nav/) taken once, an error where it differs; the receiver's velocities made again over the
// whole, phases.csv each phase once with its seconds from the whole's first statistics row, and
// the plot. Parts that overlap (an image in two, timestamps not increasing) are an error; a part
// left INCOMPLETE is a problem (report.problems; OUT/INCOMPLETE lists them) and its frames are kept.
struct EurocMergeOptions {
  bool plot = true;   // OUT/stats.png
  std::string title;  // the plot's "Occlusion statistics: TITLE" (the recording's name)
};
struct EurocMergeReport {
  std::size_t frames = 0;  // cam0's rows
  std::size_t images = 0;  // files linked (or copied) from the parts
  bool plotted = false;
  std::vector<std::string> problems;
};
Status merge_euroc(const std::vector<std::string>& inputs, const std::string& out_dir,
                   const EurocMergeOptions& options, EurocMergeReport& report);

// Writes the layout above into `out_dir` (created; an existing OUT/mav0 is an error, so two
// exports never mix). Damaged frames are skipped and listed in report.problems (so is the
// recording's own damage, RecordingReader::problems()); an error is returned only when the export
// cannot go on (no rig, a file that cannot be written).
//
// OUT/INCOMPLETE exists from before OUT/mav0 is made until the export has finished with no
// problem; an export that failed, met problems or was killed leaves it, listing the problems (or
// saying it was stopped before the end).
//
// Clock: every exported timestamp (image names and data.csv, imu0, poses.csv, stats.csv,
// frames.csv) is on one clock, report.clock: GPS time when the frames can be put on it (frames
// already in GPS time; the camera offsets to GPS the recording's clock_domains meta states; or
// each camera's device clock -> host CLOCK_MONOTONIC (t_host_ns, or the recording's clock_offset
// events) -> GPS time through the nav inputs' arrival against their own sensor time); else the
// frames' recorded clock, with a note.
Status export_euroc(const RecordingReader& reader, const std::string& out_dir,
                    const EurocExportOptions& options, EurocExportReport& report);

// sensor.yaml text of one camera stream; `stream` is "raw", "augmented" or "mask".
std::string euroc_camera_yaml(const RigCamera& camera, const std::string& side, const std::string& stream,
                              double rate_hz, PixelFormat format, ClockDomain clock);

}  // namespace augrig::recorder
