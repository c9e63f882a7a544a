// The EuRoC export's parts (recorder/euroc.hpp's export_euroc), internal to recorder/: what the
// steps of one export share. euroc.cpp runs the steps in order; each of the files below does one:
//   euroc_clock.cpp        the export's clock: every frame time -> GPS time where it can
//   euroc_frames.cpp       the frames: camera images and ground truth, encoded on worker threads,
//                          each stream's data.csv and sensor.yaml; the tables the later files need
//   euroc_nav_export.cpp   imu0 and the per-aircraft nav log folders from the nav inputs
//   euroc.cpp              the order of the steps, poses.csv, stats.csv, the receiver states
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "nav/logs.hpp"
#include "recorder/euroc.hpp"
#include "recorder/reader.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder::euroc_detail {

namespace fs = std::filesystem;

constexpr const char* kCameraCsvHeader = "#timestamp [ns],filename";

// The shortest text that reads back exactly.
std::string num(double v);
// "module::function(): rest" -> "rest".
std::string strip_function(const std::string& message);
Status write_text(const fs::path& path, const std::string& text);
// A 4x4 transform as "[a, b, ...]", row-major, the rotation's near-exact 0 and +-1 written exact.
std::string matrix_row_major(const Eigen::Matrix4d& T);
// Median interval of increasing times -> Hz (0 when fewer than two), to 1 mHz.
double median_rate_hz(std::vector<TimestampNs> t);
// The velocity at row i of positions over time: central differences (one-sided at the ends), 0
// where the two times are equal (the receiver's v_RS_R, of an export and of a join of exports).
Eigen::Vector3d central_difference_mps(const std::vector<TimestampNs>& t_ns,
                                       const std::vector<Eigen::Vector3d>& p_m, std::size_t i);
bool is_nmea_line(const std::string& s);
// export --ground-truth of a frame recorded without its depth: which, and how to get it.
Error no_depth_error(const RecordingReader& reader, std::size_t i, std::uint64_t pair_sequence,
                     const std::string& how_many = "");

// What every step of one export reads and adds to.
struct ExportContext {
  const RecordingReader* reader;  // the recording exported; null: a run's pairs (the euroc sink)
  std::string from;               // what the frames come from, in messages (the recording's path)
  fs::path out, mav0;
  const EurocExportOptions& options;
  const Rig& rig;
  EurocExportReport& report;
  // The recording whose nav inputs and aircraft settings are exported (options.nav_from, else the
  // recording exported); null: none.
  const RecordingReader* nav_reader() const { return options.nav_from ? options.nav_from : reader; }
};

// ---- The clock (euroc_clock.cpp) ------------------------------------------------------------------

// The lower envelope of d(x) (d = a later clock minus an earlier one, both stamping the same
// events with delays >= 0): the minimum of each 10 s window of x, linear between the windows'
// middles, constant beyond. The minimum takes the least-delayed event; windows follow a drift.
class LowerEnvelope {
 public:
  void add(TimestampNs x, TimestampNs d) { points_.emplace_back(x, d); }
  bool empty() const { return points_.empty(); }
  std::size_t size() const { return points_.size(); }
  void finish();
  TimestampNs at(TimestampNs x) const;

 private:
  std::vector<std::pair<TimestampNs, TimestampNs>> points_, knots_;
};

// Each camera's frame time (its recorded clock, with its host arrival) -> the export's clock.
struct ExportClock {
  ClockDomain clock = ClockDomain::kUnknown;
  std::string note;
  enum class Mode { kIdentity, kConstant, kThroughHost } mode = Mode::kIdentity;
  TimestampNs constant_ns[2] = {0, 0};  // kConstant: t - constant
  LowerEnvelope device_to_host[2];      // host - device, per camera (kThroughHost)
  bool frames_on_host = false;
  LowerEnvelope host_to_gps;  // host arrival - GPS time (kThroughHost)

  TimestampNs map(int camera, TimestampNs t_ns) const;
};

// Every frame's metadata (no image), read once before the images: the rate, the clocks.
struct FrameInfos {
  std::vector<std::optional<FrameRecord>> frames;  // nullopt: unreadable
  bool all_gps = false, all_device = false, all_host = false;
};
FrameInfos read_frame_infos(const RecordingReader& reader, EurocExportReport& report);

// The recording's nav inputs by stream (pointers into `rows`: not copied, not moved).
struct NavStreams {
  NavStreams() = default;
  NavStreams(const NavStreams&) = delete;
  NavStreams& operator=(const NavStreams&) = delete;
  Expected<std::vector<NavInputRecord>> rows = std::vector<NavInputRecord>{};
  std::map<std::string, std::vector<const NavInputRecord*>> by_stream;
};
void read_nav_streams(const RecordingReader& reader, NavStreams& nav, EurocExportReport& report);

// GPS time when the frames can be put on it (docs/REPLAY.md), else the frames' recorded clock;
// report.clock and clock_note say which.
ExportClock choose_export_clock(const RecordingReader& reader, const FrameInfos& infos, const NavStreams& nav,
                                EurocExportReport& report);

// ---- The frames (euroc_frames.cpp) ----------------------------------------------------------------

// What the frames give the files written after them (poses.csv, frames.csv, stats.csv, ...).
struct FrameTables {
  std::vector<nav::CameraPoseRow> poses;
  // The receiver in the tanker body frame per stereo frame (at the left camera's time) for
  // mav0/state_groundtruth_estimate0.
  std::vector<std::pair<TimestampNs, Pose>> receiver_states;
  std::vector<OcclusionStats> stats;
  nav::FrameIndex index;
  std::size_t skipped = 0;  // frames not exported (damaged)
};

// EurocExportOptions::progress, called at most every progress_interval_s, and once at the end.
class ExportProgress {
 public:
  ExportProgress(const EurocExportOptions& options, std::size_t frames_total);
  void update(const EurocExportReport& report, std::size_t skipped, bool final);

 private:
  const EurocExportOptions& options_;
  std::size_t total_;
  std::chrono::steady_clock::time_point start_, last_;
};

// Every frame's images (and ground truth) into mav0/cam*/, encoded on worker threads while the
// caller reads the next frame; each stream's data.csv and sensor.yaml at the end.
class FrameWriter {
 public:
  FrameWriter(const ExportContext& cx, const ExportClock& clk, ExportProgress& progress, FrameTables& tables);
  ~FrameWriter();
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;
  // The parts of a recorded frame it writes (RecordingReader::read_frame's `parts`).
  unsigned parts() const;
  // Frame `i` (its index in its stream): queued; an unreadable one (an Error) is listed in the
  // report's problems and skipped.
  Status add(std::size_t i, Expected<FrameRecord> frame);
  // Waits for every image, then writes each stream's data.csv and sensor.yaml.
  Status finish();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

// ---- Nav (euroc_nav_export.cpp) -------------------------------------------------------------------

// mav0/imu0 from the recording's IMU stream (EurocExportOptions::imu_stream).
Status write_imu0(const ExportContext& cx, const NavStreams& nav, ClockDomain frames_clock);
// OUT/nav/<aircraft>/ for each aircraft with both a GPS and an IMU stream.
Status write_nav_logs(const ExportContext& cx, const NavStreams& nav);

}  // namespace augrig::recorder::euroc_detail
