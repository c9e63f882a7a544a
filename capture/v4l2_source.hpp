// V4l2Source: frames from a Video4Linux2 capture device (USB UVC cameras, CSI bridges, vivid)
// through V4L2 streaming I/O: mmap'ed driver buffers, poll() and VIDIOC_DQBUF/QBUF, with no
// OpenCV VideoCapture and no libv4l2 in between. Formats: GREY -> Mono8, RGB24 -> RGB8, YUYV ->
// RGB8 (BT.601 limited range), MJPEG -> RGB8 (libturbojpeg), Bayer 8 -> the matching Bayer*8.
// Timestamps are the driver's; they are tagged ClockDomain::kHostMonotonic only when the buffer
// says V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC. Lost frames (sequence gaps, V4L2_BUF_FLAG_ERROR, corrupt
// JPEG) are counted in V4l2Stats, never silently skipped. A device that disappears mid-stream
// makes read() return an Error naming it. docs/V4L2.md has the details and how to test on vivid.
//
// list_v4l2_devices() is what `augrig cameras` shows for V4L2: every capture node with its driver,
// card (model), bus_info, pixel formats and frame sizes.
//
// All system calls go through V4l2Io (capture/v4l2_io.hpp) so tests can substitute a fake device.
// A V4l2Source is read from one thread.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "capture/v4l2_io.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"

struct v4l2_buffer;  // <linux/videodev2.h>

namespace augrig {

// "YUYV" <-> v4l2_fourcc('Y','U','Y','V'). Short names are padded with spaces ("Y16" = "Y16 ").
std::string fourcc_to_string(std::uint32_t fourcc);
Expected<std::uint32_t> fourcc_from_string(std::string_view text);

// The image format a V4L2 pixel format becomes in augrig; nullopt for fourccs augrig cannot read.
std::optional<PixelFormat> v4l2_to_pixel_format(std::uint32_t fourcc);
// The fourccs V4l2Source reads, best first: raw Bayer, RGB24, YUYV, GREY, MJPEG (lossy, last).
const std::vector<std::uint32_t>& default_v4l2_format_preference();

struct V4l2Options {
  std::string device_path = "/dev/video0";
  CameraId camera = CameraId::kLeft;
  // Fourccs in order of preference; the first the device lists (VIDIOC_ENUM_FMT) is used.
  // Empty: default_v4l2_format_preference().
  std::vector<std::uint32_t> pixel_formats;
  int width_px = 0;  // 0 (both): keep the device's current size; the driver may adjust either
  int height_px = 0;
  double frame_rate_hz = 0;  // 0: keep the device's current rate (VIDIOC_S_PARM otherwise)
  int buffer_count = 4;      // driver buffers to request (>= 2); the driver may grant another count
  // Manual exposure: auto exposure off (V4L2_CID_EXPOSURE_AUTO, when the device has it) and
  // V4L2_CID_EXPOSURE_ABSOLUTE, which counts 100 us units (the value is rounded to them).
  std::optional<std::int64_t> exposure_ns;
  // V4L2_CID_GAIN in the device's own units (V4L2_CID_AUTOGAIN is switched off when present).
  std::optional<std::int32_t> gain;
  // MJPEG frames that decode with a libjpeg warning (e.g. truncated data) are dropped unless this is
  // set; some cameras emit harmless warnings on every frame.
  bool keep_mjpeg_frames_with_warnings = false;
  // VIDIOC_STREAMON in open() instead of at the first read(). A device streams from STREAMON: if
  // nothing reads while the caller sets up (GL, augmenter, recorder), its buffers fill with stale
  // frames and the frames after them are lost (sequence gaps counted as camera drops), as the
  // Aravis cameras' were. So streaming starts when the frames are wanted.
  bool stream_at_open = false;
};

// What was negotiated with the driver.
struct V4l2StreamInfo {
  std::string driver;
  std::string card;
  std::string bus_info;
  std::uint32_t fourcc = 0;
  PixelFormat pixel_format = PixelFormat::kMono8;
  int width_px = 0;
  int height_px = 0;
  std::uint32_t bytes_per_line = 0;  // 0 for compressed formats
  std::uint32_t size_image = 0;      // bytes of one buffer's image (upper bound for MJPEG)
  unsigned buffer_count = 0;         // as granted by VIDIOC_REQBUFS
  double frame_rate_hz = 0;          // from VIDIOC_G_PARM/S_PARM; 0: the device does not say
  std::int64_t exposure_ns = 0;      // read back after setting; 0: not set (auto or unknown)
  std::optional<std::int32_t> gain;  // read back after setting
  // What the driver changed from the request (size, buffer count, frame rate, exposure rounding),
  // one sentence each, for the operator.
  std::vector<std::string> notes;
};

struct V4l2Stats {
  std::uint64_t frames_delivered = 0;
  std::uint64_t sequence_gap_frames = 0;       // sum of sequence numbers skipped by the driver
  std::uint64_t error_buffers = 0;             // V4L2_BUF_FLAG_ERROR: dropped
  std::uint64_t decode_failures = 0;           // corrupt MJPEG: dropped
  std::uint64_t short_buffers = 0;             // fewer bytes than the format needs: dropped
  std::uint64_t sequence_regressions = 0;      // a sequence number not after the previous one
  std::uint64_t non_monotonic_timestamps = 0;  // t_ns not after the previous frame's (same clock)
  std::uint64_t unknown_clock_frames = 0;      // timestamp not V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC
  std::uint64_t mjpeg_warnings_kept = 0;       // see V4l2Options::keep_mjpeg_frames_with_warnings
  std::string last_drop_reason;                // why the latest dropped frame was dropped
};

class V4l2Source final : public FrameSource {
 public:
  // Opens the device, negotiates format, size, rate and controls, maps the buffers and starts
  // streaming. Fails with an Error naming the device and what it lacks.
  static Expected<std::unique_ptr<V4l2Source>> open(const V4l2Options& options,
                                                    V4l2Io& io = system_v4l2_io());
  ~V4l2Source() override;  // STREAMOFF, munmap, REQBUFS 0, close
  V4l2Source(const V4l2Source&) = delete;
  V4l2Source& operator=(const V4l2Source&) = delete;

  std::string uri() const override { return "v4l2://" + options_.device_path; }
  std::string settings() const override;
  // The next good frame within `timeout` (kTimeout otherwise). Dropped buffers are re-queued and
  // counted while waiting. A disconnected or failed device gives an Error naming it, then again on
  // every later call.
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  // Every frame known lost: sequence gaps + error buffers + decode failures + short buffers.
  std::uint64_t frames_dropped() const override;
  // Disconnected once read() has failed (no reconnection: open a new source). Camera drops are the
  // sequence gaps; transport drops the error-flagged, short and undecodable buffers.
  SourceHealth health() const override;

  const V4l2Stats& stats() const { return stats_; }
  const V4l2StreamInfo& info() const { return info_; }

 private:
  struct Buffer {
    void* data = nullptr;
    std::size_t length = 0;
  };
  V4l2Source(const V4l2Options& options, V4l2Io& io);
  Status start();
  Status negotiate_format();
  Status set_frame_rate();
  Status set_controls();
  Status map_buffers_and_stream();  // REQBUFS, mmap, QBUF all; STREAMON when stream_at_open
  Status stream_on(const char* where);
  // Turns a dequeued buffer into `out`; false when the buffer was dropped (and counted).
  bool convert(const v4l2_buffer& buf, Frame& out);
  void drop(std::uint64_t& counter, std::string reason);
  Error device_error(const char* function, const std::string& what) const;

  V4l2Options options_;
  V4l2Io& io_;
  int fd_ = -1;
  std::vector<Buffer> buffers_;
  bool buffers_requested_ = false;
  bool streaming_ = false;
  void* jpeg_ = nullptr;  // tjhandle
  V4l2StreamInfo info_;
  V4l2Stats stats_;
  Image work_;  // the next frame's image; swapped with the caller's so both are reused
  std::optional<std::uint32_t> last_sequence_;
  std::uint64_t sequence_ = 0;  // unwrapped 64-bit sequence
  std::optional<TimestampNs> last_t_ns_;
  ClockDomain last_clock_ = ClockDomain::kUnknown;
  std::optional<Error> failed_;
};

// One V4L2 node as `augrig cameras` lists it.
struct V4l2FrameSize {
  // Discrete: min == max. Stepwise/continuous: the range and step.
  std::uint32_t min_width_px = 0, max_width_px = 0, step_width_px = 0;
  std::uint32_t min_height_px = 0, max_height_px = 0, step_height_px = 0;
  bool discrete() const { return min_width_px == max_width_px && min_height_px == max_height_px; }
};
struct V4l2FormatInfo {
  std::uint32_t fourcc = 0;
  std::string description;  // the driver's, e.g. "YUYV 4:2:2"
  bool compressed = false;
  bool supported = false;                  // augrig can read it (v4l2_to_pixel_format)
  std::vector<V4l2FrameSize> frame_sizes;  // empty when the driver does not enumerate them
};
struct V4l2DeviceInfo {
  std::string path;      // address: /dev/videoN
  std::string driver;    // e.g. "uvcvideo", "vivid"
  std::string card;      // model, e.g. "HD Pro Webcam C920"
  std::string bus_info;  // where it is plugged, e.g. "usb-0000:00:14.0-1"; V4L2 has no serial number
  std::uint32_t capabilities = 0;  // the node's device_caps
  std::vector<V4l2FormatInfo> formats;
  std::string error;  // non-empty when the node could not be queried (e.g. permission denied)
};

// Every node that can capture video with streaming I/O (metadata, output and radio nodes are left
// out). Nodes that cannot be opened are listed with `error` set. No devices: an empty list.
Expected<std::vector<V4l2DeviceInfo>> list_v4l2_devices(V4l2Io& io = system_v4l2_io());

}  // namespace augrig
