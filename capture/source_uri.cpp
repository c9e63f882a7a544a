#include "capture/source_uri.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <sstream>

namespace augrig {
namespace {

Error uri_error(std::string_view text, const std::string& what) {
  return make_error("source URI '", std::string(text), "': ", what);
}

// "k=v&k2=v2" (or ',' separated inside stereo's brackets) into `out`.
Status parse_params(std::string_view text, std::string_view all, char sep,
                    std::map<std::string, std::string>& out) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find(sep, pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view item = text.substr(pos, end - pos);
    const std::size_t eq = item.find('=');
    if (item.empty() || eq == 0)
      return uri_error(all, "expected key=value parameters, got '" + std::string(item) + "'");
    const std::string key(item.substr(0, eq));
    if (out.count(key)) return uri_error(all, "parameter '" + key + "' given twice");
    out[key] = eq == std::string_view::npos ? "1" : std::string(item.substr(eq + 1));
    pos = end + 1;
  }
  return {};
}

// The text inside a {...} group starting at `pos` (braces may nest); advances `pos` past it.
Expected<std::string_view> brace_group(std::string_view text, std::size_t& pos, std::string_view all) {
  if (pos >= text.size() || text[pos] != '{') return uri_error(all, "expected '{' to open a camera URI");
  int depth = 0;
  for (std::size_t i = pos; i < text.size(); ++i) {
    if (text[i] == '{') ++depth;
    if (text[i] == '}' && --depth == 0) {
      const std::string_view inner = text.substr(pos + 1, i - pos - 1);
      pos = i + 1;
      return inner;
    }
  }
  return uri_error(all, "unbalanced '{'");
}

}  // namespace

std::string SourceUri::get(const std::string& key, const std::string& fallback) const {
  const auto it = params.find(key);
  return it == params.end() ? fallback : it->second;
}

namespace {
std::string range_text(double lo, double hi) {
  std::ostringstream o;
  o << std::setprecision(15) << "[" << lo << ", " << hi << "]";
  return o.str();
}
}  // namespace

Expected<double> SourceUri::get_number(const std::string& key, double fallback, double lo, double hi) const {
  const auto it = params.find(key);
  if (it == params.end()) return fallback;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  // strtod reads "nan", "inf" and 1e999 (as inf): none is a setting, and each would overflow
  // whatever converts it to nanoseconds or pixels.
  if (it->second.empty() || *end != '\0' || errno != 0 || !std::isfinite(v) || v < lo || v > hi)
    return uri_error(text,
                     key + ": expected a number in " + range_text(lo, hi) + ", got '" + it->second + "'");
  return v;
}

Expected<long long> SourceUri::get_integer(const std::string& key, long long fallback, long long lo,
                                           long long hi) const {
  const auto it = params.find(key);
  if (it == params.end()) return fallback;
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(it->second.c_str(), &end, 10);
  if (it->second.empty() || *end != '\0' || errno != 0 || v < lo || v > hi)
    return uri_error(text, key + ": expected an integer in [" + std::to_string(lo) + ", " +
                               std::to_string(hi) + "], got '" + it->second + "'");
  return v;
}

Status SourceUri::check_known(std::initializer_list<std::string_view> known) const {
  std::string unknown, expected;
  for (std::string_view k : known) expected += (expected.empty() ? "" : ", ") + std::string(k);
  for (const auto& [k, v] : params) {
    bool ok = false;
    for (std::string_view kk : known) ok = ok || kk == k;
    if (!ok) unknown += (unknown.empty() ? "" : ", ") + k;
  }
  if (unknown.empty()) return {};
  return uri_error(text, "unknown parameter " + unknown + " for " + scheme + "://; expected " +
                             (expected.empty() ? std::string("none") : expected));
}

Expected<SourceUri> parse_source_uri(std::string_view text) {
  SourceUri uri;
  uri.text = std::string(text);
  if (text.rfind("stereo:", 0) == 0) {
    // stereo:[params]//{left}{right}
    uri.scheme = "stereo";
    std::size_t pos = 7;
    if (pos < text.size() && text[pos] == '[') {
      const std::size_t close = text.find(']', pos);
      if (close == std::string_view::npos) return uri_error(text, "expected ']' to close the parameters");
      if (Status s = parse_params(text.substr(pos + 1, close - pos - 1), text, ',', uri.params); !s)
        return s.error();
      pos = close + 1;
    }
    if (text.substr(pos, 2) != "//")
      return uri_error(text, "expected stereo:[params]//{left URI}{right URI}");
    pos += 2;
    for (int i = 0; i < 2; ++i) {
      auto inner = brace_group(text, pos, text);
      if (!inner) return inner.error();
      auto child = parse_source_uri(*inner);
      if (!child) return child.error();
      if (child->scheme == "stereo") return uri_error(text, "a stereo source cannot contain another");
      uri.children.push_back(std::move(*child));
    }
    if (pos != text.size()) return uri_error(text, "unexpected text after the right camera's URI");
    return uri;
  }
  const std::size_t sep = text.find("://");
  if (sep == std::string_view::npos || sep == 0)
    return uri_error(
        text, "expected scheme://target, with scheme aravis, v4l2, sim, replay, or stereo:[..]//{..}{..}");
  uri.scheme = std::string(text.substr(0, sep));
  std::string_view rest = text.substr(sep + 3);
  const std::size_t q = rest.find('?');
  uri.target = std::string(rest.substr(0, q));
  if (q != std::string_view::npos) {
    if (Status s = parse_params(rest.substr(q + 1), text, '&', uri.params); !s) return s.error();
  }
  if (uri.target.empty()) return uri_error(text, "expected a target after " + uri.scheme + "://");
  return uri;
}

}  // namespace augrig
