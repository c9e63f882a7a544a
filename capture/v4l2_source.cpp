#include "capture/v4l2_source.hpp"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstring>
#include <ctime>
#include <numeric>
#include <system_error>
#include <utility>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>
#include <turbojpeg.h>

#include "core/clock.hpp"

namespace augrig {
namespace {

constexpr std::uint32_t kCaptureType = V4L2_BUF_TYPE_VIDEO_CAPTURE;
// Enumerations stop here even if a (buggy) driver never answers EINVAL.
constexpr std::uint32_t kMaxEnumerated = 1024;
constexpr std::int64_t kNsPer100Us = 100'000;  // V4L2_CID_EXPOSURE_ABSOLUTE's unit

// "ENODEV (No such device)": the symbolic name helps when comparing with the kernel docs.
std::string errno_text(int e) {
  const char* name = nullptr;
  switch (e) {
    case EPERM:
      name = "EPERM";
      break;
    case ENOENT:
      name = "ENOENT";
      break;
    case EINTR:
      name = "EINTR";
      break;
    case EIO:
      name = "EIO";
      break;
    case ENXIO:
      name = "ENXIO";
      break;
    case EAGAIN:
      name = "EAGAIN";
      break;
    case ENOMEM:
      name = "ENOMEM";
      break;
    case EACCES:
      name = "EACCES";
      break;
    case EBUSY:
      name = "EBUSY";
      break;
    case ENODEV:
      name = "ENODEV";
      break;
    case EINVAL:
      name = "EINVAL";
      break;
    case ENOTTY:
      name = "ENOTTY";
      break;
    case ENOSPC:
      name = "ENOSPC";
      break;
    case EPIPE:
      name = "EPIPE";
      break;
    case ERANGE:
      name = "ERANGE";
      break;
    default:
      break;
  }
  const std::string text = std::error_code(e, std::generic_category()).message();
  return name ? std::string(name) + " (" + text + ")" : "errno " + std::to_string(e) + " (" + text + ")";
}

// A fixed-size, possibly unterminated char array from a V4L2 struct.
template <std::size_t N>
std::string field_string(const __u8 (&s)[N]) {
  const auto* p = reinterpret_cast<const char*>(s);
  return std::string(p, strnlen(p, N));
}

// Bytes one pixel takes in the V4L2 buffer (0: compressed).
int v4l2_bytes_per_pixel(std::uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_RGB24:
      return 3;
    case V4L2_PIX_FMT_YUYV:
      return 2;
    case V4L2_PIX_FMT_MJPEG:
      return 0;
    default:
      return 1;
  }
}

std::string size_text(std::uint32_t w, std::uint32_t h) {
  return std::to_string(w) + "x" + std::to_string(h);
}

std::string fourcc_list(const std::vector<std::uint32_t>& fourccs) {
  std::string s;
  for (std::uint32_t f : fourccs) s += (s.empty() ? "" : ", ") + fourcc_to_string(f);
  return s.empty() ? "none" : s;
}

std::uint8_t clamp_u8(int v) {
  return static_cast<std::uint8_t>(std::clamp(v, 0, 255));
}

// BT.601 limited range (Y 16..235, Cb/Cr 16..240) to full-range RGB, 16-bit fixed point:
//   R = 255/219 (Y-16) + 1.402 * 255/224 (Cr-128)
//   G = 255/219 (Y-16) - 0.344136 * 255/224 (Cb-128) - 0.714136 * 255/224 (Cr-128)
//   B = 255/219 (Y-16) + 1.772 * 255/224 (Cb-128)
constexpr int kFix = 16;
constexpr int fix(double c) {
  return static_cast<int>(c * (1 << kFix) + 0.5);
}
constexpr int kCy = fix(255.0 / 219.0);
constexpr int kCrR = fix(1.402 * 255.0 / 224.0);
constexpr int kCbG = fix(0.344136 * 255.0 / 224.0);
constexpr int kCrG = fix(0.714136 * 255.0 / 224.0);
constexpr int kCbB = fix(1.772 * 255.0 / 224.0);
constexpr int kHalf = 1 << (kFix - 1);

void yuyv_to_rgb(const std::uint8_t* src, std::size_t src_stride, Image& dst) {
  const int w = dst.width();
  for (int y = 0; y < dst.height(); ++y) {
    const std::uint8_t* s = src + static_cast<std::size_t>(y) * src_stride;
    std::uint8_t* d = dst.row(y);
    for (int x = 0; x < w; x += 2, s += 4) {  // Y0 Cb Y1 Cr: two pixels share the chroma
      const int cb = s[1] - 128;
      const int cr = s[3] - 128;
      const int r = kCrR * cr + kHalf;
      const int g = -kCbG * cb - kCrG * cr + kHalf;
      const int b = kCbB * cb + kHalf;
      for (int k = 0; k < 2 && x + k < w; ++k, d += 3) {
        const int yy = kCy * (s[2 * k] - 16);
        d[0] = clamp_u8((yy + r) >> kFix);  // C++20: >> of a negative int is an arithmetic shift
        d[1] = clamp_u8((yy + g) >> kFix);
        d[2] = clamp_u8((yy + b) >> kFix);
      }
    }
  }
}

struct ControlName {
  std::uint32_t id;
  const char* name;
};
constexpr ControlName kExposureAbsolute{V4L2_CID_EXPOSURE_ABSOLUTE, "V4L2_CID_EXPOSURE_ABSOLUTE (exposure)"};
constexpr ControlName kExposureAuto{V4L2_CID_EXPOSURE_AUTO, "V4L2_CID_EXPOSURE_AUTO (auto exposure)"};
constexpr ControlName kGain{V4L2_CID_GAIN, "V4L2_CID_GAIN (gain)"};
constexpr ControlName kAutogain{V4L2_CID_AUTOGAIN, "V4L2_CID_AUTOGAIN (auto gain)"};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Formats

std::string fourcc_to_string(std::uint32_t fourcc) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    s += (c >= 0x20 && c < 0x7f) ? c : '?';
  }
  if (fourcc & (1u << 31)) s.back() = '?';  // V4L2_PIX_FMT_FLAG_BE_REPRESENTATION: never a name
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

Expected<std::uint32_t> fourcc_from_string(std::string_view text) {
  if (text.empty() || text.size() > 4 ||
      !std::all_of(text.begin(), text.end(), [](char c) { return c > 0x20 && c < 0x7f; })) {
    return make_error(
        "fourcc_from_string(): '", std::string(text),
        "': expected a V4L2 fourcc of 1 to 4 printable characters, e.g. YUYV, MJPG, GREY, BA81");
  }
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    const auto c = static_cast<std::uint8_t>(i < text.size() ? text[i] : ' ');
    v |= static_cast<std::uint32_t>(c) << (8 * i);
  }
  return v;
}

std::optional<PixelFormat> v4l2_to_pixel_format(std::uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_GREY:
      return PixelFormat::kMono8;
    case V4L2_PIX_FMT_RGB24:
    case V4L2_PIX_FMT_YUYV:
    case V4L2_PIX_FMT_MJPEG:
      return PixelFormat::kRGB8;
    // V4L2 names Bayer formats by their first two rows, PixelFormat by the top-left 2x2 cell in
    // reading order: SBGGR8 is "B G / G R", i.e. BayerBG8.
    case V4L2_PIX_FMT_SBGGR8:
      return PixelFormat::kBayerBG8;
    case V4L2_PIX_FMT_SGBRG8:
      return PixelFormat::kBayerGB8;
    case V4L2_PIX_FMT_SGRBG8:
      return PixelFormat::kBayerGR8;
    case V4L2_PIX_FMT_SRGGB8:
      return PixelFormat::kBayerRG8;
    default:
      return std::nullopt;
  }
}

const std::vector<std::uint32_t>& default_v4l2_format_preference() {
  static const std::vector<std::uint32_t> kPreference = {
      V4L2_PIX_FMT_SBGGR8, V4L2_PIX_FMT_SGBRG8, V4L2_PIX_FMT_SGRBG8, V4L2_PIX_FMT_SRGGB8,
      V4L2_PIX_FMT_RGB24,  V4L2_PIX_FMT_YUYV,   V4L2_PIX_FMT_GREY,   V4L2_PIX_FMT_MJPEG};
  return kPreference;
}

// ---------------------------------------------------------------------------------------------
// V4l2Source: opening

V4l2Source::V4l2Source(const V4l2Options& options, V4l2Io& io) : options_(options), io_(io) {}

V4l2Source::~V4l2Source() {
  // Errors are ignored here: a device that was unplugged answers ENODEV to all of it, and the
  // kernel frees the buffers once they are unmapped and the descriptor is closed anyway.
  if (streaming_) {
    int type = kCaptureType;
    xioctl(io_, fd_, VIDIOC_STREAMOFF, &type);
  }
  for (const Buffer& b : buffers_) io_.munmap(b.data, b.length);
  if (buffers_requested_) {
    v4l2_requestbuffers req{};
    req.count = 0;
    req.type = kCaptureType;
    req.memory = V4L2_MEMORY_MMAP;
    xioctl(io_, fd_, VIDIOC_REQBUFS, &req);
  }
  if (fd_ >= 0) io_.close(fd_);
  if (jpeg_ != nullptr) tjDestroy(jpeg_);
}

Error V4l2Source::device_error(const char* function, const std::string& what) const {
  return make_error("V4l2Source::", function, "(): ", options_.device_path, ": ", what);
}

std::string V4l2Source::settings() const {
  const V4l2StreamInfo& i = info_;
  char b[160];
  std::snprintf(b, sizeof b, "%dx%d %s (%s)", i.width_px, i.height_px, fourcc_to_string(i.fourcc).c_str(),
                std::string(to_string(i.pixel_format)).c_str());
  std::string s = b;
  if (i.frame_rate_hz > 0) {
    std::snprintf(b, sizeof b, " at %.3g fps", i.frame_rate_hz);
    s += b;
  }
  if (i.exposure_ns > 0) {
    std::snprintf(b, sizeof b, ", exposure %.1f us", static_cast<double>(i.exposure_ns) / 1e3);
    s += b;
  }
  if (i.gain) s += ", gain " + std::to_string(*i.gain);
  s += ", " + std::to_string(i.buffer_count) + " buffers, " + i.card + " (" + i.driver + ")";
  for (const std::string& n : i.notes) s += "; " + n;
  return s;
}

Expected<std::unique_ptr<V4l2Source>> V4l2Source::open(const V4l2Options& options, V4l2Io& io) {
  auto bad = [&](const std::string& what) {
    return make_error("V4l2Source::open(): ", options.device_path.empty() ? "(no path)" : options.device_path,
                      ": ", what);
  };
  if (options.device_path.empty()) return bad("expected a device path such as /dev/video0");
  if (options.buffer_count < 2) {
    return bad("buffer_count " + std::to_string(options.buffer_count) +
               ": expected at least 2 (one filling while one is read)");
  }
  if (options.width_px < 0 || options.height_px < 0) {
    return bad("expected a size of 0 (keep) or more pixels, got " + std::to_string(options.width_px) + "x" +
               std::to_string(options.height_px));
  }
  if (!std::isfinite(options.frame_rate_hz) || options.frame_rate_hz < 0) {
    return bad("frame_rate_hz " + std::to_string(options.frame_rate_hz) +
               ": expected 0 (keep) or a rate > 0");
  }
  if (options.exposure_ns && *options.exposure_ns <= 0) {
    return bad("exposure_ns " + std::to_string(*options.exposure_ns) + ": expected a positive exposure");
  }
  for (std::uint32_t f : options.pixel_formats) {
    if (!v4l2_to_pixel_format(f)) {
      return bad("pixel format " + fourcc_to_string(f) + " is not one augrig reads (it reads " +
                 fourcc_list(default_v4l2_format_preference()) + ")");
    }
  }
  std::unique_ptr<V4l2Source> source(new V4l2Source(options, io));
  if (Status s = source->start(); !s) return s.error();
  return source;
}

Status V4l2Source::start() {
  fd_ = io_.open(options_.device_path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int e = errno;
    std::string hint;
    if (e == ENOENT || e == ENODEV || e == ENXIO)
      hint = " (is the camera plugged in? `augrig cameras` lists them)";
    if (e == EACCES || e == EPERM) hint = " (is the user in the 'video' group?)";
    return device_error("open", "cannot open: " + errno_text(e) + hint);
  }

  v4l2_capability cap{};
  if (xioctl(io_, fd_, VIDIOC_QUERYCAP, &cap) != 0) {
    return device_error("open", "VIDIOC_QUERYCAP failed: " + errno_text(errno) + "; not a V4L2 device?");
  }
  info_.driver = field_string(cap.driver);
  info_.card = field_string(cap.card);
  info_.bus_info = field_string(cap.bus_info);
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
    if (caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) {
      return device_error(
          "open",
          "'" + info_.card + "' captures only through the multi-planar API, which augrig does not support");
    }
    return device_error("open",
                        "'" + info_.card + "' is not a video capture device (no V4L2_CAP_VIDEO_CAPTURE)");
  }
  if (!(caps & V4L2_CAP_STREAMING)) {
    return device_error(
        "open",
        "'" + info_.card + "' has no streaming I/O (V4L2_CAP_STREAMING); read() I/O is not supported");
  }

  if (Status s = negotiate_format(); !s) return s;
  if (Status s = set_frame_rate(); !s) return s;
  if (Status s = set_controls(); !s) return s;
  if (info_.fourcc == V4L2_PIX_FMT_MJPEG) {
    jpeg_ = tjInitDecompress();
    if (jpeg_ == nullptr)
      return device_error("open", std::string("cannot create a JPEG decoder: ") + tjGetErrorStr2(nullptr));
  }
  return map_buffers_and_stream();
}

Status V4l2Source::negotiate_format() {
  std::vector<std::uint32_t> offered;
  for (std::uint32_t i = 0; i < kMaxEnumerated; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = kCaptureType;
    if (xioctl(io_, fd_, VIDIOC_ENUM_FMT, &desc) != 0) {
      if (errno == EINVAL) break;  // end of the list
      return device_error("open", "VIDIOC_ENUM_FMT failed: " + errno_text(errno));
    }
    offered.push_back(desc.pixelformat);
  }
  const std::vector<std::uint32_t>& wanted =
      options_.pixel_formats.empty() ? default_v4l2_format_preference() : options_.pixel_formats;
  std::uint32_t chosen = 0;
  for (std::uint32_t f : wanted) {
    if (std::find(offered.begin(), offered.end(), f) != offered.end()) {
      chosen = f;
      break;
    }
  }
  if (chosen == 0) {
    return device_error("open", "'" + info_.card + "' offers the pixel formats " + fourcc_list(offered) +
                                    "; none of the wanted " + fourcc_list(wanted));
  }

  v4l2_format fmt{};
  fmt.type = kCaptureType;
  if (xioctl(io_, fd_, VIDIOC_G_FMT, &fmt) != 0) {
    return device_error("open", "VIDIOC_G_FMT failed: " + errno_text(errno));
  }
  fmt.fmt.pix.pixelformat = chosen;
  if (options_.width_px > 0) fmt.fmt.pix.width = static_cast<std::uint32_t>(options_.width_px);
  if (options_.height_px > 0) fmt.fmt.pix.height = static_cast<std::uint32_t>(options_.height_px);
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  fmt.fmt.pix.bytesperline = 0;  // let the driver choose its stride
  fmt.fmt.pix.sizeimage = 0;
  const std::string wanted_size = size_text(fmt.fmt.pix.width, fmt.fmt.pix.height);
  if (xioctl(io_, fd_, VIDIOC_S_FMT, &fmt) != 0) {
    const int e = errno;
    return device_error("open", "VIDIOC_S_FMT " + fourcc_to_string(chosen) + " " + wanted_size +
                                    " failed: " + errno_text(e) +
                                    (e == EBUSY ? " (another program is using the device?)" : ""));
  }
  // Read back what the driver actually set up.
  fmt = v4l2_format{};
  fmt.type = kCaptureType;
  if (xioctl(io_, fd_, VIDIOC_G_FMT, &fmt) != 0) {
    return device_error("open", "VIDIOC_G_FMT failed: " + errno_text(errno));
  }
  const v4l2_pix_format& pix = fmt.fmt.pix;
  if (pix.pixelformat != chosen) {
    return device_error("open", "the driver substituted the pixel format " +
                                    fourcc_to_string(pix.pixelformat) + " for the requested " +
                                    fourcc_to_string(chosen));
  }
  if (pix.field != V4L2_FIELD_NONE) {
    return device_error("open", "the driver set field order " + std::to_string(pix.field) +
                                    "; only progressive frames (V4L2_FIELD_NONE) are supported");
  }
  if (pix.width == 0 || pix.height == 0 || pix.width > 65535 || pix.height > 65535) {
    return device_error("open", "the driver set an unusable size " + size_text(pix.width, pix.height));
  }
  const std::string got_size = size_text(pix.width, pix.height);
  if ((options_.width_px > 0 && pix.width != static_cast<std::uint32_t>(options_.width_px)) ||
      (options_.height_px > 0 && pix.height != static_cast<std::uint32_t>(options_.height_px))) {
    info_.notes.push_back("the driver adjusted the size from " + wanted_size + " to " + got_size);
  }
  info_.fourcc = chosen;
  info_.pixel_format = *v4l2_to_pixel_format(chosen);
  info_.width_px = static_cast<int>(pix.width);
  info_.height_px = static_cast<int>(pix.height);
  info_.bytes_per_line = pix.bytesperline;
  info_.size_image = pix.sizeimage;
  const int bpp = v4l2_bytes_per_pixel(chosen);
  if (bpp > 0) {
    const std::uint32_t tight = pix.width * static_cast<std::uint32_t>(bpp);
    if (info_.bytes_per_line == 0) info_.bytes_per_line = tight;  // older drivers leave it 0
    if (info_.bytes_per_line < tight) {
      return device_error("open", "bytesperline " + std::to_string(pix.bytesperline) + " is less than the " +
                                      std::to_string(tight) + " bytes a " + got_size + " " +
                                      fourcc_to_string(chosen) + " row needs");
    }
    const std::uint64_t need = static_cast<std::uint64_t>(info_.bytes_per_line) * (pix.height - 1) + tight;
    if (info_.size_image < need) {
      if (info_.size_image != 0) {
        return device_error("open", "sizeimage " + std::to_string(pix.sizeimage) + " is less than the " +
                                        std::to_string(need) + " bytes a " + got_size + " image needs");
      }
      info_.size_image =
          static_cast<std::uint32_t>(static_cast<std::uint64_t>(info_.bytes_per_line) * pix.height);
    }
  } else if (info_.size_image == 0) {
    return device_error("open", "the driver reports sizeimage 0 for " + fourcc_to_string(chosen));
  }
  return {};
}

Status V4l2Source::set_frame_rate() {
  v4l2_streamparm parm{};
  parm.type = kCaptureType;
  const bool have_parm = xioctl(io_, fd_, VIDIOC_G_PARM, &parm) == 0;
  const int parm_errno = errno;
  const bool settable = have_parm && (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME);
  auto rate_of = [](const v4l2_fract& f) {
    return f.numerator > 0 ? static_cast<double>(f.denominator) / f.numerator : 0.0;
  };
  if (settable) info_.frame_rate_hz = rate_of(parm.parm.capture.timeperframe);
  if (options_.frame_rate_hz <= 0) return {};
  if (!settable) {
    return device_error("open",
                        "cannot set the frame rate to " + std::to_string(options_.frame_rate_hz) +
                            " Hz: the device " +
                            (have_parm ? std::string("has no V4L2_CAP_TIMEPERFRAME")
                                       : "does not answer VIDIOC_G_PARM (" + errno_text(parm_errno) + ")"));
  }
  // Frame period as a fraction, to a millihertz.
  std::uint32_t num = 1000;
  auto den = static_cast<std::uint32_t>(std::llround(options_.frame_rate_hz * 1000.0));
  if (den == 0)
    return device_error("open", "frame rate " + std::to_string(options_.frame_rate_hz) + " Hz is too low");
  const std::uint32_t g = std::gcd(num, den);
  num /= g;
  den /= g;
  parm = v4l2_streamparm{};
  parm.type = kCaptureType;
  parm.parm.capture.timeperframe = {num, den};
  if (xioctl(io_, fd_, VIDIOC_S_PARM, &parm) != 0) {
    return device_error("open", "VIDIOC_S_PARM (" + std::to_string(options_.frame_rate_hz) +
                                    " Hz) failed: " + errno_text(errno));
  }
  info_.frame_rate_hz = rate_of(parm.parm.capture.timeperframe);
  if (std::abs(info_.frame_rate_hz - options_.frame_rate_hz) > 1e-3 * options_.frame_rate_hz) {
    info_.notes.push_back("the driver set the frame rate to " + std::to_string(info_.frame_rate_hz) +
                          " Hz instead of " + std::to_string(options_.frame_rate_hz) + " Hz");
  }
  return {};
}

Status V4l2Source::set_controls() {
  // A control the device lacks, or has disabled, is an error: the operator asked for it.
  auto query = [&](const ControlName& c, v4l2_queryctrl& q) -> Status {
    q = v4l2_queryctrl{};
    q.id = c.id;
    if (xioctl(io_, fd_, VIDIOC_QUERYCTRL, &q) != 0) {
      if (errno == EINVAL) return device_error("open", std::string("the device has no control ") + c.name);
      return device_error("open",
                          std::string("VIDIOC_QUERYCTRL ") + c.name + " failed: " + errno_text(errno));
    }
    if (q.flags & V4L2_CTRL_FLAG_DISABLED)
      return device_error("open", std::string("the control ") + c.name + " is disabled");
    if (q.flags & V4L2_CTRL_FLAG_READ_ONLY)
      return device_error("open", std::string("the control ") + c.name + " is read-only");
    return {};
  };
  auto has = [&](const ControlName& c) {
    v4l2_queryctrl q{};
    q.id = c.id;
    return xioctl(io_, fd_, VIDIOC_QUERYCTRL, &q) == 0 &&
           !(q.flags & (V4L2_CTRL_FLAG_DISABLED | V4L2_CTRL_FLAG_READ_ONLY));
  };
  // Sets and reads back (the driver may round to its step).
  auto set = [&](const ControlName& c, std::int32_t value, std::int32_t& actual) -> Status {
    v4l2_control ctrl{};
    ctrl.id = c.id;
    ctrl.value = value;
    if (xioctl(io_, fd_, VIDIOC_S_CTRL, &ctrl) != 0) {
      const int e = errno;
      return device_error("open",
                          std::string("setting ") + c.name + " to " + std::to_string(value) +
                              " failed: " + errno_text(e) +
                              (e == ERANGE   ? " (out of the device's range)"
                               : e == EACCES ? " (read-only, or inactive while an automatic mode is on)"
                                             : ""));
    }
    ctrl = v4l2_control{};
    ctrl.id = c.id;
    if (xioctl(io_, fd_, VIDIOC_G_CTRL, &ctrl) != 0) {
      return device_error("open", std::string("reading back ") + c.name + " failed: " + errno_text(errno));
    }
    actual = ctrl.value;
    return {};
  };
  auto range_check = [&](const ControlName& c, const v4l2_queryctrl& q, std::int64_t v,
                         const std::string& what) -> Status {
    if (v < q.minimum || v > q.maximum) {
      return device_error("open", what + " is outside the range [" + std::to_string(q.minimum) + ", " +
                                      std::to_string(q.maximum) + "] of " + c.name);
    }
    return {};
  };

  if (options_.exposure_ns) {
    v4l2_queryctrl q{};
    if (Status s = query(kExposureAbsolute, q); !s) return s;
    const std::int64_t units = std::llround(static_cast<double>(*options_.exposure_ns) / kNsPer100Us);
    const std::string what =
        "exposure " + std::to_string(*options_.exposure_ns) + " ns (" + std::to_string(units) + " x 100 us)";
    if (Status s = range_check(kExposureAbsolute, q, units, what); !s) return s;
    // Manual mode first: drivers may refuse (EACCES) to set an exposure that auto exposure owns.
    if (has(kExposureAuto)) {
      std::int32_t mode = 0;
      if (Status s = set(kExposureAuto, V4L2_EXPOSURE_MANUAL, mode); !s) return s;
    }
    std::int32_t actual = 0;
    if (Status s = set(kExposureAbsolute, static_cast<std::int32_t>(units), actual); !s) return s;
    info_.exposure_ns = static_cast<std::int64_t>(actual) * kNsPer100Us;
    if (info_.exposure_ns != *options_.exposure_ns) {
      info_.notes.push_back("exposure is " + std::to_string(info_.exposure_ns) + " ns (requested " +
                            std::to_string(*options_.exposure_ns) + " ns; the device counts 100 us units)");
    }
  }
  if (options_.gain) {
    v4l2_queryctrl q{};
    if (Status s = query(kGain, q); !s) return s;
    if (Status s = range_check(kGain, q, *options_.gain, "gain " + std::to_string(*options_.gain)); !s)
      return s;
    if (has(kAutogain)) {
      std::int32_t off = 0;
      if (Status s = set(kAutogain, 0, off); !s) return s;
    }
    std::int32_t actual = 0;
    if (Status s = set(kGain, *options_.gain, actual); !s) return s;
    info_.gain = actual;
    if (actual != *options_.gain) {
      info_.notes.push_back("gain is " + std::to_string(actual) + " (requested " +
                            std::to_string(*options_.gain) + ")");
    }
  }
  return {};
}

Status V4l2Source::map_buffers_and_stream() {
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(options_.buffer_count);
  req.type = kCaptureType;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(io_, fd_, VIDIOC_REQBUFS, &req) != 0) {
    const int e = errno;
    return device_error("open", "VIDIOC_REQBUFS (" + std::to_string(options_.buffer_count) +
                                    " mmap buffers) failed: " + errno_text(e) +
                                    (e == EINVAL  ? " (no mmap streaming?)"
                                     : e == EBUSY ? " (another program is streaming from it?)"
                                                  : ""));
  }
  buffers_requested_ = true;
  if (req.count == 0) return device_error("open", "the driver granted no buffers");
  info_.buffer_count = req.count;
  if (req.count != static_cast<std::uint32_t>(options_.buffer_count)) {
    info_.notes.push_back("the driver granted " + std::to_string(req.count) + " buffers (requested " +
                          std::to_string(options_.buffer_count) + ")");
  }
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.index = i;
    buf.type = kCaptureType;
    buf.memory = V4L2_MEMORY_MMAP;
    if (xioctl(io_, fd_, VIDIOC_QUERYBUF, &buf) != 0) {
      return device_error("open", "VIDIOC_QUERYBUF " + std::to_string(i) + " failed: " + errno_text(errno));
    }
    void* p = io_.mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
    if (p == MAP_FAILED) {
      return device_error("open", "mmap of buffer " + std::to_string(i) + " (" + std::to_string(buf.length) +
                                      " bytes) failed: " + errno_text(errno));
    }
    buffers_.push_back({p, buf.length});
  }
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.index = i;
    buf.type = kCaptureType;
    buf.memory = V4L2_MEMORY_MMAP;
    if (xioctl(io_, fd_, VIDIOC_QBUF, &buf) != 0) {
      return device_error("open", "VIDIOC_QBUF " + std::to_string(i) + " failed: " + errno_text(errno));
    }
  }
  return options_.stream_at_open ? stream_on("open") : Status{};
}

Status V4l2Source::stream_on(const char* where) {
  int type = kCaptureType;
  if (xioctl(io_, fd_, VIDIOC_STREAMON, &type) != 0) {
    return device_error(where, "VIDIOC_STREAMON failed: " + errno_text(errno));
  }
  streaming_ = true;
  return {};
}

// ---------------------------------------------------------------------------------------------
// V4l2Source: streaming

std::uint64_t V4l2Source::frames_dropped() const {
  return stats_.sequence_gap_frames + stats_.error_buffers + stats_.decode_failures + stats_.short_buffers;
}

SourceHealth V4l2Source::health() const {
  SourceHealth h;
  h.connected = !failed_.has_value();
  if (failed_) {
    h.message = failed_->message;
    h.disconnects = 1;
  }
  h.camera_drops = stats_.sequence_gap_frames;
  h.transport_drops = stats_.error_buffers + stats_.decode_failures + stats_.short_buffers;
  return h;
}

void V4l2Source::drop(std::uint64_t& counter, std::string reason) {
  ++counter;
  stats_.last_drop_reason = std::move(reason);
}

bool V4l2Source::convert(const v4l2_buffer& buf, Frame& out) {
  // Sequence numbers are 32-bit and wrap; Frame::sequence keeps counting across wraps.
  const std::uint32_t seq = buf.sequence;
  if (last_sequence_) {
    const std::uint32_t delta = seq - *last_sequence_;
    if (delta == 0 || delta > 0x8000'0000u) {
      ++stats_.sequence_regressions;  // a restart or a driver bug, not a loss we can count
      if (seq > *last_sequence_ && sequence_ >> 32 != 0) sequence_ -= std::uint64_t{1} << 32;
    } else {
      stats_.sequence_gap_frames += delta - 1;
      if (seq < *last_sequence_) sequence_ += std::uint64_t{1} << 32;  // wrapped
    }
  }
  sequence_ = (sequence_ & ~std::uint64_t{0xffff'ffff}) | seq;
  last_sequence_ = seq;
  const std::string which = "buffer " + std::to_string(buf.index) + " sequence " + std::to_string(seq);

  if (buf.flags & V4L2_BUF_FLAG_ERROR) {
    drop(stats_.error_buffers, which + ": the driver flagged it V4L2_BUF_FLAG_ERROR");
    return false;
  }
  const Buffer& mem = buffers_[buf.index];
  const std::size_t used = std::min<std::size_t>(buf.bytesused, mem.length);
  const auto* src = static_cast<const std::uint8_t*>(mem.data);
  const int w = info_.width_px;
  const int h = info_.height_px;
  if (work_.width() != w || work_.height() != h || work_.format() != info_.pixel_format) {
    work_ = Image(w, h, info_.pixel_format);
  }

  if (info_.fourcc == V4L2_PIX_FMT_MJPEG) {
    if (used == 0) {
      drop(stats_.short_buffers, which + ": empty MJPEG buffer");
      return false;
    }
    int jw = 0, jh = 0, subsamp = 0, colorspace = 0;
    if (tjDecompressHeader3(jpeg_, src, used, &jw, &jh, &subsamp, &colorspace) != 0) {
      drop(stats_.decode_failures, which + ": corrupt MJPEG (" + tjGetErrorStr2(jpeg_) + ")");
      return false;
    }
    if (jw != w || jh != h) {
      drop(stats_.decode_failures,
           which + ": MJPEG image is " + size_text(jw, jh) + ", the stream " + size_text(w, h));
      return false;
    }
    if (tjDecompress2(jpeg_, src, used, work_.data(), w, static_cast<int>(work_.stride_bytes()), h, TJPF_RGB,
                      0) != 0) {
      const bool warning = tjGetErrorCode(jpeg_) == TJERR_WARNING;
      if (!warning || !options_.keep_mjpeg_frames_with_warnings) {
        drop(stats_.decode_failures, which + ": corrupt MJPEG (" + tjGetErrorStr2(jpeg_) + ")");
        return false;
      }
      ++stats_.mjpeg_warnings_kept;
    }
  } else {
    const std::size_t bpl = info_.bytes_per_line;
    const std::size_t row_bytes = static_cast<std::size_t>(w) * v4l2_bytes_per_pixel(info_.fourcc);
    const std::size_t need = bpl * static_cast<std::size_t>(h - 1) + row_bytes;
    if (used < need) {
      drop(stats_.short_buffers, which + ": " + std::to_string(buf.bytesused) + " bytes, a " +
                                     size_text(w, h) + " " + fourcc_to_string(info_.fourcc) +
                                     " image needs " + std::to_string(need));
      return false;
    }
    if (info_.fourcc == V4L2_PIX_FMT_YUYV) {
      yuyv_to_rgb(src, bpl, work_);
    } else {
      for (int y = 0; y < h; ++y) std::memcpy(work_.row(y), src + bpl * y, row_bytes);
    }
  }

  TimestampNs t_ns = static_cast<TimestampNs>(buf.timestamp.tv_sec) * 1'000'000'000 +
                     static_cast<TimestampNs>(buf.timestamp.tv_usec) * 1000;
  // A start-of-exposure timestamp moves to mid-exposure when the exposure is known; end-of-frame
  // timestamps stay as they are (the readout time is not known). docs/V4L2.md says more.
  if ((buf.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_SOE && info_.exposure_ns > 0) {
    t_ns += info_.exposure_ns / 2;
  }
  ClockDomain clock = ClockDomain::kHostMonotonic;
  if ((buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
    clock = ClockDomain::kUnknown;  // e.g. TIMESTAMP_UNKNOWN drivers that stamp with gettimeofday()
    ++stats_.unknown_clock_frames;
  }
  if (last_t_ns_ && last_clock_ == clock && t_ns <= *last_t_ns_) ++stats_.non_monotonic_timestamps;
  last_t_ns_ = t_ns;
  last_clock_ = clock;

  std::swap(out.image, work_);
  out.t_ns = t_ns;
  out.clock = clock;
  out.t_host_ns = monotonic_now_ns();
  out.sequence = sequence_;
  out.camera = options_.camera;
  out.exposure_ns = info_.exposure_ns;
  ++stats_.frames_delivered;
  return true;
}

Expected<ReadStatus> V4l2Source::read(Frame& out, std::chrono::nanoseconds timeout) {
  if (failed_) return *failed_;
  // The buffers were queued at open(); the device captures from the first read on.
  if (!streaming_) {
    if (Status s = stream_on("read"); !s) {
      failed_ = s.error();
      return *failed_;
    }
  }
  auto fail = [&](const std::string& what) -> Error {
    failed_ = device_error("read", what);
    return *failed_;
  };
  const auto deadline = std::chrono::steady_clock::now() + std::max(timeout, std::chrono::nanoseconds(0));
  bool poll_error = false;
  for (;;) {
    v4l2_buffer buf{};
    buf.type = kCaptureType;
    buf.memory = V4L2_MEMORY_MMAP;
    if (xioctl(io_, fd_, VIDIOC_DQBUF, &buf) == 0) {
      if (buf.index >= buffers_.size()) {
        return fail("VIDIOC_DQBUF returned buffer index " + std::to_string(buf.index) + " of " +
                    std::to_string(buffers_.size()));
      }
      const bool delivered = convert(buf, out);
      // Give the buffer back to the driver whatever happened to its frame.
      v4l2_buffer again{};
      again.index = buf.index;
      again.type = kCaptureType;
      again.memory = V4L2_MEMORY_MMAP;
      if (xioctl(io_, fd_, VIDIOC_QBUF, &again) != 0) {
        const int e = errno;
        return fail((e == ENODEV ? "device disconnected (VIDIOC_QBUF: " : "VIDIOC_QBUF failed (") +
                    errno_text(e) + ")");
      }
      if (delivered) return ReadStatus::kFrame;
      poll_error = false;
      continue;  // dropped and counted: wait for the next one within the same timeout
    }
    const int e = errno;
    if (e == ENODEV) return fail("device disconnected (VIDIOC_DQBUF: " + errno_text(e) + ")");
    if (e == EIO)
      return fail("the driver reported an unrecoverable streaming error (VIDIOC_DQBUF: " + errno_text(e) +
                  ")");
    if (e != EAGAIN) return fail("VIDIOC_DQBUF failed: " + errno_text(e));
    if (poll_error)
      return fail("poll() reported an error or hang-up on the device (disconnected or stopped streaming)");

    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) return ReadStatus::kTimeout;
    // Round up so a sub-millisecond remainder waits instead of spinning.
    const auto left_ms = std::chrono::ceil<std::chrono::milliseconds>(deadline - now).count();
    pollfd p{fd_, POLLIN, 0};
    const int r = io_.poll(&p, 1, static_cast<int>(std::min<std::int64_t>(left_ms, INT_MAX)));
    if (r < 0) {
      if (errno == EINTR) continue;
      return fail("poll() failed: " + errno_text(errno));
    }
    // POLLERR: the V4L2 core after the device was unregistered (with POLLHUP), or videobuf2 when
    // the queue failed. DQBUF once more to learn which, then fail.
    if (r > 0 && (p.revents & (POLLERR | POLLHUP | POLLNVAL))) poll_error = true;
  }
}

// ---------------------------------------------------------------------------------------------
// Listing

Expected<std::vector<V4l2DeviceInfo>> list_v4l2_devices(V4l2Io& io) {
  std::vector<V4l2DeviceInfo> devices;
  for (const std::string& path : io.list_device_paths()) {
    V4l2DeviceInfo d;
    d.path = path;
    const int fd = io.open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
      const int e = errno;
      if (e == ENOENT || e == ENODEV) continue;  // unplugged since the directory was read
      d.error = "cannot open: " + errno_text(e) + (e == EACCES ? " (is the user in the 'video' group?)" : "");
      devices.push_back(std::move(d));
      continue;
    }
    v4l2_capability cap{};
    if (xioctl(io, fd, VIDIOC_QUERYCAP, &cap) != 0) {
      const int e = errno;
      io.close(fd);
      if (e == ENODEV) continue;
      d.error = "VIDIOC_QUERYCAP failed: " + errno_text(e);
      devices.push_back(std::move(d));
      continue;
    }
    d.driver = field_string(cap.driver);
    d.card = field_string(cap.card);
    d.bus_info = field_string(cap.bus_info);
    d.capabilities = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (!(d.capabilities & V4L2_CAP_VIDEO_CAPTURE) || !(d.capabilities & V4L2_CAP_STREAMING)) {
      io.close(fd);  // metadata, output, radio or multi-planar node
      continue;
    }
    for (std::uint32_t i = 0; i < kMaxEnumerated; ++i) {
      v4l2_fmtdesc desc{};
      desc.index = i;
      desc.type = kCaptureType;
      if (xioctl(io, fd, VIDIOC_ENUM_FMT, &desc) != 0) {
        if (errno != EINVAL) d.error = "VIDIOC_ENUM_FMT failed: " + errno_text(errno);
        break;
      }
      V4l2FormatInfo f;
      f.fourcc = desc.pixelformat;
      f.description = field_string(desc.description);
      f.compressed = (desc.flags & V4L2_FMT_FLAG_COMPRESSED) != 0;
      f.supported = v4l2_to_pixel_format(desc.pixelformat).has_value();
      for (std::uint32_t k = 0; k < kMaxEnumerated; ++k) {
        v4l2_frmsizeenum fs{};
        fs.index = k;
        fs.pixel_format = desc.pixelformat;
        if (xioctl(io, fd, VIDIOC_ENUM_FRAMESIZES, &fs) != 0) break;  // EINVAL: end, or not offered
        V4l2FrameSize s;
        if (fs.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
          s.min_width_px = s.max_width_px = fs.discrete.width;
          s.min_height_px = s.max_height_px = fs.discrete.height;
          f.frame_sizes.push_back(s);
          continue;
        }
        // Stepwise and continuous are one entry (index 0) only.
        s.min_width_px = fs.stepwise.min_width;
        s.max_width_px = fs.stepwise.max_width;
        s.step_width_px = fs.type == V4L2_FRMSIZE_TYPE_CONTINUOUS ? 1 : fs.stepwise.step_width;
        s.min_height_px = fs.stepwise.min_height;
        s.max_height_px = fs.stepwise.max_height;
        s.step_height_px = fs.type == V4L2_FRMSIZE_TYPE_CONTINUOUS ? 1 : fs.stepwise.step_height;
        f.frame_sizes.push_back(s);
        break;
      }
      d.formats.push_back(std::move(f));
    }
    io.close(fd);
    devices.push_back(std::move(d));
  }
  return devices;
}

}  // namespace augrig
