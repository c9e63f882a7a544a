// V4l2Io: the thin interface between the V4L2 capture code and the kernel. Every system call the
// backend makes (open, close, ioctl, mmap, munmap, poll) and the listing of /dev/video* nodes goes
// through it, so tests can drive the real driver code (capture/v4l2_source.cpp) against a fake
// device (tests/support/fake_v4l2_device.hpp) that follows the kernel's documented behaviour.
//
// The calls have the semantics of the real ones: they return -1 (MAP_FAILED for mmap) and set errno
// on failure. system_v4l2_io() forwards straight to the kernel: direct ioctls, no libv4l2 wrappers
// (which would convert formats behind our back and hide the driver's own timestamps and flags).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <poll.h>
#include <sys/types.h>

namespace augrig {

class V4l2Io {
 public:
  virtual ~V4l2Io() = default;
  virtual int open(const char* path, int flags) = 0;
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  virtual void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) = 0;
  virtual int munmap(void* addr, std::size_t length) = 0;
  virtual int poll(pollfd* fds, nfds_t nfds, int timeout_ms) = 0;
  // Paths of the V4L2 video nodes present now (/dev/video0, /dev/video1, ... in numeric order);
  // empty when there are none.
  virtual std::vector<std::string> list_device_paths() = 0;
};

// The kernel: forwards to ::open, ::close, ::ioctl, ::mmap, ::munmap, ::poll and lists /dev.
V4l2Io& system_v4l2_io();

// ioctl() repeated while it fails with EINTR (a signal arrived before the driver did anything).
int xioctl(V4l2Io& io, int fd, unsigned long request, void* arg);

}  // namespace augrig
