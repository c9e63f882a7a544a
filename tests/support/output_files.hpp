// Output folders read back whole, for tests that compare two outputs byte for byte.
#pragma once

#include <filesystem>
#include <map>
#include <string>

namespace augrig::test {

// Every file under `dir` (relative path -> bytes), but `skip`'s.
std::map<std::string, std::string> files_under(const std::filesystem::path& dir,
                                               const std::string& skip = "");

}  // namespace augrig::test
