#include "core/file_check.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

namespace augrig {

Expected<void> check_not_directory(const std::string& prefix, const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    return make_error(prefix, path, ": is a directory, expected a file");
  return {};
}

Expected<std::string> read_text_file(const std::string& prefix, const std::string& path,
                                     const std::string& what) {
  if (auto d = check_not_directory(prefix, path); !d) return d.error();
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(prefix, path, ": cannot open the ", what, " (", std::strerror(errno), ")");
  std::stringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return make_error(prefix, path, ": cannot read the ", what, " (read error)");
  return ss.str();
}

}  // namespace augrig
