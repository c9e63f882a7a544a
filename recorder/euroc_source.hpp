// EuRoC / ASL dataset layout (docs/REPLAY.md), the reader: EurocSource, a FrameSource that plays
// such a dataset (ours, written by export_euroc() in euroc.hpp, which lists the whole layout, or
// anyone's) back, and the readers of its CSV files. What it reads:
//
//   DIR/mav0/cam0/data.csv            "#timestamp [ns],filename", one row per image (cam1: the right
//                                     camera; other folders, cam0_augmented, ..., by EurocOptions)
//   DIR/mav0/cam0/data/<file>         the images: 8-bit PNGs (gray, colour, colour with alpha)
//   DIR/mav0/cam0/sensor.yaml         optional; only its `augrig:` keys (pixel_format, clock)
//   DIR/mav0/imu0/data.csv            optional: "#timestamp [ns],w_RS_S_x [rad s^-1],...,a_RS_S_z [m s^-2]"
//
// Images: an 8-bit gray PNG is read as EurocOptions::gray_format, else as sensor.yaml's `augrig:
// pixel_format` (the export writes a Bayer mosaic as it is, not debayered, and names its pattern
// there), else as Mono8; a colour PNG is RGB8, a colour PNG with alpha RGBA8.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/frame.hpp"
#include "nav/types.hpp"

namespace augrig::recorder {

struct EurocCsvRow {
  TimestampNs t_ns = 0;
  std::string file;  // relative to the stream's data/ folder
};
// A camera's data.csv ("#timestamp [ns],filename"); errors name file:line.
Expected<std::vector<EurocCsvRow>> read_euroc_camera_csv(const std::string& path);

// One row of imu0/data.csv: angular rate (rad/s) and specific force (m/s^2) in the IMU frame.
struct EurocImuRow {
  TimestampNs t_ns = 0;
  Eigen::Vector3d w_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_mps2 = Eigen::Vector3d::Zero();
};
Expected<std::vector<EurocImuRow>> read_euroc_imu_csv(const std::string& path);
// Rates -> the increments nav/ consumes: sample k covers (t[k-1], t[k]] with the trapezoid of the
// two rates (the first row starts the first interval and yields no sample).
std::vector<nav::ImuSample> imu_increments(const std::vector<EurocImuRow>& rows);

struct EurocOptions {
  std::string left_stream = "cam0";  // folder names under mav0/ ("cam0_augmented", ...)
  std::string right_stream = "cam1";
  // Largest |t_right - t_left| that pairs; 0: identical timestamps only (EuRoC's convention).
  std::int64_t pair_tolerance_ns = 0;
  // What an 8-bit gray PNG is; default: the stream's sensor.yaml `augrig: pixel_format`, else Mono8.
  std::optional<PixelFormat> gray_format;
  // The frames' clock; default: sensor.yaml's `augrig: clock`, else kUnknown.
  std::optional<ClockDomain> clock;
  // Where playback begins: pair `start_pair`, or, when set, the first pair at least
  // `start_offset_ns` after the first pair's left timestamp. A start past the last pair is an Error.
  std::size_t start_pair = 0;
  std::optional<std::int64_t> start_offset_ns;
};

// Plays a EuRoC/ASL dataset: every stereo pair (left then right Frame) in timestamp order, as
// fast as read() is called. Frames without a partner are not emitted; they are counted in
// unpaired() and frames_dropped(). sequence is the pair's index (both Frames of a pair share
// it). An image that cannot be read makes read() return an Error naming the file; that pair is
// skipped (two Frames in frames_dropped()) and the next read() goes on. sensor.yaml is read
// only for the optional `augrig:` keys; a missing or unreadable one is ignored.
class EurocSource final : public FrameSource {
 public:
  // `uri_or_dir`: "euroc://DIR", DIR holding mav0/, or the mav0 folder itself.
  static Expected<std::unique_ptr<EurocSource>> open(const std::string& uri_or_dir,
                                                     const EurocOptions& options = {});
  std::string uri() const override { return uri_; }
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  std::uint64_t frames_dropped() const override { return unpaired_ + 2 * unreadable_; }

  SourceCapabilities capabilities() const override { return {.finite = true, .ranged = true}; }
  std::size_t pair_count() const override { return pairs_.size(); }  // from the start to the end
  std::size_t range_start() const override { return start_pair(); }
  std::optional<TimestampNs> origin_t_ns() const override { return first_t_ns(); }
  Status set_range_end(std::size_t end) override { return set_end_pair(end); }
  // The dataset's pair index of the first pair played (EurocOptions' start): the pair with
  // sequence k is the dataset's pair start_pair() + k.
  std::size_t start_pair() const { return start_; }
  // The dataset's time origin: its first pair's left timestamp, whatever the start (nullopt: no
  // pair). A scripted boom's t = 0 (pipeline/boom_stage.hpp).
  std::optional<TimestampNs> first_t_ns() const { return first_t_ns_; }
  // Playback ends before the dataset's pair `end` (clamped to the last), so that a part of the
  // dataset (pairs [start, end)) plays exactly those pairs. Before the first read(). An Error when
  // `end` is not after the start.
  Status set_end_pair(std::size_t end);
  std::uint64_t unpaired() const { return unpaired_; }
  const std::string& mav0() const { return mav0_; }
  // imu0/data.csv as in the file (empty when the dataset has none), and as increments.
  const std::vector<EurocImuRow>& imu() const { return imu_; }
  std::vector<nav::ImuSample> imu_samples() const { return imu_increments(imu_); }

 private:
  EurocSource() = default;
  struct Pair {
    EurocCsvRow left, right;
  };
  std::string uri_, mav0_;
  EurocOptions options_;
  PixelFormat gray_[2] = {PixelFormat::kMono8, PixelFormat::kMono8};
  ClockDomain clock_[2] = {ClockDomain::kUnknown, ClockDomain::kUnknown};
  std::vector<Pair> pairs_;  // from the start on
  std::size_t start_ = 0;
  std::optional<TimestampNs> first_t_ns_;
  std::vector<EurocImuRow> imu_;
  std::size_t next_ = 0;
  bool right_pending_ = false;
  Frame right_;
  std::uint64_t unpaired_ = 0;
  std::uint64_t unreadable_ = 0;
};

}  // namespace augrig::recorder
