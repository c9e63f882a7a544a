#include "core/yaml_reader.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <set>

namespace augrig::yaml {

std::string join_key(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

std::string location(const Context& c, const YAML::Mark& m) {
  if (m.is_null()) return c.name;
  return c.name + ":" + std::to_string(m.line + 1) + ":" + std::to_string(m.column + 1);
}

void fail_at(const Context& c, const YAML::Mark& m, const std::string& key, const std::string& what) {
  throw ParseFailure{c.prefix + location(c, m) + ": key '" + key + "': " + what};
}

void fail(const Context& c, const YAML::Node& n, const std::string& key, const std::string& what) {
  fail_at(c, n.IsDefined() ? n.Mark() : YAML::Mark::null_mark(), key, what);
}

std::string got(const YAML::Node& n) {
  if (!n.IsDefined() || n.IsNull()) return "got nothing (null)";
  if (n.IsScalar()) return "got '" + n.Scalar() + "'";
  if (n.IsSequence()) return "got a list of " + std::to_string(n.size()) + " element(s)";
  return "got a map";
}

std::string fmt(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v + 0.0);
  return std::string(buf, r.ptr);
}

std::string join(const std::vector<std::string>& items) {
  std::string s;
  for (const auto& i : items) s += (s.empty() ? "" : ", ") + i;
  return s;
}

void expect_map(const Context& c, const YAML::Node& n, const std::string& key, const std::string& what) {
  if (!n.IsMap()) fail(c, n, key, "expected " + what + ", " + got(n));
}

void check_keys(const Context& c, const YAML::Node& map, const std::string& path,
                const std::vector<std::string>& allowed) {
  std::set<std::string> seen;
  for (const auto& kv : map) {
    const std::string k = kv.first.IsScalar() ? kv.first.Scalar() : "?";
    const std::string key = join_key(path, k);
    if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
      fail(c, kv.first, key, "unknown key; allowed keys here: " + join(allowed));
    if (!seen.insert(k).second) fail(c, kv.first, key, "duplicate key");
  }
}

YAML::Node require(const Context& c, const YAML::Node& map, const std::string& path, const std::string& key,
                   const std::string& what) {
  const YAML::Node n = map[key];
  if (!n.IsDefined()) fail(c, map, join_key(path, key), "missing; expected " + what);
  return n;
}

double to_number(const Context& c, const YAML::Node& n, const std::string& key, const std::string& what) {
  double v = 0;
  if (!n.IsScalar() || !YAML::convert<double>::decode(n, v) || !std::isfinite(v))
    fail(c, n, key, "expected " + what + ", " + got(n));
  return v;
}

std::vector<double> to_numbers(const Context& c, const YAML::Node& n, const std::string& key,
                               std::size_t count, const std::string& what) {
  if (!n.IsSequence() || n.size() != count) fail(c, n, key, "expected " + what + ", " + got(n));
  std::vector<double> v;
  for (std::size_t i = 0; i < count; ++i) {
    double x = 0;
    if (!n[i].IsScalar() || !YAML::convert<double>::decode(n[i], x) || !std::isfinite(x))
      fail(c, n[i], key, "expected " + what + ", " + got(n[i]) + " as element " + std::to_string(i));
    v.push_back(x);
  }
  return v;
}

Eigen::Vector3d to_vec3(const Context& c, const YAML::Node& n, const std::string& key,
                        const std::string& what) {
  const auto v = to_numbers(c, n, key, 3, "a list of 3 numbers " + what);
  return {v[0], v[1], v[2]};
}

bool to_bool(const Context& c, const YAML::Node& n, const std::string& key) {
  bool v = false;
  if (!n.IsScalar() || !YAML::convert<bool>::decode(n, v))
    fail(c, n, key, "expected true or false, " + got(n));
  return v;
}

std::string to_string_value(const Context& c, const YAML::Node& n, const std::string& key,
                            const std::string& what) {
  if (!n.IsScalar()) fail(c, n, key, "expected " + what + ", " + got(n));
  return n.Scalar();
}

}  // namespace augrig::yaml
