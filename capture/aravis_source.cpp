#include "capture/aravis_source.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <thread>

#include <arpa/inet.h>
#include <arv.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "core/clock.hpp"

namespace augrig {
namespace {

// A first frame may take longer than the stall limit: the camera starts its sensor, and a camera
// just restarted (or a loaded host) may need a moment more.
constexpr TimestampNs kFirstFrameGraceNs = 2'000'000'000;

// GObject references released on scope exit.
struct GObjectUnref {
  void operator()(void* p) const {
    if (p) g_object_unref(p);
  }
};
template <typename T>
using GPtr = std::unique_ptr<T, GObjectUnref>;

// Turns a GError into an Error "AravisSource::open(): aravis://DEV: WHAT: MESSAGE" and frees it.
Error take_error(GError*& e, const std::string& where, const std::string& what) {
  std::string msg = e ? e->message : "failed";
  g_clear_error(&e);
  return make_error(where, ": ", what, ": ", msg);
}

// How an Aravis pixel format becomes an 8-bit augrig image.
struct FormatMap {
  ArvPixelFormat arv;
  const char* name;
  PixelFormat out;
  int bits;  // significant bits per sample; > 8 arrives as 16-bit little-endian containers
};
constexpr FormatMap kFormats[] = {
    {ARV_PIXEL_FORMAT_MONO_8, "Mono8", PixelFormat::kMono8, 8},
    {ARV_PIXEL_FORMAT_RGB_8_PACKED, "RGB8", PixelFormat::kRGB8, 8},
    {ARV_PIXEL_FORMAT_BAYER_RG_8, "BayerRG8", PixelFormat::kBayerRG8, 8},
    {ARV_PIXEL_FORMAT_BAYER_GR_8, "BayerGR8", PixelFormat::kBayerGR8, 8},
    {ARV_PIXEL_FORMAT_BAYER_GB_8, "BayerGB8", PixelFormat::kBayerGB8, 8},
    {ARV_PIXEL_FORMAT_BAYER_BG_8, "BayerBG8", PixelFormat::kBayerBG8, 8},
    {ARV_PIXEL_FORMAT_MONO_10, "Mono10", PixelFormat::kMono8, 10},
    {ARV_PIXEL_FORMAT_MONO_12, "Mono12", PixelFormat::kMono8, 12},
    {ARV_PIXEL_FORMAT_MONO_16, "Mono16", PixelFormat::kMono8, 16},
    {ARV_PIXEL_FORMAT_BAYER_RG_10, "BayerRG10", PixelFormat::kBayerRG8, 10},
    {ARV_PIXEL_FORMAT_BAYER_GR_10, "BayerGR10", PixelFormat::kBayerGR8, 10},
    {ARV_PIXEL_FORMAT_BAYER_GB_10, "BayerGB10", PixelFormat::kBayerGB8, 10},
    {ARV_PIXEL_FORMAT_BAYER_BG_10, "BayerBG10", PixelFormat::kBayerBG8, 10},
    {ARV_PIXEL_FORMAT_BAYER_RG_12, "BayerRG12", PixelFormat::kBayerRG8, 12},
    {ARV_PIXEL_FORMAT_BAYER_GR_12, "BayerGR12", PixelFormat::kBayerGR8, 12},
    {ARV_PIXEL_FORMAT_BAYER_GB_12, "BayerGB12", PixelFormat::kBayerGB8, 12},
    {ARV_PIXEL_FORMAT_BAYER_BG_12, "BayerBG12", PixelFormat::kBayerBG8, 12},
    {ARV_PIXEL_FORMAT_BAYER_RG_16, "BayerRG16", PixelFormat::kBayerRG8, 16},
    {ARV_PIXEL_FORMAT_BAYER_GR_16, "BayerGR16", PixelFormat::kBayerGR8, 16},
    {ARV_PIXEL_FORMAT_BAYER_GB_16, "BayerGB16", PixelFormat::kBayerGB8, 16},
    {ARV_PIXEL_FORMAT_BAYER_BG_16, "BayerBG16", PixelFormat::kBayerBG8, 16},
};
const FormatMap* format_by_arv(ArvPixelFormat f) {
  for (const auto& m : kFormats)
    if (m.arv == f) return &m;
  return nullptr;
}
const FormatMap* format_by_name(const std::string& name) {
  for (const auto& m : kFormats)
    if (name == m.name) return &m;
  return nullptr;
}
std::string supported_format_names() {
  std::string s;
  for (const auto& m : kFormats) s += (s.empty() ? "" : ", ") + std::string(m.name);
  return s;
}

// Copies one received image into `out`, narrowing >8-bit samples to their top 8 bits.
bool convert(const FormatMap& fm, const std::uint8_t* data, std::size_t size, int width, int height,
             Image& out) {
  const int bpp = fm.out == PixelFormat::kRGB8 ? 3 : 1;
  const std::size_t in_row = static_cast<std::size_t>(width) * bpp * (fm.bits > 8 ? 2 : 1);
  if (size < in_row * static_cast<std::size_t>(height)) return false;
  if (out.width() != width || out.height() != height || out.format() != fm.out)
    out = Image(width, height, fm.out);
  if (fm.bits == 8) {
    for (int y = 0; y < height; ++y) std::memcpy(out.row(y), data + y * in_row, in_row);
    return true;
  }
  const int shift = fm.bits - 8;
  const unsigned max_value = (1u << fm.bits) - 1;
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* in = data + y * in_row;
    std::uint8_t* o = out.row(y);
    for (int x = 0; x < width * bpp; ++x) {
      const unsigned v = std::min<unsigned>(in[2 * x] | (in[2 * x + 1] << 8), max_value);
      o[x] = static_cast<std::uint8_t>(v >> shift);
    }
  }
  return true;
}

struct DeviceEntry {
  std::string id, vendor, model, serial, address, protocol;
};

std::vector<DeviceEntry> discover() {
  arv_update_device_list();
  std::vector<DeviceEntry> out;
  const unsigned n = arv_get_n_devices();
  auto str = [](const char* s) { return std::string(s ? s : ""); };
  for (unsigned i = 0; i < n; ++i)
    out.push_back({str(arv_get_device_id(i)), str(arv_get_device_vendor(i)), str(arv_get_device_model(i)),
                   str(arv_get_device_serial_nbr(i)), str(arv_get_device_address(i)),
                   str(arv_get_device_protocol(i))});
  return out;
}

bool looks_like_ipv4(const std::string& s) {
  GInetAddress* a = g_inet_address_new_from_string(s.c_str());
  const bool ok = a && g_inet_address_get_family(a) == G_SOCKET_FAMILY_IPV4;
  if (a) g_object_unref(a);
  return ok;
}

// Asks ADDRESS:3956 for a GigE Vision discovery ack, waiting at most `timeout_ms`. Cheap, unlike
// arv_camera_new(), which blocks for seconds on an address where nothing answers.
bool gvcp_answers(const std::string& address, int timeout_ms) {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(3956);
  bool ok = inet_pton(AF_INET, address.c_str(), &to.sin_addr) == 1;
  // GVCP command header: key 0x42, flags (ack wanted), DISCOVERY_CMD 0x0002, length 0, request id.
  const std::uint8_t cmd[8] = {0x42, 0x01, 0x00, 0x02, 0x00, 0x00, 0x7a, 0x11};
  ok = ok && sendto(fd, cmd, sizeof cmd, 0, reinterpret_cast<const sockaddr*>(&to), sizeof to) == sizeof cmd;
  bool answered = false;
  pollfd p{fd, POLLIN, 0};
  while (ok && !answered && poll(&p, 1, timeout_ms) == 1) {
    std::uint8_t ack[600];
    const ssize_t n = recv(fd, ack, sizeof ack, 0);
    if (n < 8) break;
    // Ack header: status 0x0000, DISCOVERY_ACK 0x0003, ..., our request id.
    answered =
        ack[0] == 0 && ack[1] == 0 && ack[2] == 0x00 && ack[3] == 0x03 && ack[6] == 0x7a && ack[7] == 0x11;
  }
  close(fd);
  return answered;
}

}  // namespace

std::vector<AravisDeviceInfo> list_aravis_devices(bool open_each) {
  std::vector<AravisDeviceInfo> out;
  for (const DeviceEntry& d : discover()) {
    AravisDeviceInfo info;
    info.id = d.id;
    info.vendor = d.vendor;
    info.model = d.model;
    info.serial = d.serial;
    info.address = d.address;
    info.protocol = d.protocol;
    if (open_each) {
      GError* e = nullptr;
      GPtr<ArvCamera> cam(arv_camera_new(d.id.c_str(), &e));
      if (!cam) {
        info.error = take_error(e, "open", d.id).message;
      } else {
        guint n = 0;
        const char** names = arv_camera_dup_available_pixel_formats_as_strings(cam.get(), &n, &e);
        if (names) {
          for (guint i = 0; i < n; ++i) info.pixel_formats.emplace_back(names[i]);
          g_free(names);
        } else {
          info.error = take_error(e, "pixel formats", d.id).message;
        }
        // What it is set to now: what a rig template and a URI without parameters get.
        gint x = 0, y = 0, w = 0, h = 0;
        arv_camera_get_region(cam.get(), &x, &y, &w, &h, &e);
        if (e) {
          g_clear_error(&e);
        } else {
          info.width_px = w, info.height_px = h;
        }
        if (const char* f = arv_camera_get_pixel_format_as_string(cam.get(), &e)) info.pixel_format = f;
        if (e) g_clear_error(&e);
        const double fps = arv_camera_get_frame_rate(cam.get(), &e);
        if (e)
          g_clear_error(&e);
        else if (std::isfinite(fps) && fps > 0)
          info.frame_rate_hz = fps;
      }
    }
    out.push_back(std::move(info));
  }
  return out;
}

struct AravisSource::Impl {
  AravisOptions options;
  std::string where;       // "AravisSource: aravis://DEV"
  std::string connect_id;  // what arv_camera_new() is given (an Aravis id or an address)

  GPtr<ArvCamera> camera;
  GPtr<ArvStream> stream;
  std::atomic<bool> control_lost{false};
  gulong control_lost_handler = 0;
  const FormatMap* format = nullptr;
  std::int64_t exposure_ns = 0;
  double frame_period_s = 0;

  // Streaming state, touched by read() only.
  bool connected = false;
  // Acquisition starts at the first read(), not at open(): a camera opened while the rest of the
  // pipeline sets up (GL, the augmenter, the recorder) would otherwise fill Aravis' few buffers and
  // then lose frames (underruns, seen as frame id gaps), and the stale ones would reach the
  // pairer in a burst. A reconnection restarts it at once.
  bool acquiring = false;
  TimestampNs last_activity_ns = 0;  // a buffer (good or bad) or (re)connection
  TimestampNs lost_since_ns = 0;
  TimestampNs next_attempt_ns = 0;
  bool have_last_id = false;
  std::uint64_t last_id = 0;
  std::uint64_t sequence = 0;
  // Frames lost in transport since the last good one: the frame id gap they leave is theirs, not
  // the camera's (each lost frame is counted once, as a transport drop).
  std::uint64_t transport_lost_since_good = 0;
  std::atomic<TimestampNs> trigger_pending_since_ns{0};  // software trigger sent, frame not yet seen
  TimestampNs counters_read_ns = 0;  // when Aravis' stream counters were last copied into stats

  mutable std::mutex mutex;  // guards what other threads read: stats, health, info
  AravisStats stats;
  AravisStats stream_base;  // Aravis counters of streams already torn down
  SourceHealth health;
  AravisCameraInfo info;

  static void on_control_lost(ArvDevice*, gpointer self) {
    static_cast<Impl*>(self)->control_lost.store(true);
  }

  // `start`: start acquisition too (a reconnection); open() leaves that to the first read().
  Status connect(bool start);
  Status start_acquisition();
  // Stops and releases the camera; `device_gone`: without waiting on a camera that cannot answer.
  void teardown(bool device_gone = false);
  // Whether a reconnection attempt can succeed now (a quick GVCP probe where the address is known).
  bool worth_connecting();
  int attempts = 0;
  void declare_lost(const std::string& why, TimestampNs now);
  void update_stream_counters();
  std::chrono::nanoseconds stall_limit() const {
    auto limit = options.lost_after;
    if (frame_period_s > 0)
      limit = std::max(limit, std::chrono::nanoseconds(static_cast<std::int64_t>(3e9 * frame_period_s)));
    return limit;
  }
};

// Resolves the device, opens it, applies every option and creates the stream (and starts it: `start`).
Status AravisSource::Impl::connect(bool start) {
  GError* e = nullptr;
  camera.reset(arv_camera_new(connect_id.c_str(), &e));
  if (!camera) return take_error(e, where, "cannot connect");
  ArvCamera* cam = camera.get();
  ArvDevice* device = arv_camera_get_device(cam);
  control_lost.store(false);
  control_lost_handler = g_signal_connect(device, "control-lost", G_CALLBACK(&Impl::on_control_lost), this);
  std::vector<std::string> notes;

  // Format first: region and packet size depend on it.
  if (!options.pixel_format.empty()) {
    if (!format_by_name(options.pixel_format))
      return make_error(where, ": pixel_format '", options.pixel_format,
                        "' is not supported; expected one of ", supported_format_names());
    arv_camera_set_pixel_format_from_string(cam, options.pixel_format.c_str(), &e);
    if (e) return take_error(e, where, "pixel_format " + options.pixel_format);
  }
  if (options.roi) {
    const RegionOfInterest& r = *options.roi;
    gint w_min = 0, w_max = 0, h_min = 0, h_max = 0;
    arv_camera_get_width_bounds(cam, &w_min, &w_max, nullptr);
    arv_camera_get_height_bounds(cam, &h_min, &h_max, nullptr);
    if (r.x < 0 || r.y < 0 || r.width < w_min || r.height < h_min || r.x + r.width > w_max ||
        r.y + r.height > h_max)
      return make_error(where, ": roi ", r.x, ",", r.y, " ", r.width, "x", r.height,
                        " does not fit the sensor (", w_max, "x", h_max, ")");
    arv_camera_set_region(cam, r.x, r.y, r.width, r.height, &e);
    if (e) return take_error(e, where, "roi");
  }
  switch (options.trigger) {
    case TriggerMode::kFreeRun:
      arv_camera_clear_triggers(cam, &e);
      break;
    case TriggerMode::kSoftware:
      arv_camera_set_trigger(cam, "Software", &e);
      break;
    case TriggerMode::kLine:
      arv_camera_set_trigger(cam, options.trigger_line.c_str(), &e);
      break;
  }
  if (e) return take_error(e, where, "trigger");
  if (options.frame_rate_hz) {
    arv_camera_set_frame_rate(cam, *options.frame_rate_hz, &e);
    if (e) return take_error(e, where, "frame_rate_hz " + std::to_string(*options.frame_rate_hz));
  }
  if (options.exposure_us) {
    if (arv_camera_is_exposure_auto_available(cam, nullptr))
      arv_camera_set_exposure_time_auto(cam, ARV_AUTO_OFF, nullptr);
    arv_camera_set_exposure_time(cam, *options.exposure_us, &e);
    if (e) return take_error(e, where, "exposure_us " + std::to_string(*options.exposure_us));
  }
  if (options.gain) {
    if (arv_camera_is_gain_auto_available(cam, nullptr)) arv_camera_set_gain_auto(cam, ARV_AUTO_OFF, nullptr);
    arv_camera_set_gain(cam, *options.gain, &e);
    if (e) return take_error(e, where, "gain " + std::to_string(*options.gain));
  }
  bool ptp = false;
  if (options.ptp) {
    // SFNC 2 names it PtpEnable; GigE Vision 1.2 cameras GevIEEE1588.
    for (const char* feature : {"PtpEnable", "GevIEEE1588"}) {
      if (arv_camera_is_feature_available(cam, feature, nullptr)) {
        arv_camera_set_boolean(cam, feature, TRUE, &e);
        if (e) return take_error(e, where, std::string("ptp (") + feature + ")");
        ptp = true;
        break;
      }
    }
    if (!ptp) notes.emplace_back("ptp requested, but the camera has neither PtpEnable nor GevIEEE1588");
  }
  int packet_size = 0;
  if (arv_camera_is_gv_device(cam)) {
    if (!options.packet_socket)
      arv_camera_gv_set_stream_options(cam, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
    if (options.packet_size > 0) {
      arv_camera_gv_set_packet_size(cam, options.packet_size, &e);
      if (e) return take_error(e, where, "packet_size " + std::to_string(options.packet_size));
    } else {
      // Largest size that gets through the path (Aravis probes with test packets).
      arv_camera_gv_auto_packet_size(cam, &e);
      if (e) return take_error(e, where, "packet size negotiation");
    }
    packet_size = static_cast<int>(arv_camera_gv_get_packet_size(cam, nullptr));
  }

  // What the camera now streams.
  const ArvPixelFormat pf = arv_camera_get_pixel_format(cam, &e);
  if (e) return take_error(e, where, "pixel format");
  format = format_by_arv(pf);
  if (!format) {
    const char* name = arv_camera_get_pixel_format_as_string(cam, nullptr);
    return make_error(where, ": the camera streams ", name ? name : "an unknown format",
                      ", which is not supported; set pixel_format to one of ", supported_format_names());
  }
  gint x = 0, y = 0, w = 0, h = 0;
  arv_camera_get_region(cam, &x, &y, &w, &h, nullptr);
  const double exposure_us = arv_camera_get_exposure_time(cam, nullptr);
  exposure_ns = static_cast<std::int64_t>(exposure_us * 1e3);
  const double rate =
      options.trigger == TriggerMode::kFreeRun ? arv_camera_get_frame_rate(cam, nullptr) : 0.0;
  frame_period_s = rate > 0 ? 1.0 / rate : 0.0;

  stream.reset(arv_camera_create_stream(cam, nullptr, nullptr, &e));
  if (!stream) return take_error(e, where, "cannot create the stream");
  if (ARV_IS_GV_STREAM(stream.get())) {
    g_object_set(stream.get(), "packet-resend", ARV_GV_STREAM_PACKET_RESEND_ALWAYS, nullptr);
  }
  const guint payload = arv_camera_get_payload(cam, &e);
  if (e) return take_error(e, where, "payload size");
  if (ARV_IS_GV_STREAM(stream.get())) {
    // Aravis' automatic size is one frame, which the kernel's per-datagram overhead overflows at
    // 8000-byte packets without a packet socket (bench_capture: half the frames lost at 30 fps);
    // three frames by default (the kernel caps it at net.core.rmem_max).
    const int bytes = options.socket_buffer_bytes > 0
                          ? options.socket_buffer_bytes
                          : static_cast<int>(std::min<guint>(3 * payload, 1u << 30));
    g_object_set(stream.get(), "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size",
                 bytes, nullptr);
  }
  for (int i = 0; i < std::max(2, options.buffers); ++i)
    arv_stream_push_buffer(stream.get(), arv_buffer_new_allocate(payload));
  if (start)
    if (Status s = start_acquisition(); !s) return s;

  auto str = [](const char* s) { return std::string(s ? s : ""); };
  std::lock_guard lock(mutex);
  info.id = str(arv_camera_get_device_id(cam, nullptr));
  info.vendor = str(arv_camera_get_vendor_name(cam, nullptr));
  info.model = str(arv_camera_get_model_name(cam, nullptr));
  info.serial = str(arv_camera_get_device_serial_number(cam, nullptr));
  if (ARV_IS_GV_DEVICE(device)) {
    GSocketAddress* addr = arv_gv_device_get_device_address(ARV_GV_DEVICE(device));
    if (addr) {
      gchar* s = g_inet_address_to_string(g_inet_socket_address_get_address(G_INET_SOCKET_ADDRESS(addr)));
      info.address = s;
      g_free(s);
    }
  }
  info.pixel_format = format->name;
  info.delivered = format->out;
  info.width = w;
  info.height = h;
  info.frame_rate_hz = rate;
  info.exposure_us = exposure_us;
  info.packet_size = packet_size;
  info.ptp = ptp;
  info.notes = std::move(notes);
  return {};
}

// Aravis' counters live in the stream; keep what a stream counted before it is torn down.
void AravisSource::Impl::update_stream_counters() {
  if (!stream) return;
  ArvStream* s = stream.get();
  auto get = [s](const char* name) { return arv_stream_get_info_uint64_by_name(s, name); };
  std::lock_guard lock(mutex);
  stats.underruns = stream_base.underruns + get("n_underruns");
  stats.missing_packets = stream_base.missing_packets + get("n_missing_packets");
  stats.resend_requests = stream_base.resend_requests + get("n_resend_requests");
  stats.resent_packets = stream_base.resent_packets + get("n_resent_packets");
}

Status AravisSource::Impl::start_acquisition() {
  GError* e = nullptr;
  arv_camera_start_acquisition(camera.get(), &e);
  if (e) return take_error(e, where, "cannot start acquisition");
  acquiring = true;
  last_activity_ns = monotonic_now_ns() + kFirstFrameGraceNs;
  return {};
}

void AravisSource::Impl::teardown(bool device_gone) {
  update_stream_counters();
  {
    std::lock_guard lock(mutex);
    stream_base = stats;
  }
  if (camera && control_lost_handler)
    g_signal_handler_disconnect(arv_camera_get_device(camera.get()), control_lost_handler);
  control_lost_handler = 0;
  connected = false;
  acquiring = false;
  if (!device_gone) {
    if (camera) arv_camera_stop_acquisition(camera.get(), nullptr);
    stream.reset();
    camera.reset();
    return;
  }
  // Every GVCP exchange with a camera that is gone waits out its timeouts and retries (Aravis:
  // 2.5 s to stop, 10 s to release stream and device), so the objects are released on a thread
  // of their own and read() goes on at once.
  std::thread([s = stream.release(), c = camera.release()] {
    if (s) g_object_unref(s);
    if (c) g_object_unref(c);
  }).detach();
}

void AravisSource::Impl::declare_lost(const std::string& why, TimestampNs now) {
  {
    // Reported before anything else happens.
    std::lock_guard lock(mutex);
    stats.disconnects++;
    health.connected = false;
    health.disconnects = stats.disconnects;
    health.message = std::string(to_string(options.camera)) + " camera (" + options.device +
                     ") lost: " + why + (options.reconnect ? "; reconnecting" : "");
  }
  teardown(/*device_gone=*/true);
  lost_since_ns = now;
  next_attempt_ns = now;
  attempts = 0;
  have_last_id = false;  // a restarted camera counts its frames anew
  transport_lost_since_good = 0;
  trigger_pending_since_ns = 0;
}

bool AravisSource::Impl::worth_connecting() {
  ++attempts;
  std::string address;
  {
    std::lock_guard lock(mutex);
    address = info.address;
  }
  if (address.empty()) return true;  // USB3 Vision: opening is the probe
  if (gvcp_answers(address, 100)) return true;
  // A camera given by id or serial may come back at another address (DHCP): look for it about
  // once a second, since discovery waits a second for answers.
  if (connect_id != address && attempts % 4 == 0) {
    for (const DeviceEntry& d : discover()) {
      if (d.id == connect_id) {
        std::lock_guard lock(mutex);
        info.address = d.address;
        return true;
      }
    }
  }
  return false;
}

AravisSource::AravisSource(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

AravisSource::~AravisSource() {
  if (impl_) impl_->teardown();
}

Expected<std::unique_ptr<AravisSource>> AravisSource::open(const AravisOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->where = "AravisSource: aravis://" + options.device;
  if (options.device.empty())
    return make_error("AravisSource: empty device; expected an Aravis id, serial or IPv4 address");
  if (!options.pixel_format.empty() && !format_by_name(options.pixel_format))
    return make_error(impl->where, ": pixel_format '", options.pixel_format,
                      "' is not supported; expected one of ", supported_format_names());

  // An id or serial is looked up among discovered cameras; an address is connected to directly,
  // since discovery may not reach it (another subnet) and NULL picks the wrong interface.
  if (looks_like_ipv4(options.device)) {
    impl->connect_id = options.device;
  } else {
    const std::vector<DeviceEntry> found = discover();
    for (const DeviceEntry& d : found)
      if (d.id == options.device || d.serial == options.device) impl->connect_id = d.id;
    if (impl->connect_id.empty()) {
      std::string list;
      for (const DeviceEntry& d : found) list += (list.empty() ? "" : ", ") + d.id + " (" + d.address + ")";
      return make_error(impl->where, ": no camera with this id or serial; found ",
                        list.empty() ? std::string("none") : list);
    }
  }
  // A free-running camera starts at the first read(); a triggered one at once (it sends nothing
  // until triggered, and a software trigger may come from another thread before any read()).
  if (Status s = impl->connect(/*start=*/options.trigger != TriggerMode::kFreeRun); !s) {
    impl->teardown();
    return s.error();
  }
  impl->connected = true;
  impl->last_activity_ns = monotonic_now_ns() + kFirstFrameGraceNs;
  {
    std::lock_guard lock(impl->mutex);
    impl->health.message = std::string(to_string(options.camera)) + " camera streaming";
  }
  return std::unique_ptr<AravisSource>(new AravisSource(std::move(impl)));
}

std::string AravisSource::uri() const {
  return "aravis://" + impl_->options.device;
}

Expected<ReadStatus> AravisSource::read(Frame& out, std::chrono::nanoseconds timeout) {
  Impl& m = *impl_;
  const TimestampNs deadline = monotonic_now_ns() + timeout.count();
  for (;;) {
    const TimestampNs now = monotonic_now_ns();
    if (!m.connected) {
      if (m.options.reconnect && now >= m.next_attempt_ns) {
        if (!m.worth_connecting()) {
          m.next_attempt_ns = monotonic_now_ns() + m.options.reconnect_period.count();
        } else if (Status s = m.connect(/*start=*/true); s) {
          m.connected = true;
          m.last_activity_ns = monotonic_now_ns() + kFirstFrameGraceNs;
          std::lock_guard lock(m.mutex);
          m.stats.reconnects++;
          m.health.connected = true;
          m.health.reconnects = m.stats.reconnects;
          m.health.message = std::string(to_string(m.options.camera)) + " camera reconnected after " +
                             std::to_string((monotonic_now_ns() - m.lost_since_ns) / 1'000'000) + " ms";
          continue;
        } else {
          m.teardown(/*device_gone=*/true);
          m.next_attempt_ns = monotonic_now_ns() + m.options.reconnect_period.count();
        }
      }
      const TimestampNs after = monotonic_now_ns();
      if (after >= deadline) return ReadStatus::kTimeout;
      const TimestampNs wake = m.options.reconnect ? std::min(deadline, m.next_attempt_ns) : deadline;
      std::this_thread::sleep_for(std::chrono::nanoseconds(std::max<TimestampNs>(wake - after, 1'000'000)));
      continue;
    }

    if (!m.acquiring)
      if (Status s = m.start_acquisition(); !s) return s.error();

    // Pop in short slices, so a stall is noticed while the caller waits.
    const TimestampNs slice_ns = std::clamp<TimestampNs>(deadline - now, 0, 50'000'000);
    ArvBuffer* buffer = arv_stream_timeout_pop_buffer(m.stream.get(), static_cast<guint64>(slice_ns / 1000));
    const TimestampNs t_host = monotonic_now_ns();
    if (!buffer) {
      if (m.control_lost.load()) {
        m.declare_lost("control channel lost (no heartbeat reply)", t_host);
        continue;
      }
      // Free-running cameras must deliver; a triggered one only after a trigger we sent.
      const TimestampNs since =
          m.options.trigger == TriggerMode::kFreeRun ? m.last_activity_ns : m.trigger_pending_since_ns.load();
      if (since > 0 && t_host - since > m.stall_limit().count()) {
        m.declare_lost("no frame for " + std::to_string((t_host - since) / 1'000'000) + " ms", t_host);
        continue;
      }
      if (t_host >= deadline) {
        m.update_stream_counters();
        return ReadStatus::kTimeout;
      }
      continue;
    }
    m.last_activity_ns = t_host;
    m.trigger_pending_since_ns = 0;
    if (arv_buffer_get_status(buffer) != ARV_BUFFER_STATUS_SUCCESS) {
      // Incomplete or failed block: the frame is lost in transport.
      arv_stream_push_buffer(m.stream.get(), buffer);
      m.transport_lost_since_good++;
      std::lock_guard lock(m.mutex);
      m.stats.transport_drops++;
      continue;
    }
    size_t size = 0;
    const auto* data = static_cast<const std::uint8_t*>(arv_buffer_get_image_data(buffer, &size));
    const FormatMap* fm = format_by_arv(arv_buffer_get_image_pixel_format(buffer));
    const int w = arv_buffer_get_image_width(buffer), h = arv_buffer_get_image_height(buffer);
    const bool ok = fm && data && convert(*fm, data, size, w, h, out.image);
    const std::uint64_t id = arv_buffer_get_frame_id(buffer);
    const TimestampNs t_device = static_cast<TimestampNs>(arv_buffer_get_timestamp(buffer));
    arv_stream_push_buffer(m.stream.get(), buffer);
    if (!ok) {
      m.transport_lost_since_good++;
      std::lock_guard lock(m.mutex);
      m.stats.transport_drops++;
      continue;
    }

    // Frame ids: 16-bit on GigE Vision 1.x, cycling 1..65535 (0 is never used); 64-bit otherwise.
    std::uint64_t gap = 0;
    if (m.have_last_id) {
      std::int64_t d = static_cast<std::int64_t>(id) - static_cast<std::int64_t>(m.last_id);
      if (d <= 0 && m.last_id <= 0xFFFF && m.last_id - id > 0x8000) d += 0xFFFF;
      if (d > 0) {
        gap = static_cast<std::uint64_t>(d - 1);
        gap -= std::min(gap, m.transport_lost_since_good);
        m.sequence += static_cast<std::uint64_t>(d);
      } else {
        m.sequence += 1;  // the camera restarted its count
      }
    } else {
      m.sequence = m.stats.frames == 0 ? id : m.sequence + 1;
    }
    m.have_last_id = true;
    m.last_id = id;
    m.transport_lost_since_good = 0;

    out.sequence = m.sequence;
    out.camera = m.options.camera;
    out.exposure_ns = m.exposure_ns;
    out.t_host_ns = t_host;
    if (t_device != 0) {
      out.clock = ClockDomain::kDevice;
      out.t_ns = t_device + (m.options.timestamp_at_exposure_start ? m.exposure_ns / 2 : 0);
    } else {
      // No device timestamp (some USB cameras): the arrival time is the best there is.
      out.clock = ClockDomain::kHostMonotonic;
      out.t_ns = t_host;
    }
    // Aravis' own counters (missing packets, resends, underruns), refreshed a few times a second.
    if (t_host - m.counters_read_ns > 250'000'000) {
      m.counters_read_ns = t_host;
      m.update_stream_counters();
    }
    std::lock_guard lock(m.mutex);
    m.stats.frames++;
    m.stats.camera_drops += gap;
    return ReadStatus::kFrame;
  }
}

std::uint64_t AravisSource::frames_dropped() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stats.camera_drops + impl_->stats.transport_drops;
}

SourceHealth AravisSource::health() const {
  std::lock_guard lock(impl_->mutex);
  SourceHealth h = impl_->health;
  h.camera_drops = impl_->stats.camera_drops;
  h.transport_drops = impl_->stats.transport_drops;
  return h;
}

AravisStats AravisSource::stats() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->stats;
}

std::string AravisSource::settings() const {
  const AravisCameraInfo i = info();
  char b[160];
  std::snprintf(b, sizeof b, "%dx%d %s", i.width, i.height, i.pixel_format.c_str());
  std::string s = b;
  if (i.frame_rate_hz > 0) {
    std::snprintf(b, sizeof b, " at %.3g fps", i.frame_rate_hz);
    s += b;
  } else {
    s += ", triggered";
  }
  if (i.exposure_us > 0) {
    std::snprintf(b, sizeof b, ", exposure %.1f us", i.exposure_us);
    s += b;
  }
  if (i.packet_size > 0) s += ", GVSP packets " + std::to_string(i.packet_size) + " B";
  s += i.ptp ? ", PTP on" : ", PTP off";
  s += ", serial " + i.serial + (i.address.empty() ? "" : " at " + i.address);
  for (const std::string& n : i.notes) s += "; " + n;
  return s;
}

AravisCameraInfo AravisSource::info() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->info;
}

Status AravisSource::software_trigger() {
  Impl& m = *impl_;
  if (m.options.trigger != TriggerMode::kSoftware)
    return make_error(m.where, ": software_trigger() needs trigger mode software");
  if (!m.connected) return make_error(m.where, ": camera not connected");
  GError* e = nullptr;
  arv_camera_software_trigger(m.camera.get(), &e);
  if (e) return take_error(e, m.where, "software trigger");
  if (m.trigger_pending_since_ns == 0) m.trigger_pending_since_ns = monotonic_now_ns();
  return {};
}

}  // namespace augrig
