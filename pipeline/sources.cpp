#include "pipeline/sources.hpp"

#include <array>
#include <atomic>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>
#include <thread>

#include <time.h>

#include "capture/aravis_source.hpp"
#include "capture/v4l2_source.hpp"
#include "core/clock.hpp"
#include "pipeline/image_folder_source.hpp"
#include "recorder/euroc.hpp"
#include "recorder/mcap_export.hpp"
#include "recorder/replay_source.hpp"
#include "render/gl_context.hpp"
#include "sim/flight_source.hpp"
#include "sim/scenario.hpp"
#include "sim/sensors.hpp"
#include "sim/sim_clock.hpp"

namespace augrig::pipeline {
namespace {

Error uri_error(const SourceUri& u, const std::string& what) {
  return make_error("source URI '", u.text, "': ", what);
}

// sim://SCENARIO: the simulated flight's cameras, rendered on the capture thread that reads them
// by the CPU renderer (sim/synthetic_scene_cpu.hpp: no GL context), paced to real time unless rate=0.
class SimSource final : public FrameSource {
 public:
  SimSource(std::string uri, std::shared_ptr<const SimulatedFlight> sim, int every,
            std::shared_ptr<sim::SimClock> clock, bool physical_boom)
      : uri_(std::move(uri)),
        sim_(std::move(sim)),
        every_(every),
        clock_(std::move(clock)),
        physical_boom_(physical_boom) {}
  std::string uri() const override { return uri_; }
  std::uint64_t frames_dropped() const override { return dropped_; }
  SourceCapabilities capabilities() const override { return {.finite = true}; }
  std::size_t pair_count() const override { return image_count() / 2; }
  // The frames the flight's cameras deliver that every=K selects (as FlightSource selects them).
  std::size_t image_count() const override {
    if (!image_count_) {
      std::size_t n = 0;
      for (const sim::FrameTruth& t : sim::frame_truths(sim_->scenario, *sim_->flight, sim_->logs.cameras))
        n += every_ <= 1 || t.sequence % static_cast<std::uint64_t>(every_) == 0;
      image_count_ = n;
    }
    return *image_count_;
  }

  Expected<ReadStatus> read(Frame& out, std::chrono::nanoseconds) override {
    if (!source_) {
      auto src = sim::FlightSource::create(
          sim_->scenario, *sim_->flight, sim::frame_truths(sim_->scenario, *sim_->flight, sim_->logs.cameras),
          every_);
      if (!src) return make_error(uri_, ": ", src.error().message);
      source_ = std::move(*src);
      source_->set_physical_boom(physical_boom_);
    }
    if (clock_->paced()) {
      // Live-like: a frame whose time is more than a frame period past is lost, not rendered late
      // (a camera does not wait for its reader); counted with the camera's drops.
      const auto period_ns =
          static_cast<TimestampNs>(1e9 / std::max(1.0, sim_->scenario.sensors.cameras.fps));
      // The decision is taken per exposure (the left frame): its right partner shares its fate, so
      // that a source behind schedule loses whole pairs, not every right frame.
      while (const sim::FrameTruth* next = source_->peek()) {
        const bool late = monotonic_now_ns() > clock_->host_ns(next->t_gps_ns) + period_ns;
        const bool skip = next->camera == 0
                              ? late
                              : next->sequence == skipped_left_ || (late && next->sequence != rendered_left_);
        if (!skip) break;
        if (next->camera == 0) skipped_left_ = next->sequence;
        next_sequence_[next->camera] = next->sequence + static_cast<std::uint64_t>(every_);
        source_->skip();
        ++dropped_;
      }
      if (const sim::FrameTruth* next = source_->peek(); next && next->camera == 0)
        rendered_left_ = next->sequence;
    }
    auto r = source_->read(out, {});
    if (r && *r == ReadStatus::kFrame) {
      // Frames the simulated camera dropped (its timing model), counted as they are passed, as a
      // camera's frame-id gaps are. With every=K only every K-th sequence is delivered.
      std::uint64_t& expect = next_sequence_[index_of(out.camera)];
      if (out.sequence > expect) dropped_ += (out.sequence - expect) / static_cast<std::uint64_t>(every_);
      expect = out.sequence + static_cast<std::uint64_t>(every_);
    }
    if (!r || *r != ReadStatus::kFrame || !clock_->paced()) return r;
    // Real time on the run's clock (shared with the simulated nav streams): a frame is not handed
    // out before its mid-exposure instant.
    const TimestampNs due = clock_->host_ns(source_->last_truth().t_gps_ns);
    clock_->wait_until(source_->last_truth().t_gps_ns);
    const TimestampNs now = monotonic_now_ns();
    out.t_host_ns = std::max(due, now);
    return r;
  }

 private:
  std::string uri_;
  std::shared_ptr<const SimulatedFlight> sim_;
  int every_;
  std::shared_ptr<sim::SimClock> clock_;
  bool physical_boom_ = false;
  std::unique_ptr<sim::FlightSource> source_;
  std::array<std::uint64_t, 2> next_sequence_{};  // per camera: the camera model's own drops show as gaps
  std::atomic<std::uint64_t> dropped_{0};
  mutable std::optional<std::size_t> image_count_;
  std::uint64_t skipped_left_ = ~0ull,
                rendered_left_ = ~0ull;  // sequences  // read by the pipeline while the capture thread counts
};

Expected<sim::Scenario> scenario_of(const SourceUri& u) {
  if (u.target.find('/') != std::string::npos || u.target.ends_with(".yaml"))
    return sim::load_scenario(u.target);
  return sim::builtin_scenario(u.target);
}

Expected<std::uint32_t> fourcc_of(const SourceUri& u, const std::string& s) {
  if (s.size() != 4)
    return uri_error(
        u, "format: expected a V4L2 fourcc of 4 characters (YUYV, MJPG, GREY, ...), got '" + s + "'");
  return static_cast<std::uint32_t>(s[0]) | static_cast<std::uint32_t>(s[1]) << 8 |
         static_cast<std::uint32_t>(s[2]) << 16 | static_cast<std::uint32_t>(s[3]) << 24;
}

// One camera's source (aravis://, v4l2://).
Expected<std::unique_ptr<FrameSource>> open_camera(const SourceUri& u, CameraId camera) {
  if (u.scheme == "aravis") {
    if (Status s = u.check_known({"format", "fps", "exposure_us", "gain", "roi", "trigger", "ptp",
                                  "packet_size", "socket_buffer", "packet_socket", "buffers"});
        !s)
      return s.error();
    AravisOptions o;
    o.device = u.target;
    o.camera = camera;
    o.pixel_format = u.get("format");
    // Optional numbers: absent stays unset, a bad value is an error naming it.
    // Ranges beyond any camera: 0.001..10000 fps, exposures up to 100 s, gains up to 1000 dB.
    struct Setting {
      const char* key;
      std::optional<double>* field;
      double lo, hi;
    };
    for (auto [key, field, lo, hi] :
         {Setting{"fps", &o.frame_rate_hz, 1e-3, 1e4}, Setting{"exposure_us", &o.exposure_us, 0, 1e8},
          Setting{"gain", &o.gain, -1e3, 1e3}}) {
      if (!u.has(key)) continue;
      auto v = u.get_number(key, 0, lo, hi);
      if (!v) return v.error();
      *field = *v;
    }
    if (u.has("roi")) {
      RegionOfInterest r;
      if (std::sscanf(u.get("roi").c_str(), "%d,%d,%d,%d", &r.x, &r.y, &r.width, &r.height) != 4)
        return uri_error(u, "roi: expected X,Y,WIDTH,HEIGHT in pixels, got '" + u.get("roi") + "'");
      o.roi = r;
    }
    const std::string trigger = u.get("trigger", "free");
    if (trigger == "software") {
      // Nothing in a command sends software triggers: the camera would wait for one forever.
      return uri_error(u,
                       "trigger=software: no command sends software triggers (the camera would never "
                       "deliver a frame); expected free, or LineN for a hardware trigger line");
    } else if (trigger != "free") {
      o.trigger = TriggerMode::kLine;
      o.trigger_line = trigger;
    }
    o.ptp = u.get("ptp", "0") == "1";
    o.packet_socket = u.get("packet_socket", "1") == "1";
    for (auto [key, field] :
         {std::pair{"packet_size", &o.packet_size}, std::pair{"socket_buffer", &o.socket_buffer_bytes},
          std::pair{"buffers", &o.buffers}}) {
      if (!u.has(key)) continue;
      auto v = u.get_integer(key, 0);
      if (!v) return v.error();
      if (*v <= 0 || *v > std::numeric_limits<int>::max())
        return uri_error(u, std::string(key) + ": expected a positive integer");
      *field = static_cast<int>(*v);
    }
    auto src = AravisSource::open(o);
    if (!src) return src.error();
    return std::unique_ptr<FrameSource>(std::move(*src));
  }
  if (u.scheme == "v4l2") {
    if (Status s = u.check_known({"format", "width", "height", "fps", "buffers", "exposure_us", "gain"}); !s)
      return s.error();
    V4l2Options o;
    o.device_path = u.target;
    o.camera = camera;
    if (u.has("format")) {
      auto f = fourcc_of(u, u.get("format"));
      if (!f) return f.error();
      o.pixel_formats = {*f};
    }
    // Checked ranges before the casts to int below (32768: the largest image side augrig takes).
    auto w = u.get_integer("width", 0, 0, 32768), h = u.get_integer("height", 0, 0, 32768),
         b = u.get_integer("buffers", 4, 1, 64);
    auto fps = u.get_number("fps", 0, 0, 1e4), exp = u.get_number("exposure_us", -1, -1, 1e8);
    auto gain = u.get_integer("gain", -1, -1, std::numeric_limits<std::int32_t>::max());
    for (const auto* e : {&w, &h, &b})
      if (!*e) return e->error();
    for (const auto* e : {&fps, &exp})
      if (!*e) return e->error();
    if (!gain) return gain.error();
    o.width_px = static_cast<int>(*w);
    o.height_px = static_cast<int>(*h);
    o.buffer_count = static_cast<int>(*b);
    o.frame_rate_hz = *fps;
    if (*exp >= 0) o.exposure_ns = static_cast<std::int64_t>(*exp * 1e3);
    if (*gain >= 0) o.gain = static_cast<std::int32_t>(*gain);
    auto src = V4l2Source::open(o);
    if (!src) return src.error();
    return std::unique_ptr<FrameSource>(std::move(*src));
  }
  return uri_error(u, "a camera source must be aravis:// or v4l2://, got " + u.scheme + "://");
}

// ---- One opener per scheme ----

// sim://SCENARIO: the flight simulated once for the cameras, the nav streams and the truth.
Expected<OpenedSource> open_sim(const SourceUri& u) {
  OpenedSource out;
  if (Status s = u.check_known({"every", "rate", "bayer", "boom"}); !s) return s.error();
  auto scenario = scenario_of(u);
  if (!scenario) return uri_error(u, scenario.error().message);
  // bayer=RG|GR|GB|BG: the cameras deliver raw mosaics of that pattern, as GigE rigs do.
  if (u.has("bayer")) {
    const std::string b = u.get("bayer", "");
    const PixelFormat f = b == "RG"   ? PixelFormat::kBayerRG8
                          : b == "GR" ? PixelFormat::kBayerGR8
                          : b == "GB" ? PixelFormat::kBayerGB8
                          : b == "BG" ? PixelFormat::kBayerBG8
                                      : PixelFormat::kMono8;
    if (f == PixelFormat::kMono8) return uri_error(u, "bayer: expected RG, GR, GB or BG, got '" + b + "'");
    scenario->sensors.cameras.format = f;
  }
  // boom=physical: the boom is in the simulated scene (the frames a real boom would give), for
  // comparing augrig's augmentation with it (docs/LOOK.md); boom=none (default): boom-free frames.
  const std::string boom = u.get("boom", "none");
  if (boom != "none" && boom != "physical")
    return uri_error(u, "boom: expected none or physical, got '" + boom + "'");
  auto every = u.get_integer("every", 1, 1, 1'000'000);
  auto rate = u.get_number("rate", 1.0, 0, 1e6);
  if (!every) return every.error();
  if (!rate) return rate.error();
  if (*every < 1) return uri_error(u, "every: expected an integer >= 1");
  if (*rate < 0) return uri_error(u, "rate: expected >= 0 (0: as fast as possible)");
  out.scenario = scenario->name;
  // The flight and every sensor, simulated once here for the cameras, the nav streams and the truth.
  auto sim = std::make_shared<SimulatedFlight>();
  sim->scenario = *scenario;
  auto flight = sim::Flight::create(sim->scenario);
  if (!flight) return uri_error(u, flight.error().message);
  sim->flight = std::make_unique<sim::Flight>(std::move(*flight));
  sim->logs = sim::simulate_sensors(sim->scenario, *sim->flight);
  out.sim = sim;
  out.sim_clock = std::make_shared<sim::SimClock>(scenario->start_gps_ns, *rate);
  // Both cameras stamp the simulation's device clocks, which differ by their configured offsets.
  const auto& offs = scenario->sensors.cameras.clock_offset_ns;
  const std::int64_t skew = offs.size() >= 2 ? std::abs(offs[1] - offs[0]) : 0;
  out.options.pairing.tolerance_ns = skew + static_cast<std::int64_t>(0.25e9 / scenario->sensors.cameras.fps);
  out.options.lossless = *rate == 0;
  out.sources.push_back(std::make_unique<SimSource>(u.text, out.sim, static_cast<int>(*every), out.sim_clock,
                                                    boom == "physical"));
  return out;
}

// replay://FILE.mcap
Expected<OpenedSource> open_mcap(const SourceUri& u) {
  OpenedSource out;
  // An MCAP file from augrig export --format mcap: its frames as fast as read, once (lockstep).
  if (Status s = u.check_known({"rate"}); !s) return s.error();
  if (u.get("rate", "fast") != "fast")
    return uri_error(u,
                     "rate: an MCAP file plays as fast as it is read (rate=fast); pacing needs a recording");
  auto src = recorder::McapSource::open(u.target);
  if (!src) return src.error();
  out.options.lossless = true;
  out.options.skip_read_errors = true;  // a frame that cannot be decoded is skipped (the error says which)
  out.options.pairing.mode = PairingMode::kAdjacent;
  out.sources.push_back(std::move(*src));
  return out;
}

// replay://DIR: a recording, paced or fast, looped, from a frame or a time.
Expected<OpenedSource> open_replay(const SourceUri& u) {
  if (recorder::is_mcap_path(u.target)) return open_mcap(u);
  OpenedSource out;
  if (Status s = u.check_known({"rate", "loop", "passes", "from_frame", "seek_s", "late"}); !s)
    return s.error();
  recorder::ReplayOptions o;
  // The StereoSource's capture thread already reads the recording ahead of the pipeline (its
  // queue): a decode thread of the ReplaySource's own would only add a hand-off.
  o.read_ahead = 0;
  const std::string rate = u.get("rate", "1");
  if (rate == "fast") {
    o.mode = recorder::ReplayMode::kFast;
  } else {
    auto r = u.get_number("rate", 1.0, 0, 1e6);
    if (!r) return r.error();
    if (*r <= 0) return uri_error(u, "rate: expected a number > 0 or 'fast'");
    o.mode = recorder::ReplayMode::kRealRate;
    o.rate = *r;
    o.drop_late = true;  // live-like: late frames are lost, as a camera's would be
  }
  const std::string late = u.get("late", "drop");
  if (late != "drop" && late != "keep")
    return uri_error(u, "late: expected drop or keep, got '" + late + "'");
  if (late == "keep") o.drop_late = false;  // every frame, late or not
  // loop=1: forever; passes=N: the range N times.
  o.passes = u.get("loop", "0") == "1" ? 0 : 1;
  if (u.has("passes")) {
    auto n = u.get_integer("passes", 1, 1, 1'000'000);
    if (!n) return n.error();
    o.passes = static_cast<int>(*n);
  }
  if (u.has("from_frame") && u.has("seek_s")) return uri_error(u, "from_frame and seek_s exclude each other");
  if (u.has("from_frame")) {
    auto n = u.get_integer("from_frame", 0, 0, 1LL << 40);
    if (!n) return n.error();
    o.start_frame = static_cast<std::size_t>(*n);
  }
  if (u.has("seek_s")) {
    auto t = u.get_number("seek_s", 0, 0, 1e9);
    if (!t) return t.error();
    o.start_offset_ns = s_to_ns(*t);
  }
  auto src = recorder::ReplaySource::open(u.target, o);
  if (!src) return src.error();
  out.options.lossless = o.mode == recorder::ReplayMode::kFast || !o.drop_late;
  // A damaged frame is skipped (the recording says which), the others play on.
  out.options.skip_read_errors = true;
  // A recording holds pairs already: each recorded stereo frame comes as its left Frame, then its
  // right one, and they pair as delivered (a loop or a seek goes back in time).
  out.options.pairing.mode = PairingMode::kAdjacent;
  out.replay = src->get();
  out.sources.push_back(std::move(*src));
  return out;
}

Expected<OpenedSource> open_files(const SourceUri& u) {
  OpenedSource out;
  // files://INDEX.csv (a frame index: pairs by timestamp) or files://folders?left=DIR&right=DIR (two
  // folders, or two image files: pairs by sorted name; "folders" because a URI needs a target).
  // Lockstep: every file is read, none dropped.
  if (Status s = u.check_known({"left", "right", "bayer", "tolerance_us"}); !s) return s.error();
  ImageFolderOptions o;
  o.uri = u.text;
  if (u.has("bayer")) {
    const std::string b = u.get("bayer");
    o.bayer = b == "RG"   ? PixelFormat::kBayerRG8
              : b == "GR" ? PixelFormat::kBayerGR8
              : b == "GB" ? PixelFormat::kBayerGB8
              : b == "BG" ? PixelFormat::kBayerBG8
                          : PixelFormat::kMono8;
    if (o.bayer == PixelFormat::kMono8)
      return uri_error(u, "bayer: expected RG, GR, GB or BG, got '" + b + "'");
  }
  out.options.lossless = true;
  if (u.target == "folders") {
    if (!u.has("left") || !u.has("right"))
      return uri_error(u, "expected files://INDEX.csv or files://folders?left=DIR&right=DIR");
    if (u.has("tolerance_us"))
      return uri_error(u, "tolerance_us: folders pair by sorted name, not by time (give an index for that)");
    auto src = ImageFolderSource::open_folders(u.get("left"), u.get("right"), o);
    if (!src) return src.error();
    // Each pair comes as its left Frame, then its right one.
    out.options.pairing.mode = PairingMode::kAdjacent;
    out.image_files = src->get();
    out.sources.push_back(std::move(*src));
    return out;
  }
  if (u.has("left") || u.has("right"))
    return uri_error(u, "left and right name folders without an index; an index names its own files");
  auto src = ImageFolderSource::open_index(u.target, o);
  if (!src) return src.error();
  // Default: half the median frame interval (a frame can never pair with its neighbour's partner);
  // without an interval (one frame per camera), the widest tolerance a rig allows.
  const TimestampNs half = (*src)->half_median_interval_ns();
  const double default_us = half > 0 ? static_cast<double>(half) / 1e3 : kMaxPairingToleranceUs;
  auto tol = u.get_number("tolerance_us", default_us, 0, kMaxPairingToleranceUs);
  if (!tol) return tol.error();
  StereoPairerConfig& p = out.options.pairing;
  p.mode = PairingMode::kTimestamp;
  p.tolerance_ns = static_cast<std::int64_t>(*tol * 1e3);
  (*src)->set_pairing_tolerance(p.tolerance_ns);
  p.device_clock_shared = true;  // one index, one clock: its t_ns compare directly
  out.image_files = src->get();
  out.sources.push_back(std::move(*src));
  return out;
}

Expected<OpenedSource> open_euroc(const SourceUri& u) {
  OpenedSource out;
  // A EuRoC/ASL folder: each pair's left Frame, then its right one, as fast as read (lockstep).
  if (Status s = u.check_known({"tolerance_ns", "from_frame", "seek_s", "left", "right"}); !s)
    return s.error();
  recorder::EurocOptions eo;
  auto tol = u.get_integer("tolerance_ns", 0, 0, 1LL << 40);
  if (!tol) return tol.error();
  eo.pair_tolerance_ns = *tol;
  eo.left_stream = u.get("left", "cam0");
  eo.right_stream = u.get("right", "cam1");
  if (u.has("from_frame") && u.has("seek_s")) return uri_error(u, "from_frame and seek_s exclude each other");
  if (u.has("from_frame")) {
    auto n = u.get_integer("from_frame", 0, 0, 1LL << 40);
    if (!n) return n.error();
    eo.start_pair = static_cast<std::size_t>(*n);
  }
  if (u.has("seek_s")) {
    auto t = u.get_number("seek_s", 0, 0, 1e9);
    if (!t) return t.error();
    eo.start_offset_ns = s_to_ns(*t);
  }
  auto src = recorder::EurocSource::open(u.target, eo);
  if (!src) return src.error();
  out.options.lossless = true;
  out.options.skip_read_errors = true;  // an unreadable image skips its pair
  out.options.pairing.mode = PairingMode::kAdjacent;
  out.sources.push_back(std::move(*src));
  return out;
}

// stereo:[PAIRING]//{LEFT}{RIGHT}: two cameras, paired as a rig's pairing section says.
Expected<OpenedSource> open_stereo(const SourceUri& u) {
  OpenedSource out;
  if (Status s = u.check_known({"tolerance_us", "mode", "clock", "queue"}); !s) return s.error();
  // The same parameters, defaults and values as a rig's `pairing` section.
  const RigPairing defaults;
  // The rig's pairing section takes the same ranges (render/rig.cpp).
  auto tol = u.get_number("tolerance_us", defaults.tolerance_us, 0, kMaxPairingToleranceUs);
  auto queue = u.get_integer("queue", defaults.queue, 1, 1024);
  if (!tol) return tol.error();
  if (!queue) return queue.error();
  const std::string mode = u.get("mode", defaults.mode), clock = u.get("clock", defaults.clock);
  if (!RigPairing::known_mode(mode))
    return uri_error(u, "mode: expected timestamp or trigger_id, got '" + mode + "'");
  if (!RigPairing::known_clock(clock))
    return uri_error(
        u, "clock: expected separate (each camera its own clock) or shared (PTP), got '" + clock + "'");
  StereoPairerConfig& p = out.options.pairing;
  p.mode = mode == "timestamp" ? PairingMode::kTimestamp : PairingMode::kTriggerId;
  p.tolerance_ns = static_cast<std::int64_t>(*tol * 1e3);
  p.device_clock_shared = clock == "shared";
  // Separate device clocks are compared on host time, through each camera's estimated offset.
  if (!p.device_clock_shared) p.clock_offsets = ClockOffsetConfig{};
  out.options.queue_frames = static_cast<std::size_t>(std::max<long long>(1, *queue));
  out.live = true;
  for (int i = 0; i < 2; ++i) {
    auto cam = open_camera(u.children[i], i == 0 ? CameraId::kLeft : CameraId::kRight);
    if (!cam) return cam.error();
    out.sources.push_back(std::move(*cam));
  }
  return out;
}

Expected<OpenedSource> open_single_camera(const SourceUri& u) {
  return uri_error(u,
                   "one camera is not a stereo rig: give both, as stereo:[..]//{LEFT}{RIGHT} or the rig's "
                   "per-camera 'source' keys");
}

// The schemes, one opener each.
struct Scheme {
  const char* name;
  Expected<OpenedSource> (*open)(const SourceUri&);
};
constexpr Scheme kSchemes[] = {{"sim", open_sim},           {"replay", open_replay},
                               {"files", open_files},       {"euroc", open_euroc},
                               {"stereo", open_stereo},     {"aravis", open_single_camera},
                               {"v4l2", open_single_camera}};

// A left and a right URI as one stereo:[..]//{L}{R} with the rig's pairing.
SourceUri stereo_of(const SourceUri& left, const std::string& uri, const SourceUri& right,
                    const std::string& right_uri, const RigPairing& pairing) {
  SourceUri stereo;
  std::ostringstream tolerance;
  tolerance << std::setprecision(12) << pairing.tolerance_us;
  stereo.scheme = "stereo";
  stereo.params = {{"tolerance_us", tolerance.str()},
                   {"mode", pairing.mode},
                   {"clock", pairing.clock},
                   {"queue", std::to_string(pairing.queue)}};
  std::string params;
  for (const auto& [key, value] : stereo.params) params += (params.empty() ? "" : ",") + key + "=" + value;
  stereo.text = "stereo:[" + params + "]//{" + uri + "}{" + right_uri + "}";
  stereo.children = {left, right};
  return stereo;
}

}  // namespace

Expected<OpenedSource> open_sources(const std::string& uri, const std::string& right_uri,
                                    const RigPairing& pairing) {
  auto parsed = parse_source_uri(uri);
  if (!parsed) return parsed.error();
  SourceUri u = std::move(*parsed);
  if (!right_uri.empty()) {
    auto right = parse_source_uri(right_uri);
    if (!right) return right.error();
    u = stereo_of(u, uri, *right, right_uri, pairing);
  }
  for (const Scheme& scheme : kSchemes)
    if (u.scheme == scheme.name) return scheme.open(u);
  return uri_error(
      u, "unknown scheme '" + u.scheme + "'; expected aravis, v4l2, sim, replay, euroc, files or stereo");
}

Expected<std::unique_ptr<StereoSource>> start_stereo(OpenedSource opened) {
  return StereoSource::create(std::move(opened.sources), opened.options);
}

std::function<std::string(const StereoFrame&)> sim_phases(const std::vector<sim::FrameTruth>& truths) {
  auto by_t = std::make_shared<std::map<TimestampNs, std::string>>();
  for (const sim::FrameTruth& f : truths)
    if (f.camera == 0) (*by_t)[f.t_camera_ns] = f.phase;
  return [by_t](const StereoFrame& frame) -> std::string {
    const auto it = by_t->find(frame.left.t_ns);
    return it == by_t->end() ? std::string() : it->second;
  };
}

}  // namespace augrig::pipeline
