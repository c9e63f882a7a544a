// One camera, as a stereo:// rig's left or right URI:
//   aravis://ID|SERIAL|IP[?format=PFNC&fps=F&exposure_us=US&gain=DB&roi=X,Y,W,H&trigger=free|LineN
//            &ptp=1&packet_size=B&socket_buffer=B&packet_socket=0&buffers=N]  (capture/aravis_source.hpp)
//   v4l2:///dev/videoN[?format=FOURCC&width=W&height=H&fps=F&buffers=N&exposure_us=US&gain=G]
//                                                                             (capture/v4l2_source.hpp)
// Alone, aravis:// and v4l2:// are refused: one camera is not a stereo rig.
#include <cstdio>
#include <limits>
#include <optional>
#include <utility>

#include "capture/aravis_source.hpp"
#include "capture/v4l2_source.hpp"
#include "pipeline/sources/schemes.hpp"

namespace augrig::pipeline {
namespace {

Expected<std::uint32_t> fourcc_of(const SourceUri& u, const std::string& s) {
  if (s.size() != 4)
    return uri_error(
        u, "format: expected a V4L2 fourcc of 4 characters (YUYV, MJPG, GREY, ...), got '" + s + "'");
  return static_cast<std::uint32_t>(s[0]) | static_cast<std::uint32_t>(s[1]) << 8 |
         static_cast<std::uint32_t>(s[2]) << 16 | static_cast<std::uint32_t>(s[3]) << 24;
}

// aravis://
Expected<std::unique_ptr<FrameSource>> open_aravis(const SourceUri& u, CameraId camera) {
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

// v4l2://
Expected<std::unique_ptr<FrameSource>> open_v4l2(const SourceUri& u, CameraId camera) {
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

}  // namespace

// One camera's source (aravis://, v4l2://).
Expected<std::unique_ptr<FrameSource>> open_camera(const SourceUri& u, CameraId camera) {
  if (u.scheme == "aravis") return open_aravis(u, camera);
  if (u.scheme == "v4l2") return open_v4l2(u, camera);
  return uri_error(u, "a camera source must be aravis:// or v4l2://, got " + u.scheme + "://");
}

Expected<OpenedSource> open_single_camera(const SourceUri& u) {
  return uri_error(u,
                   "one camera is not a stereo rig: give both, as stereo:[..]//{LEFT}{RIGHT} or the rig's "
                   "per-camera 'source' keys");
}

}  // namespace augrig::pipeline
