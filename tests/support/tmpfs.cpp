#include "tests/support/tmpfs.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

#include <fcntl.h>
#include <sys/mount.h>
#include <sys/statvfs.h>
#include <unistd.h>

namespace augrig::test {

ScopedTmpfs::ScopedTmpfs(const std::string& dir, std::uint64_t bytes) : dir_(dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  ::umount2(dir.c_str(), MNT_DETACH);  // a run killed before its unmount left one here
  fs::remove_all(dir, ec);
  fs::create_directories(dir, ec);
  const std::string opts = "size=" + std::to_string(bytes) + ",mode=0755";
  if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, opts.c_str()) != 0) {
    error_ = "mount -t tmpfs -o " + opts + " " + dir + ": " + std::strerror(errno) +
             " (disk-full tests need root)";
    return;
  }
  mounted_ = true;
}

ScopedTmpfs::~ScopedTmpfs() {
  if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
}

std::uint64_t ScopedTmpfs::free_bytes() const {
  struct statvfs v {};
  if (statvfs(dir_.c_str(), &v) != 0) return 0;
  return static_cast<std::uint64_t>(v.f_bavail) * v.f_frsize;
}

void ScopedTmpfs::fill(std::uint64_t leave_bytes) const {
  const std::string path = dir_ + "/filler";
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return;
  const std::vector<char> block(4096, 'x');
  while (free_bytes() > leave_bytes + block.size())
    if (::write(fd, block.data(), block.size()) <= 0) break;
  ::close(fd);
}

}  // namespace augrig::test
