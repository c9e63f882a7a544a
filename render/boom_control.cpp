#include "render/boom_control.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/file_check.hpp"
#include "core/pose.hpp"

namespace augrig {

Eigen::Vector3d nozzle_tip_body(const Eigen::Vector3d& pivot_body_m, const BoomDimensions& boom,
                                const BoomArticulation& a) {
  return boom_pose(pivot_body_m, a) * Eigen::Vector3d(boom.nozzle_tip_m(a.extension_m), 0.0, 0.0);
}

BoomCommand clamp_to_limits(const BoomArticulation& a, const BoomLimits& l) {
  BoomCommand c;
  c.articulation.elevation_rad = std::clamp(a.elevation_rad, l.elevation_min_rad, l.elevation_max_rad);
  c.articulation.azimuth_rad = std::clamp(a.azimuth_rad, l.azimuth_min_rad, l.azimuth_max_rad);
  c.articulation.extension_m = std::clamp(a.extension_m, l.extension_min_m, l.extension_max_m);
  c.clamped = c.articulation.elevation_rad != a.elevation_rad ||
              c.articulation.azimuth_rad != a.azimuth_rad || c.articulation.extension_m != a.extension_m;
  return c;
}

BoomCommand track_point(const Eigen::Vector3d& target_body_m, const Eigen::Vector3d& pivot_body_m,
                        const BoomDimensions& boom, const BoomLimits& limits) {
  // boom_pose() points the boom's x axis along (-cos az cos el, sin az cos el, sin el) in the body
  // frame; invert that for the direction from the pivot to the target.
  const Eigen::Vector3d v = target_body_m - pivot_body_m;
  const double range_m = v.norm();
  BoomArticulation want;
  if (range_m > 1e-9) {
    want.elevation_rad = std::asin(std::clamp(v.z() / range_m, -1.0, 1.0));
    want.azimuth_rad = std::atan2(v.y(), -v.x());
  }
  want.extension_m = range_m - boom.nozzle_tip_m(0.0);
  BoomCommand c = clamp_to_limits(want, limits);
  c.miss_m = (nozzle_tip_body(pivot_body_m, boom, c.articulation) - target_body_m).norm();
  return c;
}

BoomArticulation BoomScript::at(double t_s) const {
  if (points.empty()) return {};
  if (t_s <= points.front().t_s) return points.front().articulation;
  if (t_s >= points.back().t_s) return points.back().articulation;
  const auto it = std::upper_bound(points.begin(), points.end(), t_s,
                                   [](double t, const BoomScriptPoint& p) { return t < p.t_s; });
  const BoomScriptPoint& b = *it;
  const BoomScriptPoint& a = *(it - 1);
  const double w = (t_s - a.t_s) / (b.t_s - a.t_s);
  BoomArticulation r;
  r.elevation_rad =
      a.articulation.elevation_rad + w * (b.articulation.elevation_rad - a.articulation.elevation_rad);
  r.azimuth_rad = a.articulation.azimuth_rad + w * (b.articulation.azimuth_rad - a.articulation.azimuth_rad);
  r.extension_m = a.articulation.extension_m + w * (b.articulation.extension_m - a.articulation.extension_m);
  return r;
}

namespace {

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream s(line);
  while (std::getline(s, field, ',')) out.push_back(field);
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

bool parse_double(std::string text, double& v) {
  text.erase(0, text.find_first_not_of(" \t"));
  text.erase(text.find_last_not_of(" \t\r") + 1);
  if (text.empty()) return false;
  char* end = nullptr;
  v = std::strtod(text.c_str(), &end);
  return end == text.c_str() + text.size() && std::isfinite(v);
}

}  // namespace

Expected<BoomScript> parse_boom_script(const std::string& text, const std::string& name) {
  static const char* kPrefix = "boom_script::parse(): ";
  static const char* kColumns[] = {"t_s", "elevation_deg", "azimuth_deg", "extension_m"};
  BoomScript script;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  bool header_seen = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> fields = split_csv(line);
    if (!header_seen) {
      header_seen = true;
      bool is_header = fields.size() == 4;
      for (std::size_t i = 0; is_header && i < 4; ++i) is_header = fields[i] == kColumns[i];
      if (!is_header) {
        return make_error(kPrefix, name, ":", line_no,
                          ": expected the header 't_s,elevation_deg,azimuth_deg,extension_m', got '", line,
                          "'");
      }
      continue;
    }
    if (fields.size() != 4) {
      return make_error(kPrefix, name, ":", line_no, ": expected 4 columns, got ", fields.size());
    }
    double v[4];
    for (int i = 0; i < 4; ++i) {
      if (!parse_double(fields[i], v[i])) {
        return make_error(kPrefix, name, ":", line_no, ": column '", kColumns[i],
                          "': expected a number, got '", fields[i], "'");
      }
    }
    if (!script.points.empty() && v[0] <= script.points.back().t_s) {
      return make_error(kPrefix, name, ":", line_no, ": column 't_s': times must increase, got ", fields[0],
                        " after ", script.points.back().t_s);
    }
    script.points.push_back({v[0], {deg_to_rad(v[1]), deg_to_rad(v[2]), v[3]}});
  }
  if (script.points.empty())
    return make_error(kPrefix, name, ": no boom positions (expected at least one row)");
  return script;
}

Expected<BoomScript> load_boom_script(const std::string& path) {
  // A directory would open and read as an empty script ("no boom positions").
  auto text = read_text_file("boom_script::load(): ", path, "boom script");
  if (!text) return text.error();
  return parse_boom_script(*text, path);
}

std::string_view to_string(BoomMode m) {
  switch (m) {
    case BoomMode::kFixed:
      return "fixed";
    case BoomMode::kScripted:
      return "scripted";
    case BoomMode::kTrackReceptacle:
      return "track";
  }
  return "fixed";
}

Expected<BoomMode> boom_mode_from_string(std::string_view s) {
  if (s == "fixed") return BoomMode::kFixed;
  if (s == "scripted") return BoomMode::kScripted;
  if (s == "track" || s == "track-receptacle") return BoomMode::kTrackReceptacle;
  return make_error("boom_mode: expected one of fixed, scripted, track; got '", std::string(s), "'");
}

}  // namespace augrig
