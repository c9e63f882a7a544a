// AravisSource: one GigE Vision (or USB3 Vision) camera through Aravis 0.8, as a FrameSource.
//
// Opens a camera by Aravis id, serial number or IPv4 address (by address on loopback: Aravis'
// default device picks the wrong interface there), configures pixel format, region, exposure, gain,
// frame rate, trigger and PTP, negotiates the GVSP packet size and sizes the socket buffer, then
// streams into a pool of buffers: a free-running camera from the first read() (so that nothing
// piles up while the rest of the pipeline sets up), a triggered one from open(). Each Frame carries the
// device timestamp (ClockDomain::kDevice, moved to mid-exposure) and the host CLOCK_MONOTONIC time it became
// available.
//
// Nothing is lost silently, and nothing twice: incomplete or failed buffers count as transport
// drops, frame-id gaps they do not explain as camera drops, and Aravis' stream statistics (missing
// packets, resends, underruns) are kept.
// A camera that stops delivering (or whose control channel is lost) is reported within
// `lost_after`; the source then tears down and reconnects whenever the camera answers again, while
// read() keeps returning kTimeout, so a stereo partner in another thread goes on meanwhile.
//
// >8-bit formats (Mono10/12/16, Bayer*10/12/16, unpacked) are delivered as 8-bit images holding the
// most significant 8 bits; the pipeline is 8-bit (docs/CAPTURE.md).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/expected.hpp"
#include "core/frame.hpp"

namespace augrig {

enum class TriggerMode : std::uint8_t {
  kFreeRun,   // the camera runs at its frame rate
  kSoftware,  // a frame per AravisSource::software_trigger()
  kLine,      // a frame per edge on a hardware input line (AravisOptions::trigger_line)
};

struct RegionOfInterest {
  int x = 0, y = 0, width = 0, height = 0;  // pixels on the sensor
};

struct AravisOptions {
  std::string device;  // Aravis device id, serial number or IPv4 address
  CameraId camera = CameraId::kLeft;
  std::string pixel_format;  // PFNC name ("BayerRG8", "Mono8", "RGB8", "Mono12", ...); empty: as set
  std::optional<RegionOfInterest> roi;
  std::optional<double> frame_rate_hz;
  std::optional<double> exposure_us;
  std::optional<double> gain;  // in the camera's own unit (dB for SFNC Gain, raw for GainRaw)
  TriggerMode trigger = TriggerMode::kFreeRun;
  std::string trigger_line = "Line0";
  bool ptp = false;             // enable IEEE 1588 when the camera offers it (a note, not an error, when not)
  int packet_size = 0;          // GVSP packet size in bytes; 0: the largest that gets through (negotiated)
  int socket_buffer_bytes = 0;  // 0: three frames (capped by the kernel at net.core.rmem_max)
  bool packet_socket = true;    // false: plain UDP sockets even where a packet socket is possible
  int buffers = 16;             // stream buffer pool
  // No frame for this long (free-running; at least 3 frame periods) means the camera is lost.
  std::chrono::nanoseconds lost_after = std::chrono::milliseconds(500);
  bool reconnect = true;
  std::chrono::nanoseconds reconnect_period = std::chrono::milliseconds(250);
  // GenICam timestamps mark the start of exposure; half the exposure is added for mid-exposure.
  bool timestamp_at_exposure_start = true;
};

// One camera Aravis can see, for `augrig cameras`.
struct AravisDeviceInfo {
  std::string id, vendor, model, serial, address, protocol;  // protocol: "GigEVision", "USB3Vision"
  std::vector<std::string> pixel_formats;                    // empty when the camera could not be opened
  std::string error;                                         // why pixel formats are missing, if they are
  // The camera's current settings (read when it was opened; 0 / empty when not or unreadable):
  // the region's size, its pixel format and its acquisition frame rate.
  int width_px = 0, height_px = 0;
  std::string pixel_format;
  double frame_rate_hz = 0;
};

// Every camera Aravis discovers; with `open_each`, each is opened to read its pixel formats.
std::vector<AravisDeviceInfo> list_aravis_devices(bool open_each = true);

struct AravisStats {
  std::uint64_t frames = 0;           // delivered by read()
  std::uint64_t camera_drops = 0;     // frame-id gaps not explained by transport drops
  std::uint64_t transport_drops = 0;  // buffers with a status other than success
  std::uint64_t underruns = 0;        // the pool was empty when a frame came in (Aravis)
  std::uint64_t missing_packets = 0;  // Aravis stream statistics, summed over reconnects
  std::uint64_t resend_requests = 0;
  std::uint64_t resent_packets = 0;
  std::uint64_t disconnects = 0;
  std::uint64_t reconnects = 0;
};

// What the camera was configured to.
struct AravisCameraInfo {
  std::string id, vendor, model, serial, address;
  std::string pixel_format;  // as the camera streams it (PFNC)
  PixelFormat delivered = PixelFormat::kMono8;
  int width = 0, height = 0;
  double frame_rate_hz = 0;  // 0: unknown or triggered
  double exposure_us = 0;
  int packet_size = 0;             // GVSP bytes; 0 for USB3 Vision
  bool ptp = false;                // IEEE 1588 enabled on the camera
  std::vector<std::string> notes;  // what was asked for and not available
};

class AravisSource final : public FrameSource {
 public:
  // Connects and starts streaming. Errors name the device and the setting that failed.
  static Expected<std::unique_ptr<AravisSource>> open(const AravisOptions& options);
  ~AravisSource() override;
  AravisSource(const AravisSource&) = delete;
  AravisSource& operator=(const AravisSource&) = delete;

  std::string uri() const override;  // aravis://<device>
  std::string settings() const override;
  // kTimeout while the camera is lost (health() says so); never kEndOfStream.
  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds timeout) override;
  std::uint64_t frames_dropped() const override;
  SourceHealth health() const override;

  AravisStats stats() const;
  AravisCameraInfo info() const;
  // One frame in TriggerMode::kSoftware. Call it from the thread that reads.
  Status software_trigger();

 private:
  struct Impl;
  explicit AravisSource(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace augrig
