#include "tests/support/output_files.hpp"

#include <fstream>
#include <iterator>

namespace augrig::test {

std::map<std::string, std::string> files_under(const std::filesystem::path& dir, const std::string& skip) {
  std::map<std::string, std::string> m;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = e.path().lexically_relative(dir).string();
    if (!skip.empty() && rel == skip) continue;
    std::ifstream in(e.path(), std::ios::binary);
    m[rel] = std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  return m;
}

}  // namespace augrig::test
