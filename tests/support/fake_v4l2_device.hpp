// FakeV4l2Io: a V4l2Io (capture/v4l2_io.hpp) that emulates V4L2 capture devices the way the kernel
// documents them (https://www.kernel.org/doc/html/latest/userspace-api/media/v4l/), so the real
// V4L2 backend runs against it in tests on machines without /dev/video*:
//   QUERYCAP; ENUM_FMT and ENUM_FRAMESIZES (EINVAL past the end); G/S/TRY_FMT adjusting the size
//   to the device's and substituting the default format for unsupported fourccs (EINVAL only for a
//   bad buffer type, EBUSY once buffers exist); REQBUFS (count 0 frees; EBUSY while mapped or
//   streaming or owned by another file handle); QUERYBUF; mmap at the buffer offsets; QBUF/DQBUF
//   (EINVAL for a bad index or a buffer the driver owns, EAGAIN on an empty done queue in
//   non-blocking mode, EIO after a queue error); STREAMON/STREAMOFF (STREAMOFF returns every
//   buffer to the application); QUERYCTRL, G/S_CTRL (EINVAL unknown control or menu item, ERANGE
//   out of range, EACCES read-only or inactive); G/S_PARM; poll readiness; ENOTTY for ioctls the
//   device does not implement; and ENODEV / POLLERR|POLLHUP after unplug().
// Frames appear only when the test pushes them (push_frame), so tests need no sleeps for ordering.
// Like a real driver, a frame pushed while no buffer is queued is lost and its sequence number
// skipped.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <linux/videodev2.h>

#include "capture/v4l2_io.hpp"
#include "core/conventions.hpp"

namespace augrig::test {

struct FakeV4l2Format {
  std::uint32_t fourcc = 0;
  int bits_per_pixel = 0;   // in the buffer; 0: compressed (MJPEG)
  std::string description;  // ENUM_FMT's; empty: the fourcc
};
// The fourccs with their V4L2 sizes: GREY 8, RGB3 24, YUYV 16, MJPG compressed, Bayer 8, Y16 16.
FakeV4l2Format fake_format(std::uint32_t fourcc);

struct FakeV4l2Control {
  std::uint32_t id = 0;
  std::string name;
  std::uint32_t type = V4L2_CTRL_TYPE_INTEGER;  // INTEGER, BOOLEAN or MENU
  std::int32_t minimum = 0, maximum = 0, step = 1, default_value = 0;
  std::uint32_t flags = 0;      // e.g. V4L2_CTRL_FLAG_READ_ONLY, V4L2_CTRL_FLAG_DISABLED
  std::uint64_t menu_mask = 0;  // MENU: bit i set when item i exists (0: every item in range)
};
// Exposure (auto menu with manual and aperture priority, as UVC cameras have; absolute 1..5000 x
// 100 us, inactive unless auto exposure is manual) and gain (0..480, auto gain boolean).
std::vector<FakeV4l2Control> fake_camera_controls();

struct FakeV4l2Config {
  std::string path = "/dev/video0";
  std::string driver = "fake_v4l2";
  std::string card = "Fake V4L2 Camera";
  std::string bus_info = "platform:fake_v4l2-0";
  std::uint32_t device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  int open_errno = 0;  // non-zero: open() fails with it (e.g. EACCES)
  // ENUM_FMT order; the first is the default that S_FMT substitutes for unsupported fourccs.
  std::vector<FakeV4l2Format> formats = {fake_format(V4L2_PIX_FMT_YUYV)};
  // Listed by ENUM_FMT but substituted by S_FMT all the same (a driver that lies).
  std::vector<std::uint32_t> enum_only_fourccs;
  // Frame sizes: the nearest discrete size, or else the stepwise range below.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> discrete_sizes;
  std::uint32_t min_width = 16, max_width = 4096, step_width = 2;
  std::uint32_t min_height = 16, max_height = 4096, step_height = 2;
  bool enumerates_frame_sizes = true;       // false: ENUM_FRAMESIZES is ENOTTY
  std::uint32_t width = 640, height = 480;  // at power-on
  std::uint32_t bytesperline_align = 1;     // rows are padded to a multiple of this
  std::uint32_t field = V4L2_FIELD_NONE;    // what S_FMT sets
  std::uint32_t min_buffers = 2, max_buffers = 8;
  std::uint32_t timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_EOF;
  // Frame intervals (seconds per frame) S_PARM picks the nearest of; empty: G/S_PARM are ENOTTY.
  std::vector<v4l2_fract> frame_intervals = {{1, 30}, {1, 60}, {1, 15}};
  std::vector<FakeV4l2Control> controls = fake_camera_controls();
};

class FakeV4l2Io;

class FakeV4l2Device {
 public:
  // Puts a captured frame into the oldest queued buffer (bytesused = bytes.size()) and marks it
  // done, waking poll(). `timestamp_ns` defaults to CLOCK_MONOTONIC now (V4L2 keeps microseconds);
  // `sequence` defaults to one after the previous frame's; `extra_flags` adds e.g.
  // V4L2_BUF_FLAG_ERROR. Returns false, consuming the sequence number, when no buffer is queued
  // (the frame is lost as on a real device), and false without consuming it when not streaming.
  bool push_frame(const std::vector<std::uint8_t>& bytes, std::optional<TimestampNs> timestamp_ns = {},
                  std::optional<std::uint32_t> sequence = {}, std::uint32_t extra_flags = 0);
  // A frame of the current (uncompressed) format: pixel byte (x, y, channel) = x + 3y + 7c + seed
  // (mod 256); row padding beyond width is 0xEE so stride mistakes show.
  std::vector<std::uint8_t> pattern_frame(std::uint8_t seed) const;
  static std::uint8_t pattern_byte(int x_byte, int y, std::uint8_t seed) {
    return static_cast<std::uint8_t>(x_byte + 3 * y + seed);
  }

  // The device disappears: ioctl and mmap give ENODEV, poll POLLERR|POLLHUP, open ENOENT.
  void unplug();
  // vb2_queue_error(): poll gives POLLERR and DQBUF EIO until STREAMOFF.
  void set_queue_error();

  // Inspection.
  const FakeV4l2Config& config() const { return config_; }
  v4l2_pix_format format() const;
  v4l2_fract time_per_frame() const;
  bool streaming() const;
  std::size_t buffer_count() const;
  std::size_t queued_buffers() const;  // owned by the driver, waiting for a frame
  std::size_t done_buffers() const;    // filled, waiting for DQBUF
  int mappings() const;
  int open_files() const;
  std::int32_t control(std::uint32_t id) const;
  int poll_calls() const;
  int last_poll_timeout_ms() const;
  std::vector<unsigned long> ioctl_log() const;  // every request code received, in order
  std::uint32_t next_sequence() const;

 private:
  friend class FakeV4l2Io;
  enum class BufState { kDequeued, kQueued, kDone };
  struct Buf {
    std::vector<std::uint8_t> mem;
    std::uint32_t offset = 0;
    BufState state = BufState::kDequeued;
    std::uint32_t bytesused = 0;
    std::uint32_t flags = 0;
    std::uint32_t sequence = 0;
    timeval timestamp{};
    int mappings = 0;
    std::uint64_t queue_order = 0;  // QBUF order: drivers fill buffers first in, first out
    std::uint64_t done_order = 0;   // completion order: DQBUF returns the oldest
  };
  FakeV4l2Device(FakeV4l2Io& io, FakeV4l2Config config);

  // Called with the io mutex held; return 0 or an errno.
  int do_ioctl(int fd, bool nonblocking, unsigned long request, void* arg,
               std::unique_lock<std::mutex>& lock);
  int querycap(v4l2_capability& cap) const;
  int enum_fmt(v4l2_fmtdesc& d) const;
  int enum_framesizes(v4l2_frmsizeenum& s) const;
  int try_fmt(v4l2_format& f) const;
  int reqbufs(int fd, v4l2_requestbuffers& r);
  int querybuf(v4l2_buffer& b) const;
  int qbuf(int fd, v4l2_buffer& b);
  int dqbuf(int fd, bool nonblocking, v4l2_buffer& b, std::unique_lock<std::mutex>& lock);
  int streamon(int fd, const int& type);
  int streamoff(int fd, const int& type);
  int queryctrl(v4l2_queryctrl& q) const;
  int g_ctrl(v4l2_control& c) const;
  int s_ctrl(v4l2_control& c);
  int g_parm(v4l2_streamparm& p) const;
  int s_parm(v4l2_streamparm& p);
  short poll_events() const;
  void fill(const Buf& b, std::uint32_t index, v4l2_buffer& out) const;
  const FakeV4l2Format* find_format(std::uint32_t fourcc) const;
  FakeV4l2Control* find_control(std::uint32_t id);
  const FakeV4l2Control* find_control(std::uint32_t id) const;
  bool control_inactive(const FakeV4l2Control& c) const;
  void release_file(int fd);  // close(): the owner's queue is stopped and freed
  void free_buffers();

  FakeV4l2Io& io_;
  FakeV4l2Config config_;
  v4l2_pix_format pix_{};
  v4l2_fract time_per_frame_{};
  std::map<std::uint32_t, std::int32_t> control_values_;
  std::vector<Buf> bufs_;
  bool free_when_unmapped_ = false;
  int owner_fd_ = -1;
  bool streaming_ = false;
  bool queue_error_ = false;
  bool unplugged_ = false;
  std::uint32_t next_sequence_ = 0;
  std::uint64_t order_counter_ = 0;
  int open_files_ = 0;
  int poll_calls_ = 0;
  int last_poll_timeout_ms_ = 0;
  std::vector<unsigned long> ioctl_log_;
};

class FakeV4l2Io final : public V4l2Io {
 public:
  FakeV4l2Io() = default;
  FakeV4l2Io(const FakeV4l2Io&) = delete;
  FakeV4l2Io& operator=(const FakeV4l2Io&) = delete;

  // Adds a device node (list_device_paths() lists them in the order added).
  FakeV4l2Device& add_device(FakeV4l2Config config = {});
  FakeV4l2Device& device(const std::string& path);

  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) override;
  int munmap(void* addr, std::size_t length) override;
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  std::vector<std::string> list_device_paths() override;

  int open_files() const;  // across all devices
  int mappings() const;

 private:
  friend class FakeV4l2Device;
  struct File {
    FakeV4l2Device* device;
    bool nonblocking;
  };
  struct Mapping {
    FakeV4l2Device* device;
    std::uint32_t index;
    int count;
  };
  mutable std::mutex mutex_;
  std::condition_variable changed_;  // a frame, STREAMOFF, an error or an unplug
  std::vector<std::unique_ptr<FakeV4l2Device>> devices_;
  std::map<int, File> files_;
  std::map<void*, Mapping> mappings_;
  int next_fd_ = 100;
};

}  // namespace augrig::test
