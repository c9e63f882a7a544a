// Frame and StereoFrame: images with the timing facts needed to pair them and to look up the
// pose at mid-exposure, and FrameSource, the interface every image source implements
// (simulation, replay, Aravis GigE Vision, V4L2).
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
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

namespace recorder {
struct RecordedFrame;
}

// Where a frame lies in a file source: its index there (a recording's frame, a dataset's pair)
// and the loop pass (0: the first).
struct SourcePosition {
  std::size_t index = 0;
  int pass = 0;
};

// A recorded pair's own pairing (a replay keeps the key, skew and sequence it was recorded with).
struct RecordedPairing {
  TimestampNs t_key_ns = 0;
  std::int64_t skew_ns = 0;
  std::uint64_t pair_sequence = 0;
};

// What a file source knows about a frame beyond its pixels, asked through these accessors (never
// by the attachment's type). Both Frames of a stereo frame share one; it is never changed after
// the source made it.
struct FrameAttachment {
  virtual ~FrameAttachment() = default;
  // Where the frame lies in its file (none: the source has no such index).
  virtual std::optional<SourcePosition> position() const { return std::nullopt; }
  // The file its image was read from (an image folder's); empty: none.
  virtual std::string file_path() const { return {}; }
  // A paced replay: CLOCK_MONOTONIC when the frame was due (0: not paced, or not a replay).
  virtual TimestampNs due_host_ns() const { return 0; }
  // A replayed pair's recorded pairing (none: pair it anew).
  virtual std::optional<RecordedPairing> recorded_pairing() const { return std::nullopt; }
  // A recording's frame (recorder/replay_source.hpp): everything recorded with it; null otherwise.
  virtual const recorder::RecordedFrame* recorded() const { return nullptr; }
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

// What a source can do beyond read(), asked instead of its type.
struct SourceCapabilities {
  bool finite = false;    // it ends (a file, a dataset, a simulation): pair_count() is its length
  bool seekable = false;  // a frame can be sought and stepped to (a recording)
  bool paced = false;     // it can play at its recorded rate, or as fast as possible
  bool ranged = false;    // it plays a range of its file: range_start(), origin_t_ns(), set_range_end()
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

  // ---- Capabilities (the defaults: a live source that says nothing more) ----
  virtual SourceCapabilities capabilities() const { return {}; }
  // Finite: the stereo pairs it delivers from its start to its end, and the images (both
  // cameras' Frames, paired or not) it delivers (0: not known before reading).
  virtual std::size_t pair_count() const { return 0; }
  virtual std::size_t image_count() const { return 0; }
  // Ranged: the index in its file of the first pair it plays (a pair's position() is this plus its
  // sequence), and the time origin of the whole file, whatever the start (a scripted boom's t = 0).
  virtual std::size_t range_start() const { return 0; }
  virtual std::optional<TimestampNs> origin_t_ns() const { return std::nullopt; }
  // Ranged: plays only up to, not including, the file's pair `end` (clamped to its last); before
  // the first read(). An Error for a source without a range.
  virtual Status set_range_end(std::size_t /*end*/) { return make_error(uri(), ": plays no range of a file"); }
  // What its file stores about itself (an MCAP file's augrig_recording metadata: rig_yaml, ...).
  virtual std::map<std::string, std::string> metadata() const { return {}; }
};

}  // namespace augrig
