// MCAP for ROS 2 and Foxglove (docs/MCAP.md), the reader: McapSource plays an MCAP file written by
// export_mcap() or the mcap sink (mcap_export.hpp, which lists the file's topics) back as a
// FrameSource (replay://OUT.mcap, `augrig replay OUT.mcap`): the raw images (/<camera>/image_raw,
// or as an export with compressed images wrote them: .../compressed in JPEG, .../h264 in H.264)
// with the recorded scene (/augrig/frame, /<camera>/receiver_pose, /tf, /augrig/occlusion_stats).
// The augmented images, masks, camera_info and nav inputs are not read back.
//
// Every message's log_time and header stamp is its recorded timestamp as it is (the frames' clock;
// the nav inputs their sensors' time of validity), so the round trip is exact.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/frame.hpp"
#include "recorder/mcap_names.hpp"
#include "recorder/mcap_reader.hpp"
#include "recorder/replay_source.hpp"
#include "render/video_codec.hpp"
#include "ros2/messages.hpp"

namespace augrig::recorder {

// Plays an MCAP file written by export_mcap(): per stereo frame its left, then its right raw Frame,
// as fast as read() is called, each carrying a RecordedFrame (replay_source.hpp) with the recorded
// scene: poses (/<camera>/receiver_pose, /tf), boom, receiver presence, sigma and statistics. A
// frame whose messages cannot be decoded is an Error naming the file and the frame, and is
// skipped; damage to the file itself (a chunk's CRC, a record past the end) ends the stream with an
// Error naming the file and the offset.
class McapSource final : public FrameSource {
 public:
  // `uri_or_path`: "replay://OUT.mcap" or the path.
  static Expected<std::unique_ptr<McapSource>> open(const std::string& uri_or_path);
  std::string uri() const override { return "replay://" + reader_->path(); }
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  std::uint64_t frames_dropped() const override { return 2 * damaged_; }
  SourceCapabilities capabilities() const override { return {.finite = true}; }
  std::size_t pair_count() const override { return frame_count_; }
  std::map<std::string, std::string> metadata() const override { return meta_; }

  const std::string& path() const { return reader_->path(); }
  // The recording's meta table as exported (rig_yaml, ...); empty when the file has none.
  const std::map<std::string, std::string>& meta() const { return meta_; }
  // Stereo frames in the file (the statistics' count of /augrig/frame).
  std::size_t frame_count() const { return frame_count_; }
  std::uint64_t damaged_frames() const { return damaged_; }

 private:
  McapSource() = default;
  // The next stereo frame's messages, up to the next /augrig/frame; false at the end.
  Expected<bool> next_frame(std::map<std::string, std::vector<std::uint8_t>>& messages);

  std::unique_ptr<McapReader> reader_;
  std::map<std::string, std::string> meta_;
  std::size_t frame_count_ = 0;
  std::uint64_t damaged_ = 0;
  bool have_pending_ = false, ended_ = false;
  McapMessage pending_;  // the /augrig/frame that starts the next stereo frame
  // An H.264 file's raw image streams, one decoder per camera (made at its first unit).
  std::array<std::unique_ptr<H264Decoder>, 2> decoders_;
  Expected<Image> decode_video(int c, const std::vector<std::uint8_t>& msg, const ros2::CameraFrameInfo& ci);
  bool right_pending_ = false;
  Frame right_;
};

// Whether `path` names an MCAP file (ends in .mcap, or starts with the MCAP magic).
bool is_mcap_path(const std::string& path);

}  // namespace augrig::recorder
