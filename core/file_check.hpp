// file_check: what every file loader does before it reads a path. On Linux std::ifstream opens a
// directory without complaint and only the first read fails, so a directory given where a file is
// expected came out as a "read error", an empty file or "got nothing (null)". These helpers say
// what is wrong instead: "<prefix><path>: is a directory, expected a file".
#pragma once

#include <string>

#include "core/expected.hpp"

namespace augrig {

// Success unless `path` names a directory (following symbolic links); then the Error
// "<prefix><path>: is a directory, expected a file". A missing or unreadable path passes: the
// caller's open says why it fails.
Expected<void> check_not_directory(const std::string& prefix, const std::string& path);

// The whole content of the file `path`, or an Error "<prefix><path>: ..." that says why not:
// a directory, cannot open (with the system's reason), or a read error. `what` names the file in
// the messages ("rig file", "scenario file").
Expected<std::string> read_text_file(const std::string& prefix, const std::string& path,
                                     const std::string& what);

}  // namespace augrig
