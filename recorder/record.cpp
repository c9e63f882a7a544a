#include "recorder/record.hpp"

#include <algorithm>
#include <charconv>
#include <cstring>

namespace augrig::recorder {

bool parse_drop_stage(std::string_view name, DropStage& out) {
  for (DropStage s : kAllDropStages) {
    if (name == to_string(s)) {
      out = s;
      return true;
    }
  }
  return false;
}

bool parse_clock_domain(std::string_view name, ClockDomain& out) {
  for (ClockDomain c : {ClockDomain::kUnknown, ClockDomain::kHostMonotonic, ClockDomain::kHostRealtime,
                        ClockDomain::kDevice, ClockDomain::kGps, ClockDomain::kSim}) {
    if (name == to_string(c)) {
      out = c;
      return true;
    }
  }
  return false;
}

std::string_view look_kind(const LookRecord& r) {
  return std::holds_alternative<LookNoise>(r.update) ? "noise" : "light";
}

bool parse_light_source(std::string_view name, LightSource& out) {
  for (LightSource s :
       {LightSource::kFixed, LightSource::kDefaultSun, LightSource::kConfigured, LightSource::kEphemeris}) {
    if (name == to_string(s)) {
      out = s;
      return true;
    }
  }
  return false;
}

namespace {

void append_number(std::string& s, double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest text that reads back exactly
  s.append(buf, r.ptr);
}

void append_number(std::string& s, std::int64_t v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

}  // namespace

std::string_view imu_input_header() {
  return "t_ns,dt_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps,arrival_ns";
}

NavInputRecord imu_input(const nav::ImuSample& sample, std::string stream) {
  NavInputRecord r;
  r.stream = std::move(stream);
  r.t_ns = sample.t_ns;
  r.clock = ClockDomain::kGps;
  r.arrival_ns = sample.arrival_ns;
  std::string& s = r.data;
  append_number(s, sample.t_ns);
  s += ',';
  append_number(s, sample.dt_s);
  for (int i = 0; i < 3; ++i) {
    s += ',';
    append_number(s, sample.dtheta_rad[i]);
  }
  for (int i = 0; i < 3; ++i) {
    s += ',';
    append_number(s, sample.dv_mps[i]);
  }
  s += ',';
  append_number(s, sample.arrival_ns);
  return r;
}

namespace {
// +inf's bits: "no receiver". Compared as bits so that NaN, -inf and -0 count as values.
std::uint32_t float_bits(float v) {
  std::uint32_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}
}  // namespace

DepthRecord DepthRecord::from(const DepthImage& depth) {
  DepthRecord r;
  r.width = depth.width;
  r.height = depth.height;
  if (r.empty() || depth.z_m.size() != static_cast<std::size_t>(depth.width) * depth.height) return r;
  const std::uint32_t none = float_bits(DepthImage::kNone);
  int x0 = depth.width, x1 = 0, y0 = depth.height, y1 = 0;
  for (int y = 0; y < depth.height; ++y) {
    const float* row = depth.z_m.data() + static_cast<std::size_t>(y) * depth.width;
    int first = -1, last = -1;
    for (int x = 0; x < depth.width; ++x)
      if (float_bits(row[x]) != none) {
        if (first < 0) first = x;
        last = x;
      }
    if (first < 0) continue;
    x0 = std::min(x0, first);
    x1 = std::max(x1, last + 1);
    y0 = std::min(y0, y);
    y1 = y + 1;
  }
  if (x1 <= x0) return r;  // no receiver: an empty box
  r.box = {x0, y0, x1, y1};
  const std::size_t bw = static_cast<std::size_t>(x1 - x0);
  r.z_m.resize(bw * static_cast<std::size_t>(y1 - y0));
  for (int y = y0; y < y1; ++y)
    std::memcpy(r.z_m.data() + bw * static_cast<std::size_t>(y - y0),
                depth.z_m.data() + static_cast<std::size_t>(y) * depth.width + x0, bw * sizeof(float));
  return r;
}

DepthImage DepthRecord::image() const {
  DepthImage d;
  if (empty()) return d;
  d.width = width;
  d.height = height;
  d.z_m.assign(static_cast<std::size_t>(width) * height, DepthImage::kNone);
  const std::size_t bw = static_cast<std::size_t>(box.width());
  if (box.empty() || !box.inside(width, height) || z_m.size() != bw * box.height()) return d;
  for (int y = box.y0; y < box.y1; ++y)
    std::memcpy(d.z_m.data() + static_cast<std::size_t>(y) * width + box.x0,
                z_m.data() + bw * static_cast<std::size_t>(y - box.y0), bw * sizeof(float));
  return d;
}

}  // namespace augrig::recorder
