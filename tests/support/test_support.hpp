// Helpers shared by the tests: where test data lives and where outputs (diff images) go.
#pragma once

#include <string>

namespace augrig::test {

// Absolute path of a file under tests/data.
std::string data_path(const std::string& relative);
// A fresh directory under build/test-output/<name> (created, emptied).
std::string output_dir(const std::string& name);
// Path of the built augrig binary.
std::string augrig_binary();
// Runs a shell command, returns its exit status and fills `output` with stdout+stderr.
int run_command(const std::string& command, std::string* output = nullptr);
// Runs the augrig binary with `args`; `output` gets its stdout and stderr together.
int run_augrig(const std::string& args, std::string* output = nullptr);

}  // namespace augrig::test
