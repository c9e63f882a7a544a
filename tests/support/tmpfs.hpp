// A small tmpfs mounted for one test: a real file system that fills up (disk-full tests). Needs
// root (CI and the development machines run as root); where mount(2) is refused the test skips
// with the reason.
#pragma once

#include <cstdint>
#include <string>

namespace augrig::test {

class ScopedTmpfs {
 public:
  // Mounts a tmpfs of `bytes` at `dir` (created, and emptied first).
  ScopedTmpfs(const std::string& dir, std::uint64_t bytes);
  ~ScopedTmpfs();
  ScopedTmpfs(const ScopedTmpfs&) = delete;
  ScopedTmpfs& operator=(const ScopedTmpfs&) = delete;

  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }  // why it is not mounted
  const std::string& dir() const { return dir_; }
  // Fills the file system with one file, leaving about `leave_bytes` free.
  void fill(std::uint64_t leave_bytes) const;
  std::uint64_t free_bytes() const;

 private:
  std::string dir_, error_;
  bool mounted_ = false;
};

}  // namespace augrig::test
