// Helpers shared by the libFuzzer targets (docs/RELIABILITY.md, "Fuzzing").
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>
#include <string>
#include <string_view>

#include <unistd.h>

namespace augrig::fuzz {

// Reads the fuzzer's bytes front to back: selector bytes and length-prefixed pieces, so that one
// target can drive several parsers or several inputs. Past the end everything reads as zero/empty.
class Input {
 public:
  Input(const std::uint8_t* data, std::size_t size) : p_(data), n_(size) {}
  std::size_t left() const { return n_; }
  std::uint8_t byte() {
    if (n_ == 0) return 0;
    --n_;
    return *p_++;
  }
  template <typename T>
  T value() {  // little-endian bytes of T, zero-padded at the end
    std::uint8_t b[sizeof(T)] = {};
    const std::size_t k = n_ < sizeof(T) ? n_ : sizeof(T);
    std::memcpy(b, p_, k);
    p_ += k;
    n_ -= k;
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
  }
  std::string_view bytes(std::size_t k) {
    if (k > n_) k = n_;
    std::string_view s(reinterpret_cast<const char*>(p_), k);
    p_ += k;
    n_ -= k;
    return s;
  }
  std::string_view rest() { return bytes(n_); }
  // Up to the separator (consumed, not returned), or the rest.
  std::string_view until(std::string_view sep) {
    const std::string_view all(reinterpret_cast<const char*>(p_), n_);
    const std::size_t at = all.find(sep);
    if (at == std::string_view::npos) return rest();
    const std::string_view s = bytes(at);
    bytes(sep.size());
    return s;
  }

 private:
  const std::uint8_t* p_;
  std::size_t n_;
};

// AUGRIG_FUZZ_VERBOSE=1: targets print what their parsers said, to check that seeds get as far
// as meant (run the target on one seed file).
inline bool verbose() {
  static const bool v = std::getenv("AUGRIG_FUZZ_VERBOSE") != nullptr;
  return v;
}

// Loaders that only take a path read the input from this file: one per process and name, in /tmp,
// rewritten on every run (the name keeps the extension the loader dispatches on).
inline std::string temp_path(const std::string& name) {
  return "/tmp/augrig-fuzz-" + std::to_string(::getpid()) + "-" + name;
}

// Unlinks the temp files when the fuzzer exits.
struct TempFiles {
  std::set<std::string> paths;
  ~TempFiles() {
    for (const auto& p : paths) ::unlink(p.c_str());
  }
};

inline std::string write_temp(const std::string& name, std::string_view bytes) {
  static TempFiles files;
  const std::string path = temp_path(name);
  files.paths.insert(path);
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path;
}

}  // namespace augrig::fuzz
