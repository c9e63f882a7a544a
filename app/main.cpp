// augrig: the command-line entry point. Everything lives in app/commands.cpp; main only turns
// argv into strings and makes sure nothing escapes as a crash.
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "app/commands.hpp"

int main(int argc, char** argv) {
  try {
    const std::vector<std::string> args(argv + 1, argv + argc);
    return augrig::app::run_cli(args, std::cout, std::cerr);
  } catch (const std::exception& e) {
    std::cerr << "augrig: internal error: " << e.what() << "\n";
  } catch (...) {
    std::cerr << "augrig: internal error\n";
  }
  return augrig::app::kExitRuntime;
}
