// Frame and StereoFrame: images with the timing facts needed to pair them and to look up the
// pose at mid-exposure, and FrameSource, the interface every image source implements
// (simulation, replay, Aravis GigE Vision, V4L2).
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "core/conventions.hpp"
#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig {

// Cameras of a stereo rig: index into the rig's camera list (0 = left, 1 = right).
enum class CameraId : std::uint8_t { kLeft = 0, kRight = 1 };
constexpr int index_of(CameraId id) {
  return static_cast<int>(id);
}
constexpr std::string_view to_string(CameraId id) {
  return id == CameraId::kLeft ? "left" : "right";
}

// What a file source knows about a frame beyond its pixels (a recording's poses and stored image
// bytes, a dataset's row): opaque here, read by whoever knows the type (dynamic_cast). Both Frames
// of a stereo frame share one; it is never changed after the source made it.
struct FrameAttachment {
  virtual ~FrameAttachment() = default;
};

struct Frame {
  Image image;
  TimestampNs t_ns = 0;  // mid-exposure, in `clock`
  ClockDomain clock = ClockDomain::kUnknown;
  TimestampNs t_host_ns = 0;   // CLOCK_MONOTONIC when the frame became available (0: unknown)
  std::uint64_t sequence = 0;  // per-camera frame counter from the source
  CameraId camera = CameraId::kLeft;
  std::int64_t exposure_ns = 0;  // 0: unknown
  std::shared_ptr<const FrameAttachment> attachment;  // null for cameras and simulations
};

struct StereoFrame {
  Frame left;
  Frame right;
  TimestampNs t_key_ns = 0;  // the pair's timestamp (mean of both mid-exposures)
  std::int64_t skew_ns = 0;  // right.t_ns - left.t_ns
  std::uint64_t pair_sequence = 0;

  Frame& operator[](CameraId id) { return id == CameraId::kLeft ? left : right; }
  const Frame& operator[](CameraId id) const { return id == CameraId::kLeft ? left : right; }
};

// How many items were counted, and the earliest and latest of their timestamps (each in its own
// frame's clock): the drop ledger's rows (count, first_t_ns, last_t_ns).
struct TimeSpan {
  std::uint64_t count = 0;
  TimestampNs first_t_ns = 0, last_t_ns = 0;
  void add(TimestampNs t_ns) {
    first_t_ns = count == 0 ? t_ns : std::min(first_t_ns, t_ns);
    last_t_ns = count == 0 ? t_ns : std::max(last_t_ns, t_ns);
    ++count;
  }
  void add(const TimeSpan& o) {
    if (o.count == 0) return;
    first_t_ns = count == 0 ? o.first_t_ns : std::min(first_t_ns, o.first_t_ns);
    last_t_ns = count == 0 ? o.last_t_ns : std::max(last_t_ns, o.last_t_ns);
    count += o.count;
  }
};

enum class ReadStatus : std::uint8_t {
  kFrame,        // `out` holds a new frame
  kTimeout,      // nothing arrived within the timeout; call again
  kEndOfStream,  // a finite source (replay, simulation) is exhausted
};

// What a live source knows about its device, for the display and the run's summary. Files and
// simulations are always connected.
struct SourceHealth {
  bool connected = true;
  std::string message;                // plain words: "left camera lost 0.6 s ago, reconnecting"
  std::uint64_t disconnects = 0;      // times the device was declared lost
  std::uint64_t reconnects = 0;       // times it came back
  std::uint64_t camera_drops = 0;     // frames the device skipped (frame-id gaps)
  std::uint64_t transport_drops = 0;  // frames lost on the way (incomplete blocks, error flags)
};

// A stream of frames from one or more cameras. Sources deliver each camera's frames in
// sequence order; pairing into StereoFrames happens downstream (capture/stereo_pairer.hpp).
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // A URI that names the source (sim://..., replay://..., aravis://..., v4l2://...).
  virtual std::string uri() const = 0;
  // Blocks up to `timeout` for the next frame of any camera.
  virtual Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) = 0;
  // What the device is set to now, every setting in effect (size, format, rate, exposure,
  // transport), in one line for the run's banner; empty for files and simulations.
  virtual std::string settings() const { return {}; }
  // Frames the source knows it lost (camera or transport), for the drop ledger.
  virtual std::uint64_t frames_dropped() const { return 0; }
  // Device state; sources without a device report connected and their frames_dropped().
  virtual SourceHealth health() const {
    SourceHealth h;
    h.camera_drops = frames_dropped();
    return h;
  }
};

}  // namespace augrig
