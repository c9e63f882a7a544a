// yaml_reader: helpers for reading YAML configuration (rig, scene, scenario files) with errors that
// name the file, line, column and key path and say what was expected:
//   "rig::load(): rig.yaml:12:5: key 'cameras[1].intrinsics': expected a list of 4 numbers, got '3'"
// Parsers throw yaml::ParseFailure from deep inside; their public entry points catch it (and every
// YAML exception) and return an Error, so nothing escapes as an exception.
#pragma once

#include <exception>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

#include "core/expected.hpp"

namespace augrig::yaml {

struct ParseFailure {
  std::string message;
};

struct Context {
  std::string prefix;  // "rig::load(): ", "scene::parse(): ", ...
  std::string name;    // the file name as given, for messages
};

std::string join_key(const std::string& path, const std::string& key);
std::string location(const Context& c, const YAML::Mark& m);  // "file:line:col" (1-based)
[[noreturn]] void fail_at(const Context& c, const YAML::Mark& m, const std::string& key,
                          const std::string& what);
[[noreturn]] void fail(const Context& c, const YAML::Node& n, const std::string& key,
                       const std::string& what);
// "got ..." part of a message: shows the user what the parser actually saw.
std::string got(const YAML::Node& n);
// Shortest text that reads back to exactly `v` (-0 printed as 0).
std::string fmt(double v);
std::string join(const std::vector<std::string>& items);

void expect_map(const Context& c, const YAML::Node& n, const std::string& key, const std::string& what);
// Rejects unknown (typo) and duplicate keys, naming the allowed ones so the fix is obvious.
void check_keys(const Context& c, const YAML::Node& map, const std::string& path,
                const std::vector<std::string>& allowed);
YAML::Node require(const Context& c, const YAML::Node& map, const std::string& path, const std::string& key,
                   const std::string& what);
double to_number(const Context& c, const YAML::Node& n, const std::string& key, const std::string& what);
std::vector<double> to_numbers(const Context& c, const YAML::Node& n, const std::string& key,
                               std::size_t count, const std::string& what);
Eigen::Vector3d to_vec3(const Context& c, const YAML::Node& n, const std::string& key,
                        const std::string& what);
bool to_bool(const Context& c, const YAML::Node& n, const std::string& key);
std::string to_string_value(const Context& c, const YAML::Node& n, const std::string& key,
                            const std::string& what);

// Runs a parser body and turns whatever it throws (ParseFailure, YAML syntax or other errors) into
// an Error that names the file and, where YAML knows it, the line.
template <typename F>
auto guarded(const Context& c, F&& body) -> Expected<decltype(body())> {
  try {
    return body();
  } catch (const ParseFailure& e) {
    return Error{e.message};
  } catch (const YAML::ParserException& e) {
    return make_error(c.prefix, location(c, e.mark), ": YAML syntax error: ", e.msg);
  } catch (const YAML::Exception& e) {
    return make_error(c.prefix, location(c, e.mark), ": ", e.msg);
  } catch (const std::exception& e) {
    return make_error(c.prefix, c.name, ": ", e.what());
  }
}

}  // namespace augrig::yaml
