#include "capture/v4l2_io.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <dirent.h>
#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace augrig {
namespace {

class SystemV4l2Io final : public V4l2Io {
 public:
  int open(const char* path, int flags) override { return ::open(path, flags); }
  int close(int fd) override { return ::close(fd); }
  int ioctl(int fd, unsigned long request, void* arg) override { return ::ioctl(fd, request, arg); }
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd, off_t offset) override {
    return ::mmap(addr, length, prot, flags, fd, offset);
  }
  int munmap(void* addr, std::size_t length) override { return ::munmap(addr, length); }
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override { return ::poll(fds, nfds, timeout_ms); }

  std::vector<std::string> list_device_paths() override {
    // udev names every V4L2 video node /dev/videoN; radio, vbi, sub-device and media nodes have
    // other names and are not capture devices.
    std::vector<std::pair<long, std::string>> found;
    DIR* dir = ::opendir("/dev");
    if (dir == nullptr) return {};
    while (const dirent* entry = ::readdir(dir)) {
      const char* name = entry->d_name;
      if (std::strncmp(name, "video", 5) != 0 || name[5] == '\0') continue;
      char* end = nullptr;
      const long n = std::strtol(name + 5, &end, 10);
      if (*end != '\0' || name[5] < '0' || name[5] > '9') continue;
      found.emplace_back(n, std::string("/dev/") + name);
    }
    ::closedir(dir);
    std::sort(found.begin(), found.end());
    std::vector<std::string> paths;
    for (auto& [n, path] : found) paths.push_back(std::move(path));
    return paths;
  }
};

}  // namespace

V4l2Io& system_v4l2_io() {
  static SystemV4l2Io io;
  return io;
}

int xioctl(V4l2Io& io, int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = io.ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

}  // namespace augrig
