#include "recorder/record.hpp"

#include <charconv>

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

}  // namespace augrig::recorder
