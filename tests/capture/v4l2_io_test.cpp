// The real V4l2Io (what can be checked on a machine without /dev/video*), and the V4L2 ioctl
// contract the backend relies on, checked against the fake device and, when
// AUGRIG_V4L2_DEVICE=/dev/videoN is set, against that real device (e.g. vivid), so the fake is
// held to the kernel's behaviour.
#include "capture/v4l2_io.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <sys/mman.h>
#include <unistd.h>

#include "capture/v4l2_source.hpp"
#include "tests/support/fake_v4l2_device.hpp"

namespace augrig {
namespace {

// ---------------------------------------------------------------------------------------------
// system_v4l2_io(): forwarding to the kernel

std::string missing_video_node() {
  for (int n = 63;; ++n) {
    const std::string path = "/dev/video" + std::to_string(n);
    if (!std::filesystem::exists(path)) return path;
  }
}

TEST(SystemV4l2Io, OpeningAMissingNodeIsENOENT) {
  const std::string path = missing_video_node();
  errno = 0;
  EXPECT_EQ(system_v4l2_io().open(path.c_str(), O_RDWR | O_NONBLOCK), -1);
  EXPECT_EQ(errno, ENOENT);
}

TEST(SystemV4l2Io, IoctlOnANonV4l2FileIsENOTTY) {
  V4l2Io& io = system_v4l2_io();
  const int fd = io.open("/dev/null", O_RDWR);
  ASSERT_GE(fd, 0);
  v4l2_capability cap{};
  errno = 0;
  EXPECT_EQ(io.ioctl(fd, VIDIOC_QUERYCAP, &cap), -1);
  EXPECT_EQ(errno, ENOTTY);
  EXPECT_EQ(io.close(fd), 0);
  errno = 0;
  EXPECT_EQ(io.close(fd), -1);
  EXPECT_EQ(errno, EBADF);
}

TEST(SystemV4l2Io, MmapAndPollForwardToTheKernel) {
  V4l2Io& io = system_v4l2_io();
  void* p = io.mmap(nullptr, 4096, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(p, MAP_FAILED);
  static_cast<char*>(p)[10] = 42;
  EXPECT_EQ(io.munmap(p, 4096), 0);

  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  pollfd pfd{fds[0], POLLIN, 0};
  EXPECT_EQ(io.poll(&pfd, 1, 0), 0);  // nothing to read
  ASSERT_EQ(::write(fds[1], "x", 1), 1);
  EXPECT_EQ(io.poll(&pfd, 1, 1000), 1);
  EXPECT_TRUE(pfd.revents & POLLIN);
  ::close(fds[0]);
  ::close(fds[1]);
}

TEST(SystemV4l2Io, ListsExactlyTheVideoNodesInNumericOrder) {
  // Independent listing of /dev: videoN names only (not video-foo, not vbi0), numeric order.
  std::vector<std::pair<int, std::string>> expected;
  const std::regex name("video([0-9]+)");
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
    std::smatch m;
    const std::string file = entry.path().filename().string();
    if (std::regex_match(file, m, name)) expected.emplace_back(std::stoi(m[1]), "/dev/" + file);
  }
  std::sort(expected.begin(), expected.end());
  std::vector<std::string> expected_paths;
  for (auto& [n, p] : expected) expected_paths.push_back(p);
  EXPECT_EQ(system_v4l2_io().list_device_paths(), expected_paths);
}

TEST(SystemV4l2Io, ListingDevicesOnThisMachineSucceeds) {
  auto devices = list_v4l2_devices();
  ASSERT_TRUE(devices) << devices.error().message;
  if (system_v4l2_io().list_device_paths().empty()) {
    EXPECT_TRUE(devices->empty());
  }
  for (const auto& d : *devices) EXPECT_FALSE(d.path.empty());
}

// xioctl(): a signal before the driver did anything is retried; other errors are not.
class ScriptedIo final : public V4l2Io {
 public:
  std::vector<int> errnos;  // per call: 0 succeeds
  int calls = 0;
  int open(const char*, int) override { return -1; }
  int close(int) override { return 0; }
  int ioctl(int, unsigned long, void*) override {
    const int e = calls < static_cast<int>(errnos.size()) ? errnos[calls] : 0;
    ++calls;
    if (e == 0) return 0;
    errno = e;
    return -1;
  }
  void* mmap(void*, std::size_t, int, int, int, off_t) override { return MAP_FAILED; }
  int munmap(void*, std::size_t) override { return 0; }
  int poll(pollfd*, nfds_t, int) override { return 0; }
  std::vector<std::string> list_device_paths() override { return {}; }
};

TEST(Xioctl, RetriesEINTROnly) {
  ScriptedIo io;
  io.errnos = {EINTR, EINTR, 0};
  EXPECT_EQ(xioctl(io, 3, VIDIOC_QUERYCAP, nullptr), 0);
  EXPECT_EQ(io.calls, 3);

  ScriptedIo busy;
  busy.errnos = {EBUSY, 0};
  errno = 0;
  EXPECT_EQ(xioctl(busy, 3, VIDIOC_QUERYCAP, nullptr), -1);
  EXPECT_EQ(errno, EBUSY);
  EXPECT_EQ(busy.calls, 1);
}

// ---------------------------------------------------------------------------------------------
// The ioctl contract, on the fake and (optionally) on a real device.

struct Target {
  V4l2Io* io = nullptr;
  std::string path;
  test::FakeV4l2Device* fake = nullptr;  // null for a real device
};

class V4l2Contract : public ::testing::TestWithParam<bool> {
 protected:
  void SetUp() override {
    if (GetParam()) {
      const char* dev = std::getenv("AUGRIG_V4L2_DEVICE");
      if (dev == nullptr || *dev == '\0') {
        GTEST_SKIP() << "set AUGRIG_V4L2_DEVICE=/dev/videoN (e.g. vivid: sudo modprobe vivid) to run the "
                        "V4L2 contract against a real device";
      }
      target_ = {&system_v4l2_io(), dev, nullptr};
    } else {
      test::FakeV4l2Config config;
      config.formats = {test::fake_format(V4L2_PIX_FMT_YUYV), test::fake_format(V4L2_PIX_FMT_GREY)};
      target_ = {&fake_io_, config.path, &fake_io_.add_device(config)};
    }
    fd_ = target_.io->open(target_.path.c_str(), O_RDWR | O_NONBLOCK);
    ASSERT_GE(fd_, 0) << target_.path << ": " << std::strerror(errno);
  }
  void TearDown() override {
    for (auto& [p, len] : maps_) target_.io->munmap(p, len);
    if (fd_ >= 0) target_.io->close(fd_);
  }
  int call(unsigned long request, void* arg) {
    errno = 0;
    const int r = target_.io->ioctl(fd_, request, arg);
    return r == 0 ? 0 : errno;
  }
  // REQBUFS + QUERYBUF + mmap; returns the granted count.
  std::uint32_t allocate(std::uint32_t count, std::uint32_t* caps = nullptr) {
    v4l2_requestbuffers req{};
    req.count = count;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    EXPECT_EQ(call(VIDIOC_REQBUFS, &req), 0);
    if (caps) *caps = req.capabilities;
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer b = buffer(i);
      EXPECT_EQ(call(VIDIOC_QUERYBUF, &b), 0);
      void* p = target_.io->mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, b.m.offset);
      EXPECT_NE(p, MAP_FAILED);
      if (p != MAP_FAILED) maps_.emplace_back(p, b.length);
    }
    return req.count;
  }
  static v4l2_buffer buffer(std::uint32_t index) {
    v4l2_buffer b{};
    b.index = index;
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    return b;
  }

  test::FakeV4l2Io fake_io_;
  Target target_;
  int fd_ = -1;
  std::vector<std::pair<void*, std::size_t>> maps_;
};

TEST_P(V4l2Contract, QuerycapSaysCaptureAndStreaming) {
  v4l2_capability cap{};
  ASSERT_EQ(call(VIDIOC_QUERYCAP, &cap), 0);
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  EXPECT_TRUE(caps & V4L2_CAP_VIDEO_CAPTURE);
  EXPECT_TRUE(caps & V4L2_CAP_STREAMING);
}

TEST_P(V4l2Contract, EnumFmtEndsWithEINVAL) {
  std::uint32_t n = 0;
  for (;; ++n) {
    v4l2_fmtdesc d{};
    d.index = n;
    d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    const int e = call(VIDIOC_ENUM_FMT, &d);
    if (e != 0) {
      EXPECT_EQ(e, EINVAL);
      break;
    }
    ASSERT_LT(n, 1000u);
  }
  EXPECT_GT(n, 0u);
}

TEST_P(V4l2Contract, SFmtSubstitutesAnUnsupportedFourccInsteadOfFailing) {
  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  ASSERT_EQ(call(VIDIOC_G_FMT, &f), 0);
  f.fmt.pix.pixelformat = v4l2_fourcc('Z', 'Z', 'Z', 'Z');
  ASSERT_EQ(call(VIDIOC_TRY_FMT, &f), 0);
  EXPECT_NE(f.fmt.pix.pixelformat, v4l2_fourcc('Z', 'Z', 'Z', 'Z'));
  EXPECT_GT(f.fmt.pix.width, 0u);

  v4l2_format bad_type{};
  bad_type.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
  EXPECT_EQ(call(VIDIOC_TRY_FMT, &bad_type), EINVAL);
}

TEST_P(V4l2Contract, BufferLifecycle) {
  std::uint32_t caps = 0;
  const std::uint32_t n = allocate(2, &caps);
  ASSERT_GE(n, 1u);

  v4l2_buffer past_end = buffer(n);
  EXPECT_EQ(call(VIDIOC_QUERYBUF, &past_end), EINVAL);
  EXPECT_EQ(call(VIDIOC_QBUF, &past_end), EINVAL);

  v4l2_buffer dq = buffer(0);
  EXPECT_EQ(call(VIDIOC_DQBUF, &dq), EINVAL) << "DQBUF before STREAMON";

  for (std::uint32_t i = 0; i < n; ++i) {
    v4l2_buffer b = buffer(i);
    ASSERT_EQ(call(VIDIOC_QBUF, &b), 0);
  }
  v4l2_buffer again = buffer(0);
  EXPECT_EQ(call(VIDIOC_QBUF, &again), EINVAL) << "QBUF of a buffer the driver already has";

  // S_FMT is refused once buffers exist.
  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  ASSERT_EQ(call(VIDIOC_G_FMT, &f), 0);
  EXPECT_EQ(call(VIDIOC_S_FMT, &f), EBUSY);

  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  ASSERT_EQ(call(VIDIOC_STREAMON, &type), 0);
  if (target_.fake != nullptr) {
    v4l2_buffer empty = buffer(0);
    EXPECT_EQ(call(VIDIOC_DQBUF, &empty), EAGAIN) << "non-blocking DQBUF with nothing captured";
    pollfd p{fd_, POLLIN, 0};
    EXPECT_EQ(target_.io->poll(&p, 1, 0), 0);
  }
  ASSERT_EQ(call(VIDIOC_STREAMOFF, &type), 0);
  // STREAMOFF gives every buffer back to the application: none queued or done, all queueable.
  for (std::uint32_t i = 0; i < n; ++i) {
    v4l2_buffer b = buffer(i);
    ASSERT_EQ(call(VIDIOC_QUERYBUF, &b), 0);
    EXPECT_EQ(b.flags & (V4L2_BUF_FLAG_QUEUED | V4L2_BUF_FLAG_DONE), 0u) << "buffer " << i;
    EXPECT_TRUE(b.flags & V4L2_BUF_FLAG_MAPPED);
    EXPECT_EQ(call(VIDIOC_QBUF, &b), 0);
  }
  // Not streaming: poll reports an error at once (videobuf2).
  pollfd p{fd_, POLLIN, 0};
  EXPECT_EQ(target_.io->poll(&p, 1, 0), 1);
  EXPECT_TRUE(p.revents & POLLERR);

  // REQBUFS 0 frees; while buffers are mapped only drivers with orphaned-buffer support allow it.
  v4l2_requestbuffers none{};
  none.count = 0;
  none.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  none.memory = V4L2_MEMORY_MMAP;
  EXPECT_EQ(call(VIDIOC_REQBUFS, &none), (caps & V4L2_BUF_CAP_SUPPORTS_ORPHANED_BUFS) ? 0 : EBUSY);
  for (auto& [ptr, len] : maps_) EXPECT_EQ(target_.io->munmap(ptr, len), 0);
  maps_.clear();
  EXPECT_EQ(call(VIDIOC_REQBUFS, &none), 0);
  v4l2_buffer gone = buffer(0);
  EXPECT_EQ(call(VIDIOC_QUERYBUF, &gone), EINVAL);
}

TEST_P(V4l2Contract, UnknownControlsAreEINVAL) {
  v4l2_queryctrl q{};
  q.id = V4L2_CID_PRIVATE_BASE + 0x7777;
  EXPECT_EQ(call(VIDIOC_QUERYCTRL, &q), EINVAL);
  v4l2_control c{V4L2_CID_PRIVATE_BASE + 0x7777, 0};
  EXPECT_EQ(call(VIDIOC_G_CTRL, &c), EINVAL);
  EXPECT_EQ(call(VIDIOC_S_CTRL, &c), EINVAL);
}

INSTANTIATE_TEST_SUITE_P(FakeAndReal, V4l2Contract, ::testing::Values(false, true),
                         [](const auto& info) { return info.param ? "RealDevice" : "Fake"; });

// ---------------------------------------------------------------------------------------------
// The fake's own behaviour beyond what a real device can be made to show on demand.

TEST(FakeV4l2Io, ControlsFollowTheDocumentedErrors) {
  test::FakeV4l2Io io;
  auto& dev = io.add_device();
  const int fd = io.open("/dev/video0", O_RDWR | O_NONBLOCK);
  ASSERT_GE(fd, 0);
  auto s_ctrl = [&](std::uint32_t id, std::int32_t v) {
    v4l2_control c{id, v};
    errno = 0;
    return io.ioctl(fd, VIDIOC_S_CTRL, &c) == 0 ? 0 : errno;
  };
  EXPECT_EQ(s_ctrl(V4L2_CID_EXPOSURE_ABSOLUTE, 100), EACCES) << "inactive while auto exposure is on";
  EXPECT_EQ(s_ctrl(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_SHUTTER_PRIORITY), EINVAL) << "no such menu item";
  EXPECT_EQ(s_ctrl(V4L2_CID_EXPOSURE_AUTO, 7), ERANGE);
  EXPECT_EQ(s_ctrl(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL), 0);
  EXPECT_EQ(s_ctrl(V4L2_CID_EXPOSURE_ABSOLUTE, 100), 0);
  EXPECT_EQ(s_ctrl(V4L2_CID_EXPOSURE_ABSOLUTE, 5001), ERANGE);
  EXPECT_EQ(dev.control(V4L2_CID_EXPOSURE_ABSOLUTE), 100);

  // Enumeration with V4L2_CTRL_FLAG_NEXT_CTRL visits every control once, in id order.
  std::vector<std::uint32_t> ids;
  v4l2_queryctrl q{};
  q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  while (io.ioctl(fd, VIDIOC_QUERYCTRL, &q) == 0) {
    ids.push_back(q.id);
    q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  EXPECT_EQ(errno, EINVAL);
  EXPECT_EQ(ids.size(), dev.config().controls.size());
  EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end()));
  io.close(fd);
}

TEST(FakeV4l2Io, AFrameWithNoQueuedBufferIsLostAndItsSequenceSkipped) {
  test::FakeV4l2Io io;
  auto& dev = io.add_device();
  const int fd = io.open("/dev/video0", O_RDWR | O_NONBLOCK);
  v4l2_requestbuffers req{};
  req.count = 2;
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  ASSERT_EQ(io.ioctl(fd, VIDIOC_REQBUFS, &req), 0);
  EXPECT_FALSE(dev.push_frame({1, 2, 3})) << "not streaming";
  v4l2_buffer b{};
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  ASSERT_EQ(io.ioctl(fd, VIDIOC_QBUF, &b), 0);
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  ASSERT_EQ(io.ioctl(fd, VIDIOC_STREAMON, &type), 0);
  EXPECT_TRUE(dev.push_frame({1, 2, 3}, 1'000'000));
  EXPECT_FALSE(dev.push_frame({4, 5, 6}, 2'000'000));  // no buffer left
  pollfd p{fd, POLLIN, 0};
  EXPECT_EQ(io.poll(&p, 1, 0), 1);
  EXPECT_TRUE(p.revents & POLLIN);
  ASSERT_EQ(io.ioctl(fd, VIDIOC_DQBUF, &b), 0);
  EXPECT_EQ(b.sequence, 0u);
  EXPECT_EQ(b.bytesused, 3u);
  EXPECT_EQ(b.timestamp.tv_usec, 1000);
  EXPECT_EQ(b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK,
            static_cast<std::uint32_t>(V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC));
  ASSERT_EQ(io.ioctl(fd, VIDIOC_QBUF, &b), 0);
  EXPECT_TRUE(dev.push_frame({7}));
  ASSERT_EQ(io.ioctl(fd, VIDIOC_DQBUF, &b), 0);
  EXPECT_EQ(b.sequence, 2u) << "sequence 1 was lost";

  dev.unplug();
  errno = 0;
  EXPECT_EQ(io.ioctl(fd, VIDIOC_QBUF, &b), -1);
  EXPECT_EQ(errno, ENODEV);
  EXPECT_EQ(io.poll(&p, 1, 1000), 1);
  EXPECT_TRUE(p.revents & POLLERR);
  EXPECT_TRUE(p.revents & POLLHUP);
  EXPECT_EQ(io.open("/dev/video0", O_RDWR), -1);
  EXPECT_EQ(errno, ENOENT);
  EXPECT_TRUE(io.list_device_paths().empty());
  EXPECT_EQ(io.close(fd), 0);
}

}  // namespace
}  // namespace augrig
