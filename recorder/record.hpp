// What a recording holds, item by item: stereo frames (raw, augmented, masks, the receiver depth,
// the poses and boom articulation used, occlusion statistics), nav inputs exactly as received, the drop ledger,
// free-text events and the camera look's updates (noise level functions, the light measured). The Recorder (recorder/recorder.hpp) takes these items and the
// RecordingReader (recorder/reader.hpp) gives them back; docs/RECORDING.md has the schema.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "core/conventions.hpp"
#include "core/frame.hpp"
#include "core/pose.hpp"
#include "nav/types.hpp"
#include "render/camera_look.hpp"
#include "render/models.hpp"
#include "render/noise_level.hpp"
#include "render/stats.hpp"

namespace augrig::recorder {

// Where in the pipeline an item was lost. Every loss is entered in the drop ledger; none is silent.
enum class DropStage : std::uint8_t {
  kCamera,      // the camera skipped frames (sequence gaps, reported by the source)
  kTransport,   // lost between camera and host (incomplete GigE blocks, USB overruns)
  kPairing,     // a frame found no stereo partner (capture/stereo_pairer.hpp)
  kProcessing,  // augmentation or nav could not keep up or failed for a frame
  kRecorder,    // the recorder's queue was full, or writing failed
};
inline constexpr std::array<DropStage, 5> kAllDropStages = {DropStage::kCamera, DropStage::kTransport,
                                                            DropStage::kPairing, DropStage::kProcessing,
                                                            DropStage::kRecorder};
constexpr std::string_view to_string(DropStage s) {
  switch (s) {
    case DropStage::kCamera:
      return "camera";
    case DropStage::kTransport:
      return "transport";
    case DropStage::kPairing:
      return "pairing";
    case DropStage::kProcessing:
      return "processing";
    case DropStage::kRecorder:
      return "recorder";
  }
  return "?";
}
// Parses the names above; false for anything else.
bool parse_drop_stage(std::string_view name, DropStage& out);
// Parses core/conventions.hpp's ClockDomain names ("gps", "device", ...); false for anything else.
bool parse_clock_domain(std::string_view name, ClockDomain& out);

// A camera's receiver depth (render/stats.hpp DepthImage: z in metres along the optical axis,
// DepthImage::kNone = +inf where no receiver) as a recording holds it: the image's size and the
// smallest box holding every value that is not +inf, with the values inside it, row-major. Outside
// the box every value is +inf. Bit-exact both ways (any float inside the box, NaN and -inf too).
// The receiver covers a small part of a frame, so the box is what is stored (codec.hpp).
struct DepthRecord {
  int width = 0, height = 0;  // of the whole image; 0: not recorded
  PixelBox box;
  std::vector<float> z_m;  // box.width() * box.height() values

  bool empty() const { return width <= 0 || height <= 0; }
  // The box of `depth` (one pass over it) and its values.
  static DepthRecord from(const DepthImage& depth);
  // The whole image again, +inf outside the box.
  DepthImage image() const;
};

// One stereo frame and what was made of it. Only `raw` is required; everything else is optional
// and is recorded only when present (an empty Image, std::nullopt or NaN means "not present").
struct FrameRecord {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

  // Raw images exactly as captured (any PixelFormat, any stride; both cameras), timestamps,
  // clocks, sequences, pairing key and skew.
  StereoFrame raw;
  // Per camera (index_of(CameraId)): the augmented image, same size and format as the raw one;
  // or, when augmented_box[c] is set, only its part inside that box (an image of the box's size,
  // as render/augmenter.hpp's AugmentedOutput::kChangedBox makes it), the rest being the raw image.
  // An empty box then means the augmented image is the raw image.
  std::array<Image, 2> augmented;
  std::array<std::optional<PixelBox>, 2> augmented_box;
  // Per camera: the Mono8 mask (kMaskBoom | kMaskReceiver), same size as the raw image.
  std::array<Image, 2> mask;
  // Per camera: the receiver depth behind the mask (ViewResult::receiver_depth), recorded only when
  // asked (`--ground-truth`); same size as the raw image. With the rig and the masks it gives the
  // rest of the ground truth (the correspondence, the stereo classes: docs/GROUND_TRUTH.md).
  std::array<DepthRecord, 2> receiver_depth;
  // The relative poses the augmentation used: the receiver in each camera (OpenCV camera frame,
  // receiver body FRD) and in the tanker body frame, with their 1-sigma errors.
  std::array<std::optional<Pose>, 2> T_cam_receiver;
  std::optional<Pose> T_body_receiver;
  std::optional<bool> receiver_present;
  double sigma_pos_m = kNaN;
  double sigma_att_deg = kNaN;
  std::optional<BoomArticulation> boom;
  std::optional<OcclusionStats> stats;
};

// A raw image's blob exactly as a recording stores it (codec.hpp's raw encoding, the recording's
// `codec.raw` being this build's kRawCodec), with what identifies the image it holds. A replayed
// Frame carries both of its stereo frame's (replay_source.hpp, RecordedFrame) so that the Recorder
// can store them again as they are, without decoding or compressing (recorder.hpp, push()).
struct StoredRawBlob {
  std::vector<std::uint8_t> bytes;  // empty: no blob (not kept, or another codec)
  PixelFormat format = PixelFormat::kMono8;
  int width = 0, height = 0;
  TimestampNs t_ns = 0;          // the Frame's mid-exposure time
  std::uint64_t fingerprint = 0;  // raw_fingerprint() (codec.hpp) of the decoded image

  bool empty() const { return bytes.empty(); }
};

// One nav input exactly as received: an NMEA line (without its line ending), an IMU sample as the
// device sent it, a CSV row, ... `data` is stored byte for byte; `binary` says whether it is text
// (SQLite TEXT) or bytes (BLOB).
struct NavInputRecord {
  std::string stream;    // "gps", "imu", "tanker.gps", ...
  TimestampNs t_ns = 0;  // sensor time of validity (0: unknown), in `clock`
  ClockDomain clock = ClockDomain::kGps;
  TimestampNs arrival_ns = 0;  // host arrival time, ClockDomain::kHostMonotonic (0: unknown)
  std::string data;
  bool binary = false;
};

// An IMU sample as one line of the nav IMU CSV (nav/logs.hpp, docs/NAV_FORMATS.md):
// "t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps,arrival_ns", every
// double in its shortest exact text, so the sample reads back bit-exact.
NavInputRecord imu_input(const nav::ImuSample& sample, std::string stream = "imu");
// The header line that makes imu_input()'s rows a file nav::parse_imu_csv() reads.
std::string_view imu_input_header();

// An entry of the drop ledger: `count` items of kind `item` lost at `stage`, the first and last
// of them stamped `first_t_ns` and `last_t_ns` (their own clock; 0: unknown).
struct DropRecord {
  DropStage stage = DropStage::kCamera;
  std::uint64_t count = 0;
  TimestampNs first_t_ns = 0;
  TimestampNs last_t_ns = 0;
  std::string reason;
  std::string item = "frame";  // "frame", "nav_input", "event", "look"
};

struct EventRecord {
  TimestampNs t_ns = 0;
  ClockDomain clock = ClockDomain::kHostMonotonic;
  std::string text;
};

// One update of what the camera look knows (pipeline/look_stage.hpp, docs/LOOK.md), recorded when
// it changes rather than per frame: a camera's noise level function, or the light measured on the
// receiver.
struct LookNoise {
  int camera = 0;            // rig camera index: 0 left, 1 right
  NoiseLevelFunction nlf;    // channels 1 (grey) or 3 (R, G, B); a in DN, b in DN^2
  bool configured = false;   // the rig's (look.noise_a/noise_b), not estimated from the frames
  std::uint64_t frames = 0;  // frames the estimate used (0 when configured)
  std::string note;          // the estimator's word on it ("one level only: a = 0"), may be empty
};
struct LookLight {
  // render/light_probe.hpp LightFit: per channel R, G, B, in SceneLight's units.
  Eigen::Vector3d direct = Eigen::Vector3d::Zero(), sky = Eigen::Vector3d::Zero(),
                  ground = Eigen::Vector3d::Zero();
  std::uint64_t samples = 0;  // points the fit used
  double rms = 0;             // the inliers' residual RMS
  // The scene's sun when it was measured: where its direction came from, whether it was up, and
  // the unit vector towards it in the tanker's body frame.
  LightSource source = LightSource::kFixed;
  bool sun_up = false;
  Eigen::Vector3d towards_sun_body = Eigen::Vector3d::Zero();
};
struct LookRecord {
  TimestampNs t_ns = 0;  // the pair whose frames gave it (its t_key_ns), in `clock`
  ClockDomain clock = ClockDomain::kUnknown;
  std::variant<LookNoise, LookLight> update;
};
// "noise" or "light", the `look` table's kind.
std::string_view look_kind(const LookRecord& r);
// Parses render/camera_look.hpp's LightSource names ("ephemeris", "default sun", ...); false for
// anything else.
bool parse_light_source(std::string_view name, LightSource& out);

using RecordItem = std::variant<FrameRecord, NavInputRecord, DropRecord, EventRecord, LookRecord>;

// Which images RecordingReader::read_frame() decodes (a bit set); metadata, poses and statistics
// always come.
enum FrameParts : unsigned {
  kPartsNone = 0,
  kPartRaw = 1u << 0,
  kPartAugmented = 1u << 1,  // needs the raw images too; asking for it decodes them
  kPartMasks = 1u << 2,
  kPartDepth = 1u << 3,  // the receiver depth (when recorded)
  kPartsAll = kPartRaw | kPartAugmented | kPartMasks | kPartDepth,
};

// What a recording is about, stored once in its `meta` table.
struct RecordingInfo {
  std::string rig_yaml;                      // the rig file's text (render/rig.hpp)
  std::string scene;                         // the scene or scenario file's text, if any
  std::string clock_domains;                 // free text: which clock each stream uses and known offsets
  std::map<std::string, std::string> extra;  // more meta keys (must not start with "summary.")
};

}  // namespace augrig::recorder
