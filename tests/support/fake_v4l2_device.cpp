#include "tests/support/fake_v4l2_device.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <stdexcept>

#include <fcntl.h>
#include <sys/mman.h>

namespace augrig::test {
namespace {

constexpr std::uint32_t kCapture = V4L2_BUF_TYPE_VIDEO_CAPTURE;
constexpr std::uint32_t kPage = 4096;

template <std::size_t N>
void copy_field(__u8 (&dst)[N], const std::string& s) {
  std::memset(dst, 0, N);
  std::memcpy(dst, s.data(), std::min(s.size(), N - 1));
}

std::uint32_t round_to_step(std::uint32_t v, std::uint32_t lo, std::uint32_t hi, std::uint32_t step) {
  v = std::clamp(v, lo, hi);
  step = std::max<std::uint32_t>(step, 1);
  const std::uint32_t k = (v - lo + step / 2) / step;
  return std::min(lo + k * step, hi - (hi - lo) % step);
}

}  // namespace

FakeV4l2Format fake_format(std::uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_GREY:
      return {fourcc, 8, "8-bit Greyscale"};
    case V4L2_PIX_FMT_RGB24:
      return {fourcc, 24, "24-bit RGB 8-8-8"};
    case V4L2_PIX_FMT_YUYV:
      return {fourcc, 16, "YUYV 4:2:2"};
    case V4L2_PIX_FMT_MJPEG:
      return {fourcc, 0, "Motion-JPEG"};
    case V4L2_PIX_FMT_SBGGR8:
      return {fourcc, 8, "8-bit Bayer BGBG/GRGR"};
    case V4L2_PIX_FMT_SGBRG8:
      return {fourcc, 8, "8-bit Bayer GBGB/RGRG"};
    case V4L2_PIX_FMT_SGRBG8:
      return {fourcc, 8, "8-bit Bayer GRGR/BGBG"};
    case V4L2_PIX_FMT_SRGGB8:
      return {fourcc, 8, "8-bit Bayer RGRG/GBGB"};
    case V4L2_PIX_FMT_Y16:
      return {fourcc, 16, "16-bit Greyscale"};
    default:
      return {fourcc, 16, ""};
  }
}

std::vector<FakeV4l2Control> fake_camera_controls() {
  FakeV4l2Control exposure_auto{V4L2_CID_EXPOSURE_AUTO,         "Auto Exposure", V4L2_CTRL_TYPE_MENU, 0, 3, 1,
                                V4L2_EXPOSURE_APERTURE_PRIORITY};
  exposure_auto.menu_mask = (1u << V4L2_EXPOSURE_MANUAL) | (1u << V4L2_EXPOSURE_APERTURE_PRIORITY);
  return {
      exposure_auto,
      {V4L2_CID_EXPOSURE_ABSOLUTE, "Exposure Time, Absolute", V4L2_CTRL_TYPE_INTEGER, 1, 5000, 1, 156},
      {V4L2_CID_AUTOGAIN, "Gain, Automatic", V4L2_CTRL_TYPE_BOOLEAN, 0, 1, 1, 1},
      {V4L2_CID_GAIN, "Gain", V4L2_CTRL_TYPE_INTEGER, 0, 480, 1, 64},
  };
}

// ---------------------------------------------------------------------------------------------
// FakeV4l2Device

FakeV4l2Device::FakeV4l2Device(FakeV4l2Io& io, FakeV4l2Config config) : io_(io), config_(std::move(config)) {
  if (config_.formats.empty()) throw std::invalid_argument("FakeV4l2Config: at least one format is needed");
  v4l2_format f{};
  f.type = kCapture;
  f.fmt.pix.pixelformat = config_.formats[0].fourcc;
  f.fmt.pix.width = config_.width;
  f.fmt.pix.height = config_.height;
  try_fmt(f);
  pix_ = f.fmt.pix;
  if (!config_.frame_intervals.empty()) time_per_frame_ = config_.frame_intervals[0];
  for (const auto& c : config_.controls) control_values_[c.id] = c.default_value;
}

const FakeV4l2Format* FakeV4l2Device::find_format(std::uint32_t fourcc) const {
  for (const auto& f : config_.formats)
    if (f.fourcc == fourcc) return &f;
  return nullptr;
}

FakeV4l2Control* FakeV4l2Device::find_control(std::uint32_t id) {
  for (auto& c : config_.controls)
    if (c.id == id) return &c;
  return nullptr;
}
const FakeV4l2Control* FakeV4l2Device::find_control(std::uint32_t id) const {
  return const_cast<FakeV4l2Device*>(this)->find_control(id);
}

bool FakeV4l2Device::control_inactive(const FakeV4l2Control& c) const {
  // As in UVC: the exposure time belongs to auto exposure unless that is manual or shutter priority.
  if (c.id == V4L2_CID_EXPOSURE_ABSOLUTE && control_values_.count(V4L2_CID_EXPOSURE_AUTO)) {
    const auto mode = control_values_.at(V4L2_CID_EXPOSURE_AUTO);
    return mode != V4L2_EXPOSURE_MANUAL && mode != V4L2_EXPOSURE_SHUTTER_PRIORITY;
  }
  if (c.id == V4L2_CID_GAIN && control_values_.count(V4L2_CID_AUTOGAIN)) {
    return control_values_.at(V4L2_CID_AUTOGAIN) != 0;
  }
  return false;
}

int FakeV4l2Device::querycap(v4l2_capability& cap) const {
  cap = v4l2_capability{};
  copy_field(cap.driver, config_.driver);
  copy_field(cap.card, config_.card);
  copy_field(cap.bus_info, config_.bus_info);
  cap.version = (6u << 16) | (1u << 8);
  cap.device_caps = config_.device_caps;
  cap.capabilities = config_.device_caps | V4L2_CAP_DEVICE_CAPS;
  return 0;
}

int FakeV4l2Device::enum_fmt(v4l2_fmtdesc& d) const {
  if (d.type != kCapture || d.index >= config_.formats.size()) return EINVAL;
  const FakeV4l2Format& f = config_.formats[d.index];
  const std::uint32_t index = d.index;
  d = v4l2_fmtdesc{};
  d.index = index;
  d.type = kCapture;
  d.pixelformat = f.fourcc;
  d.flags = f.bits_per_pixel == 0 ? V4L2_FMT_FLAG_COMPRESSED : 0;
  std::string desc = f.description;
  if (desc.empty()) {
    for (int i = 0; i < 4; ++i) desc += static_cast<char>((f.fourcc >> (8 * i)) & 0xff);
  }
  copy_field(d.description, desc);
  return 0;
}

int FakeV4l2Device::enum_framesizes(v4l2_frmsizeenum& s) const {
  if (!config_.enumerates_frame_sizes) return ENOTTY;
  if (!find_format(s.pixel_format)) return EINVAL;
  const std::uint32_t index = s.index, fourcc = s.pixel_format;
  s = v4l2_frmsizeenum{};
  s.index = index;
  s.pixel_format = fourcc;
  if (!config_.discrete_sizes.empty()) {
    if (index >= config_.discrete_sizes.size()) return EINVAL;
    s.type = V4L2_FRMSIZE_TYPE_DISCRETE;
    s.discrete.width = config_.discrete_sizes[index].first;
    s.discrete.height = config_.discrete_sizes[index].second;
    return 0;
  }
  if (index > 0) return EINVAL;
  const bool continuous = config_.step_width == 1 && config_.step_height == 1;
  s.type = continuous ? V4L2_FRMSIZE_TYPE_CONTINUOUS : V4L2_FRMSIZE_TYPE_STEPWISE;
  s.stepwise = {config_.min_width,  config_.max_width,  config_.step_width,
                config_.min_height, config_.max_height, config_.step_height};
  return 0;
}

// TRY_FMT: "drivers should not return an error code unless the type field is invalid"; they
// adjust everything else to what the hardware can do.
int FakeV4l2Device::try_fmt(v4l2_format& f) const {
  if (f.type != kCapture) return EINVAL;
  v4l2_pix_format& p = f.fmt.pix;
  const bool enum_only = std::find(config_.enum_only_fourccs.begin(), config_.enum_only_fourccs.end(),
                                   p.pixelformat) != config_.enum_only_fourccs.end();
  const FakeV4l2Format* fmt = find_format(p.pixelformat);
  if (fmt == nullptr || enum_only) fmt = &config_.formats[0];
  if (!config_.discrete_sizes.empty()) {
    auto cost = [&](const std::pair<std::uint32_t, std::uint32_t>& s) {
      return std::abs(static_cast<long>(s.first) - static_cast<long>(p.width)) +
             std::abs(static_cast<long>(s.second) - static_cast<long>(p.height));
    };
    const auto best = std::min_element(config_.discrete_sizes.begin(), config_.discrete_sizes.end(),
                                       [&](const auto& a, const auto& b) { return cost(a) < cost(b); });
    p.width = best->first;
    p.height = best->second;
  } else {
    p.width = round_to_step(p.width, config_.min_width, config_.max_width, config_.step_width);
    p.height = round_to_step(p.height, config_.min_height, config_.max_height, config_.step_height);
  }
  p.pixelformat = fmt->fourcc;
  p.field = config_.field;
  if (fmt->bits_per_pixel == 0) {
    p.bytesperline = 0;
    p.sizeimage = std::max<std::uint32_t>(p.width * p.height * 3, 16384);  // worst-case JPEG
  } else {
    const std::uint32_t row = p.width * static_cast<std::uint32_t>(fmt->bits_per_pixel) / 8;
    const std::uint32_t a = std::max<std::uint32_t>(config_.bytesperline_align, 1);
    p.bytesperline = (row + a - 1) / a * a;
    p.sizeimage = p.bytesperline * p.height;
  }
  p.colorspace = fmt->fourcc == V4L2_PIX_FMT_YUYV ? V4L2_COLORSPACE_SMPTE170M : V4L2_COLORSPACE_SRGB;
  p.priv = 0;
  p.flags = 0;
  p.ycbcr_enc = V4L2_YCBCR_ENC_DEFAULT;
  p.quantization = V4L2_QUANTIZATION_DEFAULT;
  p.xfer_func = V4L2_XFER_FUNC_DEFAULT;
  return 0;
}

void FakeV4l2Device::free_buffers() {
  bufs_.clear();
  free_when_unmapped_ = false;
}

int FakeV4l2Device::reqbufs(int fd, v4l2_requestbuffers& r) {
  if (r.type != kCapture || r.memory != V4L2_MEMORY_MMAP) return EINVAL;
  if (owner_fd_ >= 0 && owner_fd_ != fd) return EBUSY;
  if (streaming_) return EBUSY;
  int mapped = 0;
  for (const Buf& b : bufs_) mapped += b.mappings;
  if (mapped > 0) return EBUSY;  // no V4L2_BUF_CAP_SUPPORTS_ORPHANED_BUFS
  free_buffers();
  r.capabilities = V4L2_BUF_CAP_SUPPORTS_MMAP;
  std::memset(r.reserved, 0, sizeof r.reserved);
  if (r.count == 0) {
    owner_fd_ = -1;
    return 0;
  }
  r.count = std::clamp(r.count, config_.min_buffers, config_.max_buffers);
  const std::uint32_t length = (pix_.sizeimage + kPage - 1) / kPage * kPage;
  bufs_.resize(r.count);
  for (std::uint32_t i = 0; i < r.count; ++i) {
    bufs_[i].mem.assign(length, 0);
    bufs_[i].offset = i * length;
  }
  owner_fd_ = fd;
  return 0;
}

void FakeV4l2Device::fill(const Buf& b, std::uint32_t index, v4l2_buffer& out) const {
  out = v4l2_buffer{};
  out.index = index;
  out.type = kCapture;
  out.memory = V4L2_MEMORY_MMAP;
  out.m.offset = b.offset;
  out.length = static_cast<std::uint32_t>(b.mem.size());
  out.bytesused = b.bytesused;
  out.field = V4L2_FIELD_NONE;
  out.sequence = b.sequence;
  out.timestamp = b.timestamp;
  out.flags =
      (b.flags & ~(V4L2_BUF_FLAG_TIMESTAMP_MASK | V4L2_BUF_FLAG_TSTAMP_SRC_MASK)) | config_.timestamp_flags;
  if (b.mappings > 0) out.flags |= V4L2_BUF_FLAG_MAPPED;
  if (b.state == BufState::kQueued) out.flags |= V4L2_BUF_FLAG_QUEUED;
  if (b.state == BufState::kDone) out.flags |= V4L2_BUF_FLAG_DONE;
}

int FakeV4l2Device::querybuf(v4l2_buffer& b) const {
  if (b.type != kCapture || b.index >= bufs_.size()) return EINVAL;
  fill(bufs_[b.index], b.index, b);
  return 0;
}

int FakeV4l2Device::qbuf(int fd, v4l2_buffer& b) {
  if (owner_fd_ >= 0 && owner_fd_ != fd) return EBUSY;
  if (b.type != kCapture || b.memory != V4L2_MEMORY_MMAP || b.index >= bufs_.size()) return EINVAL;
  Buf& buf = bufs_[b.index];
  if (buf.state != BufState::kDequeued) return EINVAL;  // the driver has it already
  buf.state = BufState::kQueued;
  buf.queue_order = ++order_counter_;
  buf.flags = 0;
  buf.bytesused = 0;
  fill(buf, b.index, b);
  return 0;
}

int FakeV4l2Device::dqbuf(int fd, bool nonblocking, v4l2_buffer& b, std::unique_lock<std::mutex>& lock) {
  if (owner_fd_ >= 0 && owner_fd_ != fd) return EBUSY;
  if (b.type != kCapture || b.memory != V4L2_MEMORY_MMAP || bufs_.empty()) return EINVAL;
  auto oldest_done = [&]() -> Buf* {
    Buf* best = nullptr;
    for (Buf& x : bufs_)
      if (x.state == BufState::kDone && (best == nullptr || x.done_order < best->done_order)) best = &x;
    return best;
  };
  for (;;) {
    if (unplugged_) return ENODEV;
    if (!streaming_) return EINVAL;
    if (queue_error_) return EIO;
    if (Buf* d = oldest_done()) {
      d->state = BufState::kDequeued;
      fill(*d, static_cast<std::uint32_t>(d - bufs_.data()), b);
      return 0;
    }
    if (nonblocking) return EAGAIN;
    io_.changed_.wait(lock);
  }
}

int FakeV4l2Device::streamon(int fd, const int& type) {
  if (type != static_cast<int>(kCapture)) return EINVAL;
  if (owner_fd_ >= 0 && owner_fd_ != fd) return EBUSY;
  if (bufs_.empty()) return EINVAL;
  if (streaming_) return 0;
  streaming_ = true;
  queue_error_ = false;
  next_sequence_ = 0;
  return 0;
}

int FakeV4l2Device::streamoff(int fd, const int& type) {
  if (type != static_cast<int>(kCapture)) return EINVAL;
  if (owner_fd_ >= 0 && owner_fd_ != fd) return EBUSY;
  // "all buffers are in the dequeued state"; captured but unread frames are lost.
  for (Buf& b : bufs_) b.state = BufState::kDequeued;
  streaming_ = false;
  queue_error_ = false;
  io_.changed_.notify_all();
  return 0;
}

int FakeV4l2Device::queryctrl(v4l2_queryctrl& q) const {
  const FakeV4l2Control* c = nullptr;
  if (q.id & V4L2_CTRL_FLAG_NEXT_CTRL) {
    const std::uint32_t after = q.id & ~(V4L2_CTRL_FLAG_NEXT_CTRL | V4L2_CTRL_FLAG_NEXT_COMPOUND);
    for (const auto& x : config_.controls)
      if (x.id > after && (c == nullptr || x.id < c->id)) c = &x;
  } else {
    c = find_control(q.id);
  }
  if (c == nullptr) return EINVAL;
  q = v4l2_queryctrl{};
  q.id = c->id;
  q.type = c->type;
  copy_field(q.name, c->name);
  q.minimum = c->minimum;
  q.maximum = c->maximum;
  q.step = c->type == V4L2_CTRL_TYPE_MENU ? 1 : c->step;
  q.default_value = c->default_value;
  q.flags = c->flags | (control_inactive(*c) ? V4L2_CTRL_FLAG_INACTIVE : 0u);
  return 0;
}

int FakeV4l2Device::g_ctrl(v4l2_control& c) const {
  const FakeV4l2Control* ctrl = find_control(c.id);
  if (ctrl == nullptr || (ctrl->flags & V4L2_CTRL_FLAG_DISABLED)) return EINVAL;
  if (ctrl->flags & V4L2_CTRL_FLAG_WRITE_ONLY) return EACCES;
  c.value = control_values_.at(c.id);
  return 0;
}

int FakeV4l2Device::s_ctrl(v4l2_control& c) {
  FakeV4l2Control* ctrl = find_control(c.id);
  if (ctrl == nullptr || (ctrl->flags & V4L2_CTRL_FLAG_DISABLED)) return EINVAL;
  if (ctrl->flags & V4L2_CTRL_FLAG_READ_ONLY) return EACCES;
  if (control_inactive(*ctrl)) return EACCES;  // "an inactive control and the driver does not support that"
  if (c.value < ctrl->minimum || c.value > ctrl->maximum) return ERANGE;
  std::int32_t v = c.value;
  if (ctrl->type == V4L2_CTRL_TYPE_MENU) {
    if (ctrl->menu_mask != 0 && !(ctrl->menu_mask & (std::uint64_t{1} << v))) return EINVAL;
  } else if (ctrl->type == V4L2_CTRL_TYPE_INTEGER && ctrl->step > 1) {
    v = ctrl->minimum + (v - ctrl->minimum + ctrl->step / 2) / ctrl->step * ctrl->step;
    v = std::min(v, ctrl->maximum);
  }
  control_values_[c.id] = v;
  c.value = v;
  return 0;
}

int FakeV4l2Device::g_parm(v4l2_streamparm& p) const {
  if (config_.frame_intervals.empty()) return ENOTTY;
  if (p.type != kCapture) return EINVAL;
  p.parm.capture = v4l2_captureparm{};
  p.parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
  p.parm.capture.timeperframe = time_per_frame_;
  return 0;
}

int FakeV4l2Device::s_parm(v4l2_streamparm& p) {
  if (config_.frame_intervals.empty()) return ENOTTY;
  if (p.type != kCapture) return EINVAL;
  const v4l2_fract want = p.parm.capture.timeperframe;
  if (want.numerator == 0 || want.denominator == 0) {
    time_per_frame_ = config_.frame_intervals[0];  // nominal rate
  } else {
    const double want_s = static_cast<double>(want.numerator) / want.denominator;
    auto diff = [&](const v4l2_fract& f) {
      return std::abs(static_cast<double>(f.numerator) / f.denominator - want_s);
    };
    time_per_frame_ = *std::min_element(config_.frame_intervals.begin(), config_.frame_intervals.end(),
                                        [&](const auto& a, const auto& b) { return diff(a) < diff(b); });
  }
  return g_parm(p);
}

int FakeV4l2Device::do_ioctl(int fd, bool nonblocking, unsigned long request, void* arg,
                             std::unique_lock<std::mutex>& lock) {
  ioctl_log_.push_back(request);
  if (unplugged_) return ENODEV;
  switch (request) {
    case VIDIOC_QUERYCAP:
      return querycap(*static_cast<v4l2_capability*>(arg));
    case VIDIOC_ENUM_FMT:
      return enum_fmt(*static_cast<v4l2_fmtdesc*>(arg));
    case VIDIOC_ENUM_FRAMESIZES:
      return enum_framesizes(*static_cast<v4l2_frmsizeenum*>(arg));
    case VIDIOC_G_FMT: {
      auto& f = *static_cast<v4l2_format*>(arg);
      if (f.type != kCapture) return EINVAL;
      f.fmt.pix = pix_;
      return 0;
    }
    case VIDIOC_TRY_FMT:
      return try_fmt(*static_cast<v4l2_format*>(arg));
    case VIDIOC_S_FMT: {
      auto& f = *static_cast<v4l2_format*>(arg);
      if (f.type != kCapture) return EINVAL;
      if (!bufs_.empty() || streaming_) return EBUSY;
      if (owner_fd_ >= 0 && owner_fd_ != fd) return EBUSY;
      try_fmt(f);
      pix_ = f.fmt.pix;
      return 0;
    }
    case VIDIOC_REQBUFS:
      return reqbufs(fd, *static_cast<v4l2_requestbuffers*>(arg));
    case VIDIOC_QUERYBUF:
      return querybuf(*static_cast<v4l2_buffer*>(arg));
    case VIDIOC_QBUF:
      return qbuf(fd, *static_cast<v4l2_buffer*>(arg));
    case VIDIOC_DQBUF:
      return dqbuf(fd, nonblocking, *static_cast<v4l2_buffer*>(arg), lock);
    case VIDIOC_STREAMON:
      return streamon(fd, *static_cast<const int*>(arg));
    case VIDIOC_STREAMOFF:
      return streamoff(fd, *static_cast<const int*>(arg));
    case VIDIOC_QUERYCTRL:
      return queryctrl(*static_cast<v4l2_queryctrl*>(arg));
    case VIDIOC_G_CTRL:
      return g_ctrl(*static_cast<v4l2_control*>(arg));
    case VIDIOC_S_CTRL:
      return s_ctrl(*static_cast<v4l2_control*>(arg));
    case VIDIOC_G_PARM:
      return g_parm(*static_cast<v4l2_streamparm*>(arg));
    case VIDIOC_S_PARM:
      return s_parm(*static_cast<v4l2_streamparm*>(arg));
    default:
      return ENOTTY;
  }
}

short FakeV4l2Device::poll_events() const {
  if (unplugged_) return POLLERR | POLLHUP | POLLPRI;  // v4l2_poll() once unregistered
  if (!streaming_ || queue_error_) return POLLERR;     // vb2_core_poll()
  for (const Buf& b : bufs_)
    if (b.state == BufState::kDone) return POLLIN | POLLRDNORM;
  return 0;
}

void FakeV4l2Device::release_file(int fd) {
  --open_files_;
  if (fd != owner_fd_) return;
  // vb2_queue_release(): streaming stops and the buffers go once nothing maps them.
  for (Buf& b : bufs_) b.state = BufState::kDequeued;
  streaming_ = false;
  owner_fd_ = -1;
  int mapped = 0;
  for (const Buf& b : bufs_) mapped += b.mappings;
  if (mapped == 0) {
    free_buffers();
  } else {
    free_when_unmapped_ = true;
  }
  io_.changed_.notify_all();
}

bool FakeV4l2Device::push_frame(const std::vector<std::uint8_t>& bytes,
                                std::optional<TimestampNs> timestamp_ns,
                                std::optional<std::uint32_t> sequence, std::uint32_t extra_flags) {
  std::lock_guard lock(io_.mutex_);
  if (unplugged_ || !streaming_) return false;
  const std::uint32_t seq = sequence.value_or(next_sequence_);
  next_sequence_ = seq + 1;
  // The oldest queued buffer, as drivers fill them in QBUF order.
  Buf* target = nullptr;
  for (Buf& b : bufs_)
    if (b.state == BufState::kQueued && (target == nullptr || b.queue_order < target->queue_order))
      target = &b;
  if (target == nullptr) return false;  // no buffer: the frame is lost, its sequence number skipped
  if (bytes.size() > target->mem.size()) {
    throw std::length_error("FakeV4l2Device::push_frame(): " + std::to_string(bytes.size()) +
                            " bytes do not fit a " + std::to_string(target->mem.size()) + "-byte buffer");
  }
  std::copy(bytes.begin(), bytes.end(), target->mem.begin());
  target->bytesused = static_cast<std::uint32_t>(bytes.size());
  target->flags = extra_flags;
  target->sequence = seq;
  TimestampNs t_ns = 0;
  if (timestamp_ns) {
    t_ns = *timestamp_ns;
  } else {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    t_ns = static_cast<TimestampNs>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  }
  target->timestamp.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  target->timestamp.tv_usec = static_cast<suseconds_t>(t_ns % 1'000'000'000 / 1000);
  target->state = BufState::kDone;
  target->done_order = ++order_counter_;
  io_.changed_.notify_all();
  return true;
}

std::vector<std::uint8_t> FakeV4l2Device::pattern_frame(std::uint8_t seed) const {
  std::lock_guard lock(io_.mutex_);
  const FakeV4l2Format* f = find_format(pix_.pixelformat);
  if (f == nullptr || f->bits_per_pixel == 0) {
    throw std::logic_error("FakeV4l2Device::pattern_frame(): the current format is compressed");
  }
  const std::uint32_t row = pix_.width * static_cast<std::uint32_t>(f->bits_per_pixel) / 8;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(pix_.bytesperline) * pix_.height, 0xEE);
  for (std::uint32_t y = 0; y < pix_.height; ++y)
    for (std::uint32_t x = 0; x < row; ++x)
      bytes[static_cast<std::size_t>(y) * pix_.bytesperline + x] =
          pattern_byte(static_cast<int>(x), static_cast<int>(y), seed);
  return bytes;
}

void FakeV4l2Device::unplug() {
  std::lock_guard lock(io_.mutex_);
  unplugged_ = true;
  io_.changed_.notify_all();
}

void FakeV4l2Device::set_queue_error() {
  std::lock_guard lock(io_.mutex_);
  queue_error_ = true;
  io_.changed_.notify_all();
}

v4l2_pix_format FakeV4l2Device::format() const {
  std::lock_guard lock(io_.mutex_);
  return pix_;
}
v4l2_fract FakeV4l2Device::time_per_frame() const {
  std::lock_guard lock(io_.mutex_);
  return time_per_frame_;
}
bool FakeV4l2Device::streaming() const {
  std::lock_guard lock(io_.mutex_);
  return streaming_;
}
std::size_t FakeV4l2Device::buffer_count() const {
  std::lock_guard lock(io_.mutex_);
  return bufs_.size();
}
std::size_t FakeV4l2Device::queued_buffers() const {
  std::lock_guard lock(io_.mutex_);
  return std::count_if(bufs_.begin(), bufs_.end(), [](const Buf& b) { return b.state == BufState::kQueued; });
}
std::size_t FakeV4l2Device::done_buffers() const {
  std::lock_guard lock(io_.mutex_);
  return std::count_if(bufs_.begin(), bufs_.end(), [](const Buf& b) { return b.state == BufState::kDone; });
}
int FakeV4l2Device::mappings() const {
  std::lock_guard lock(io_.mutex_);
  int n = 0;
  for (const Buf& b : bufs_) n += b.mappings;
  return n;
}
int FakeV4l2Device::open_files() const {
  std::lock_guard lock(io_.mutex_);
  return open_files_;
}
std::int32_t FakeV4l2Device::control(std::uint32_t id) const {
  std::lock_guard lock(io_.mutex_);
  return control_values_.at(id);
}
int FakeV4l2Device::poll_calls() const {
  std::lock_guard lock(io_.mutex_);
  return poll_calls_;
}
int FakeV4l2Device::last_poll_timeout_ms() const {
  std::lock_guard lock(io_.mutex_);
  return last_poll_timeout_ms_;
}
std::vector<unsigned long> FakeV4l2Device::ioctl_log() const {
  std::lock_guard lock(io_.mutex_);
  return ioctl_log_;
}
std::uint32_t FakeV4l2Device::next_sequence() const {
  std::lock_guard lock(io_.mutex_);
  return next_sequence_;
}

// ---------------------------------------------------------------------------------------------
// FakeV4l2Io

FakeV4l2Device& FakeV4l2Io::add_device(FakeV4l2Config config) {
  std::lock_guard lock(mutex_);
  devices_.push_back(std::unique_ptr<FakeV4l2Device>(new FakeV4l2Device(*this, std::move(config))));
  return *devices_.back();
}

FakeV4l2Device& FakeV4l2Io::device(const std::string& path) {
  std::lock_guard lock(mutex_);
  for (auto& d : devices_)
    if (d->config_.path == path) return *d;
  throw std::out_of_range("FakeV4l2Io::device(): no device " + path);
}

int FakeV4l2Io::open(const char* path, int flags) {
  std::lock_guard lock(mutex_);
  for (auto& d : devices_) {
    if (d->config_.path != path || d->unplugged_) continue;
    if (d->config_.open_errno != 0) {
      errno = d->config_.open_errno;
      return -1;
    }
    const int fd = next_fd_++;
    files_[fd] = {d.get(), (flags & O_NONBLOCK) != 0};
    ++d->open_files_;
    return fd;
  }
  errno = ENOENT;
  return -1;
}

int FakeV4l2Io::close(int fd) {
  std::lock_guard lock(mutex_);
  auto it = files_.find(fd);
  if (it == files_.end()) {
    errno = EBADF;
    return -1;
  }
  it->second.device->release_file(fd);
  files_.erase(it);
  return 0;
}

int FakeV4l2Io::ioctl(int fd, unsigned long request, void* arg) {
  std::unique_lock lock(mutex_);
  auto it = files_.find(fd);
  if (it == files_.end()) {
    errno = EBADF;
    return -1;
  }
  const File file = it->second;
  const int e = file.device->do_ioctl(fd, file.nonblocking, request, arg, lock);
  if (e != 0) {
    errno = e;
    return -1;
  }
  return 0;
}

void* FakeV4l2Io::mmap(void* /*addr*/, std::size_t length, int prot, int flags, int fd, off_t offset) {
  std::lock_guard lock(mutex_);
  auto it = files_.find(fd);
  if (it == files_.end()) {
    errno = EBADF;
    return MAP_FAILED;
  }
  FakeV4l2Device& d = *it->second.device;
  if (d.unplugged_) {
    errno = ENODEV;
    return MAP_FAILED;
  }
  // vb2_mmap(): shared mappings only, readable for a capture queue, one whole buffer at its offset.
  if (!(flags & MAP_SHARED) || !(prot & PROT_READ) || length == 0) {
    errno = EINVAL;
    return MAP_FAILED;
  }
  for (std::uint32_t i = 0; i < d.bufs_.size(); ++i) {
    auto& b = d.bufs_[i];
    if (static_cast<off_t>(b.offset) != offset) continue;
    if (length > b.mem.size()) break;
    ++b.mappings;
    void* p = b.mem.data();
    auto [m, inserted] = mappings_.try_emplace(p, Mapping{&d, i, 0});
    ++m->second.count;
    return p;
  }
  errno = EINVAL;
  return MAP_FAILED;
}

int FakeV4l2Io::munmap(void* addr, std::size_t /*length*/) {
  std::lock_guard lock(mutex_);
  auto it = mappings_.find(addr);
  if (it == mappings_.end()) {
    errno = EINVAL;  // not a mapping this fake made: a bug in the caller
    return -1;
  }
  FakeV4l2Device& d = *it->second.device;
  --d.bufs_[it->second.index].mappings;
  if (--it->second.count == 0) mappings_.erase(it);
  if (d.free_when_unmapped_) {
    int mapped = 0;
    for (const auto& b : d.bufs_) mapped += b.mappings;
    if (mapped == 0) d.free_buffers();
  }
  return 0;
}

int FakeV4l2Io::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  std::unique_lock lock(mutex_);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(std::max(timeout_ms, 0));
  for (nfds_t i = 0; i < nfds; ++i) {
    auto it = files_.find(fds[i].fd);
    if (it != files_.end()) {
      ++it->second.device->poll_calls_;
      it->second.device->last_poll_timeout_ms_ = timeout_ms;
    }
  }
  for (;;) {
    int ready = 0;
    for (nfds_t i = 0; i < nfds; ++i) {
      auto it = files_.find(fds[i].fd);
      const short ev = it == files_.end() ? POLLNVAL : it->second.device->poll_events();
      // POLLERR, POLLHUP and POLLNVAL are reported whether asked for or not.
      fds[i].revents = static_cast<short>(ev & (fds[i].events | POLLERR | POLLHUP | POLLNVAL));
      if (fds[i].revents != 0) ++ready;
    }
    if (ready > 0 || timeout_ms == 0) return ready;
    if (timeout_ms < 0) {
      changed_.wait(lock);
    } else if (changed_.wait_until(lock, deadline) == std::cv_status::timeout) {
      timeout_ms = 0;  // one last look, then report the timeout
    }
  }
}

std::vector<std::string> FakeV4l2Io::list_device_paths() {
  std::lock_guard lock(mutex_);
  std::vector<std::string> paths;
  for (const auto& d : devices_)
    if (!d->unplugged_) paths.push_back(d->config_.path);
  return paths;
}

int FakeV4l2Io::open_files() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(files_.size());
}

int FakeV4l2Io::mappings() const {
  std::lock_guard lock(mutex_);
  int n = 0;
  for (const auto& [p, m] : mappings_) n += m.count;
  return n;
}

}  // namespace augrig::test
