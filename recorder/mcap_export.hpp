// MCAP for ROS 2 and Foxglove (docs/MCAP.md), the writer: export_mcap() writes a recording as one
// MCAP file of ROS 2 messages in CDR through McapFrameWriter (which the mcap sink shares), and
// merge_mcap() joins the files of a flight's shards. McapSource (mcap_source.hpp) plays such a
// file back.
//
//   /augrig/frame                 augrig_msgs/msg/StereoFrameInfo    per stereo frame, first: pairing, boom, presence, sigma
//   /left/image_raw               sensor_msgs/msg/Image              the raw image (bayer_rggb8, mono8, rgb8, ...)
//   /left/camera_info             sensor_msgs/msg/CameraInfo         intrinsics, plumb_bob / equidistant
//   /left/image_augmented         sensor_msgs/msg/Image              the augmented image (same encoding)
//   /left/image_raw/compressed,   sensor_msgs/msg/CompressedImage    with images = jpeg, instead of the two
//   /left/image_augmented/compressed                                   above: JPEG (a Bayer mosaic demosaiced)
//   /left/image_raw/h264,         foxglove_msgs/msg/CompressedVideo  with images = h264, instead: H.264, each
//   /left/image_augmented/h264                                         frame one unit, an IDR every h264_gop_frames
//   /left/mask                    sensor_msgs/msg/Image              mono8: 1 boom, 2 receiver, 3 both
//   /left/receiver_pose           geometry_msgs/msg/PoseWithCovarianceStamped   T_cam_receiver (frame left_camera)
//   /right/...                    the same for the right camera
//   /tf_static                    tf2_msgs/msg/TFMessage             tanker_body -> left_camera, right_camera (once)
//   /tf                           tf2_msgs/msg/TFMessage             tanker_body -> receiver_body per frame
//   /augrig/occlusion_stats       augrig_msgs/msg/OcclusionStats     the statistics per frame
//   /nav/<stream>/imu, /fix       sensor_msgs/msg/Imu, NavSatFix     the recorded nav inputs, when there are any
//
// Every message's log_time and header stamp is its recorded timestamp as it is (the frames' clock;
// the nav inputs their sensors' time of validity), so the round trip is exact.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/frame.hpp"
#include "recorder/mcap_names.hpp"
#include "recorder/mcap_source.hpp"  // for now: its includers that read MCAP files compile unchanged
#include "recorder/reader.hpp"
#include "render/rig.hpp"
#include "render/video_codec.hpp"

namespace augrig::recorder {

struct McapExportOptions {
  std::optional<Rig> rig;  // default: the recording's (meta rig_yaml); without one, no camera_info nor /tf_static
  bool augmented = true;   // /<camera>/image_augmented
  bool masks = true;       // /<camera>/mask
  bool nav = true;         // /nav/<stream>/imu and /fix from the recorded nav inputs
  // The raw and augmented images as JPEG (sensor_msgs/msg/CompressedImage on .../compressed), at
  // jpeg_quality: a file a tenth of the size, lossy (the masks stay lossless). A replay decodes them.
  bool jpeg = false;
  int jpeg_quality = 90;
  // Or as H.264 (foxglove_msgs/msg/CompressedVideo on .../h264; render/video_codec.hpp): a stream per
  // topic, an IDR keyframe every h264_gop_frames frames, x264's quality h264_crf. Smaller still; a
  // replay decodes them from the file's start (a stream cannot be entered between keyframes).
  bool h264 = false;
  int h264_gop_frames = 30;
  int h264_crf = 23;
  std::size_t chunk_size_bytes = 4u << 20;
  int zstd_level = 3;
  std::function<void(std::size_t done, std::size_t total)> progress;  // after each frame
};

struct McapExportReport {
  std::size_t frames = 0, frames_written = 0;
  std::uint64_t messages = 0, chunks = 0, bytes = 0;
  std::map<std::string, std::uint64_t> messages_by_topic;
  std::vector<std::string> notes;     // what was left out and why
  std::vector<std::string> problems;  // damaged frames or nav inputs skipped
};

// One stereo frame as an MCAP file takes it, by view (nothing is copied): a recording's frame
// (mcap_frame_of) or a run's pair (the mcap sink, pipeline/sinks/mcap_sink.cpp).
struct McapFrame {
  const StereoFrame* raw = nullptr;
  std::array<ConstImageView, 2> augmented{}, mask{};  // whole images; an empty view is not written
  std::array<std::optional<Pose>, 2> T_cam_receiver;
  std::optional<Pose> T_body_receiver;
  std::optional<bool> receiver_present;
  double sigma_pos_m = FrameRecord::kNaN, sigma_att_deg = FrameRecord::kNaN;
  std::optional<BoomArticulation> boom;
  const OcclusionStats* stats = nullptr;
};
McapFrame mcap_frame_of(const FrameRecord& f);

// The MCAP writer every MCAP output shares (export_mcap(), the mcap sink): the file is written as
// out_path + ".part" and renamed by finish(), so that a failed export leaves no file that looks
// finished. The meta table goes first (what a replay needs, the rig, before any frame); then each
// stereo frame's messages (the file's header); then, from a recording, its nav inputs.
class McapFrameWriter {
 public:
  // `rig`: for camera_info and /tf_static (none: neither is written). `report` collects the counts
  // and must outlive the writer.
  static Expected<std::unique_ptr<McapFrameWriter>> create(const std::string& out_path,
                                                           const McapExportOptions& options,
                                                           const std::map<std::string, std::string>& meta,
                                                           std::optional<Rig> rig, McapExportReport& report);
  ~McapFrameWriter();
  // One stereo frame; `index` is its index in its stream (/augrig/frame), `where` names it in errors.
  Status write(const McapFrame& f, std::uint64_t index, const std::string& where);
  // One message as it is, on `topic` of ROS 2 type `type` (merge_mcap()).
  Status write_message(const std::string& topic, const std::string& type, std::int64_t log_time_ns,
                       const std::vector<std::uint8_t>& data);
  // The recording's nav inputs: each IMU increment as mean rates at the middle of its interval,
  // each GPS epoch as a NavSatFix (streams neither IMU nor GPS are noted and left out).
  Status write_nav(const RecordingReader& reader);
  // Closes the file and renames it to out_path; the report's message, chunk and byte counts.
  Status finish();

 private:
  McapFrameWriter() = default;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Writes `out_path` (through out_path + ".part", renamed at the end: a failed export leaves no
// file that looks finished). An Error when the export cannot go on; damaged frames are skipped
// and listed in report.problems.
Status export_mcap(const RecordingReader& reader, const std::string& out_path, const McapExportOptions& options,
                   McapExportReport& report);

// Joins MCAP files written by export_mcap() or the mcap sink for consecutive parts of one flight
// (a campaign's shards) into one: the first file's metadata, then every file's messages in order
// (channels and schemas by topic and type, as written), then, given `nav_from`, that recording's
// nav inputs. A shard's frames keep their recording's indices, so the result is, message for
// message, the file of the whole flight. Written through out_path + ".part"; `report` counts.
Status merge_mcap(const std::vector<std::string>& inputs, const std::string& out_path,
                  const RecordingReader* nav_from, McapExportReport& report);

}  // namespace augrig::recorder
