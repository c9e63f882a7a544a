#include "nav/logs.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <istream>
#include <ostream>
#include <sstream>
#include <system_error>

#include "core/csv.hpp"
#include "core/file_check.hpp"
#include "nav/gps_time.hpp"

namespace augrig::nav {
namespace {

constexpr std::size_t kMaxMessages = 1000;
constexpr double kMaxImuDtS = 60.0;  // an IMU sample interval longer than a minute is not an IMU's

constexpr std::array kClockDomains = {ClockDomain::kUnknown,      ClockDomain::kHostMonotonic,
                                      ClockDomain::kHostRealtime, ClockDomain::kDevice,
                                      ClockDomain::kGps,          ClockDomain::kSim};

// The field as a message quotes it: printable ASCII only, at most 40 characters.
std::string quoted(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) {
    const auto u = static_cast<unsigned char>(c);
    out += u >= 0x20 && u < 0x7f ? c : '?';
  }
  return "'" + out + (s.size() > 40 ? "...'" : "'");
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& x : v) s += (s.empty() ? "" : ",") + x;
  return s;
}

// Shortest text that reads back to exactly `v`.
std::string shortest(double v) {
  char buf[64];
  const auto [p, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, p) : std::string();
}

bool is_identifier(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
}

struct ParseFailure {
  std::string message;
};

// A CSV table: header with named columns, rows handed to a callback with their line number.
class Table {
 public:
  Table(std::string prefix, std::string name, std::vector<std::string> required,
        std::vector<std::string> optional)
      : prefix_(std::move(prefix)),
        name_(std::move(name)),
        required_(std::move(required)),
        optional_(std::move(optional)) {}

  ClockDomain clock = ClockDomain::kGps;
  std::map<std::string, std::string> metadata;

  [[noreturn]] void fail(std::size_t line, const std::string& what) const {
    throw ParseFailure{prefix_ + name_ + ":" + std::to_string(line) + ": " + what};
  }
  std::string at(std::size_t line) const { return name_ + ":" + std::to_string(line) + ": "; }

  // Index of a column in the rows, -1 when an optional column is absent.
  int column(const std::string& c) const {
    const auto it = std::find(header_.begin(), header_.end(), c);
    return it == header_.end() ? -1 : static_cast<int>(it - header_.begin());
  }

  void read(std::istream& in,
            const std::function<void(const std::vector<std::string_view>&, std::size_t)>& row) {
    std::string text;
    std::size_t line = 0;
    bool have_header = false;
    while (std::getline(in, text)) {
      ++line;
      const std::string_view s = trim_csv_cell(text);
      if (s.empty()) continue;
      if (s.front() == '#') {
        comment(s.substr(1), line);
        continue;
      }
      if (!have_header) {
        header(s, line);
        have_header = true;
        continue;
      }
      const auto fields = split_csv_line_trimmed(s);
      if (fields.size() != header_.size()) {
        fail(line, "expected " + std::to_string(header_.size()) + " fields (" + join(header_) + "), got " +
                       std::to_string(fields.size()));
      }
      row(fields, line);
    }
    if (in.bad()) fail(line, "read error");
    if (!have_header) {
      throw ParseFailure{prefix_ + name_ + ": expected the header line '" + join(required_) +
                         "' (no header found in " + std::to_string(line) + " lines)"};
    }
  }

  double number(const std::vector<std::string_view>& f, int col, std::size_t line,
                bool allow_empty = false) const {
    const std::string_view s = f[col];
    if (s.empty() && allow_empty) return std::numeric_limits<double>::quiet_NaN();
    double v = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || ec != std::errc() || p != s.data() + s.size() || !std::isfinite(v)) {
      fail(line, "column '" + header_[col] + "': expected a finite number" +
                     (allow_empty ? " or nothing" : "") + ", got " + quoted(s));
    }
    return v;
  }

  std::int64_t integer(const std::vector<std::string_view>& f, int col, std::size_t line) const {
    const std::string_view s = f[col];
    std::int64_t v = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || ec != std::errc() || p != s.data() + s.size()) {
      fail(line, "column '" + header_[col] + "': expected an integer (ns), got " + quoted(s));
    }
    return v;
  }

  // A time in ns, bounded (nav/gps_time.hpp) so that differences of two times and a time plus a
  // clock offset cannot overflow int64.
  TimestampNs timestamp(const std::vector<std::string_view>& f, int col, std::size_t line) const {
    const std::int64_t v = integer(f, col, line);
    if (!is_supported_timestamp(v)) {
      fail(line, "column '" + header_[col] + "': expected a time in " + kTimestampRangeText + ", got " +
                     quoted(f[col]));
    }
    return v;
  }

 private:
  void comment(std::string_view s, std::size_t line) {
    const std::size_t colon = s.find(':');
    if (colon == std::string_view::npos) return;
    const std::string key(trim_csv_cell(s.substr(0, colon)));
    if (!is_identifier(key)) return;
    const std::string value(trim_csv_cell(s.substr(colon + 1)));
    metadata.emplace(key, value);
    if (key != "clock") return;
    for (ClockDomain c : kClockDomains) {
      if (value == to_string(c)) {
        clock = c;
        return;
      }
    }
    std::vector<std::string> names;
    for (ClockDomain c : kClockDomains) names.emplace_back(to_string(c));
    fail(line, "'# clock:' expected one of " + join(names) + ", got " + quoted(value));
  }

  void header(std::string_view s, std::size_t line) {
    for (std::string_view f : split_csv_line_trimmed(s)) header_.emplace_back(f);
    for (std::size_t i = 0; i < header_.size(); ++i) {
      const std::string& c = header_[i];
      if (std::find(required_.begin(), required_.end(), c) == required_.end() &&
          std::find(optional_.begin(), optional_.end(), c) == optional_.end()) {
        fail(line, "header: unknown column " + quoted(c) + " (expected the columns " + join(required_) +
                       (optional_.empty() ? "" : ", optionally " + join(optional_)) + ")");
      }
      if (std::find(header_.begin(), header_.begin() + i, c) != header_.begin() + i) {
        fail(line, "header: column " + quoted(c) + " appears twice");
      }
    }
    for (const std::string& c : required_) {
      if (column(c) < 0) fail(line, "header: missing column '" + c + "' (expected " + join(required_) + ")");
    }
  }

  std::string prefix_;
  std::string name_;
  std::vector<std::string> required_;
  std::vector<std::string> optional_;
  std::vector<std::string> header_;
};

void report(LogIssues& issues, const std::string& name, const std::string& what) {
  if (issues.messages.size() < kMaxMessages) {
    issues.messages.push_back(what);
  } else if (issues.messages.size() == kMaxMessages) {
    issues.messages.push_back(name + ": further messages suppressed (the counts stay exact)");
  }
}

// Drops a sample whose time does not increase; true when it is kept.
bool check_order(LogIssues& issues, const Table& t, const std::string& name, TimestampNs prev,
                 TimestampNs now, std::size_t prev_line, std::size_t line) {
  if (now > prev) return true;
  const bool dup = now == prev;
  ++(dup ? issues.duplicates : issues.out_of_order);
  report(issues, name,
         t.at(line) + "t_ns " + std::to_string(now) + (dup ? " repeats" : " is older than") +
             " the previous sample's (line " + std::to_string(prev_line) + "): dropped");
  return false;
}

template <typename F>
auto guarded(const std::string& prefix, const std::string& name, F&& body) -> Expected<decltype(body())> {
  try {
    return body();
  } catch (const ParseFailure& e) {
    return Error{e.message};
  } catch (const std::exception& e) {
    return make_error(prefix, name, ": ", e.what());
  }
}

const std::vector<std::string> kImuColumns = {"t_ns",         "dt_s",     "dtheta_x_rad", "dtheta_y_rad",
                                              "dtheta_z_rad", "dv_x_mps", "dv_y_mps",     "dv_z_mps"};
const std::vector<std::string> kNavColumns = {"t_ns",   "lat_deg", "lon_deg", "h_m",       "vn_mps",
                                              "ve_mps", "vd_mps",  "yaw_deg", "pitch_deg", "roll_deg"};
const std::vector<std::string> kNavSigmaColumns = {"sigma_n_m",     "sigma_e_m",       "sigma_d_m",
                                                   "sigma_yaw_deg", "sigma_pitch_deg", "sigma_roll_deg"};
// Written only when estimated (NavSolutionRow); the last two are sigmas.
const std::vector<std::string> kNavClockColumns = {"imu_clock_offset_ms", "imu_clock_drift_ppm",
                                                   "sigma_imu_clock_offset_ms", "sigma_imu_clock_drift_ppm"};

Expected<ImuLog> parse_imu(std::istream& in, const std::string& name, const std::string& prefix) {
  return guarded(prefix, name, [&]() -> ImuLog {
    ImuLog log;
    Table t(prefix, name, kImuColumns, {"arrival_ns"});
    std::size_t prev_line = 0;
    t.read(in, [&](const std::vector<std::string_view>& f, std::size_t line) {
      ImuSample s;
      s.t_ns = t.timestamp(f, t.column("t_ns"), line);
      s.dt_s = t.number(f, t.column("dt_s"), line);
      // Bounded above too: fusion turns dt_s into int64 ns, which 1e300 s would overflow.
      if (!(s.dt_s > 0 && s.dt_s <= kMaxImuDtS))
        t.fail(line,
               "column 'dt_s': expected an interval > 0 s and <= 60 s, got " + quoted(f[t.column("dt_s")]));
      for (int i = 0; i < 3; ++i) {
        s.dtheta_rad[i] = t.number(f, t.column(kImuColumns[2 + i]), line);
        s.dv_mps[i] = t.number(f, t.column(kImuColumns[5 + i]), line);
      }
      if (const int c = t.column("arrival_ns"); c >= 0) s.arrival_ns = t.timestamp(f, c, line);
      if (!log.samples.empty()) {
        const ImuSample& p = log.samples.back();
        if (!check_order(log.issues, t, name, p.t_ns, s.t_ns, prev_line, line)) return;
        const double interval_s = ns_to_s(s.t_ns - p.t_ns);
        if (interval_s > 1.5 * s.dt_s) {
          ++log.issues.gaps;
          report(log.issues, name,
                 t.at(line) + "gap: " + shortest(interval_s) + " s since the previous sample (line " +
                     std::to_string(prev_line) + ") but dt_s is " + shortest(s.dt_s));
        }
      }
      log.samples.push_back(s);
      prev_line = line;
    });
    log.clock = t.clock;
    log.metadata = t.metadata;
    return log;
  });
}

Expected<NavSolutionLog> parse_nav(std::istream& in, const std::string& name, const std::string& prefix) {
  return guarded(prefix, name, [&]() -> NavSolutionLog {
    NavSolutionLog log;
    std::vector<std::string> optional = kNavSigmaColumns;
    optional.insert(optional.end(), kNavClockColumns.begin(), kNavClockColumns.end());
    Table t(prefix, name, kNavColumns, optional);
    std::vector<std::size_t> lines;
    t.read(in, [&](const std::vector<std::string_view>& f, std::size_t line) {
      NavSolutionRow r;
      r.t_ns = t.timestamp(f, t.column("t_ns"), line);
      double* const values[] = {&r.lat_deg, &r.lon_deg, &r.h_m,       &r.vn_mps,  &r.ve_mps,
                                &r.vd_mps,  &r.yaw_deg, &r.pitch_deg, &r.roll_deg};
      for (std::size_t i = 0; i < std::size(values); ++i)
        *values[i] = t.number(f, t.column(kNavColumns[1 + i]), line);
      double* const sigmas[] = {&r.sigma_n_m,     &r.sigma_e_m,       &r.sigma_d_m,
                                &r.sigma_yaw_deg, &r.sigma_pitch_deg, &r.sigma_roll_deg};
      for (std::size_t i = 0; i < std::size(sigmas); ++i) {
        const int c = t.column(kNavSigmaColumns[i]);
        if (c < 0) continue;
        *sigmas[i] = t.number(f, c, line, true);
        if (*sigmas[i] < 0)
          t.fail(line, "column '" + kNavSigmaColumns[i] + "': expected a sigma >= 0, got " + quoted(f[c]));
      }
      double* const clock[] = {&r.imu_clock_offset_ms, &r.imu_clock_drift_ppm, &r.sigma_imu_clock_offset_ms,
                               &r.sigma_imu_clock_drift_ppm};
      for (std::size_t i = 0; i < std::size(clock); ++i) {
        const int c = t.column(kNavClockColumns[i]);
        if (c < 0) continue;
        *clock[i] = t.number(f, c, line, true);
        if (i >= 2 && *clock[i] < 0)
          t.fail(line, "column '" + kNavClockColumns[i] + "': expected a sigma >= 0, got " + quoted(f[c]));
      }
      if (std::abs(r.lat_deg) > 90)
        t.fail(line, "column 'lat_deg': expected -90..90, got " + quoted(f[t.column("lat_deg")]));
      if (std::abs(r.lon_deg) > 180) {
        t.fail(line, "column 'lon_deg': expected -180..180, got " + quoted(f[t.column("lon_deg")]));
      }
      if (!log.rows.empty() &&
          !check_order(log.issues, t, name, log.rows.back().t_ns, r.t_ns, lines.back(), line)) {
        return;
      }
      log.rows.push_back(r);
      lines.push_back(line);
    });
    if (log.rows.size() >= 3) {
      std::vector<TimestampNs> d;
      for (std::size_t i = 1; i < log.rows.size(); ++i) d.push_back(log.rows[i].t_ns - log.rows[i - 1].t_ns);
      std::vector<TimestampNs> sorted = d;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      const TimestampNs median = sorted[sorted.size() / 2];
      for (std::size_t i = 0; i < d.size(); ++i) {
        if (d[i] - median <= median) continue;  // d[i] <= 2 * median without overflowing
        ++log.issues.gaps;
        report(log.issues, name,
               t.at(lines[i + 1]) + "gap of " + shortest(ns_to_s(d[i])) +
                   " s before this row (median interval " + shortest(ns_to_s(median)) + " s)");
      }
    }
    log.clock = t.clock;
    log.metadata = t.metadata;
    return log;
  });
}

void write_metadata(std::ostream& out, const char* what, const CsvWriteOptions& o) {
  out << "# augrig " << what << " (docs/NAV_FORMATS.md)\n";
  out << "# clock: " << to_string(o.clock) << "\n";
  for (const auto& [k, v] : o.metadata) {
    if (k != "clock") out << "# " << k << ": " << v << "\n";
  }
}

template <typename Writer>
Status write_file(const char* fn, const std::string& path, Writer&& write) {
  std::ostringstream text;
  if (Status s = write(text); !s) return s;
  std::ofstream out(path, std::ios::binary);
  if (!out)
    return make_error("nav::", fn, "(): ", path, ": cannot create the file (", std::strerror(errno), ")");
  out << text.str();
  out.close();
  if (!out) return make_error("nav::", fn, "(): ", path, ": write failed");
  return {};
}

Expected<std::ifstream> open(const char* fn, const std::string& path, const char* what) {
  if (auto d = check_not_directory(std::string("nav::") + fn + "(): ", path); !d) return d.error();
  std::ifstream in(path, std::ios::binary);
  if (!in)
    return make_error("nav::", fn, "(): ", path, ": cannot open the ", what, " (", std::strerror(errno), ")");
  return in;
}

}  // namespace

Expected<ImuLog> parse_imu_csv(std::istream& in, const std::string& name) {
  return parse_imu(in, name, "nav::parse_imu_csv(): ");
}

Expected<ImuLog> read_imu_csv(const std::string& path) {
  auto in = open("read_imu_csv", path, "IMU log");
  if (!in) return in.error();
  return parse_imu(*in, path, "nav::read_imu_csv(): ");
}

Status write_imu_csv(std::ostream& out, const std::vector<ImuSample>& samples,
                     const CsvWriteOptions& options) {
  const bool arrival =
      std::any_of(samples.begin(), samples.end(), [](const ImuSample& s) { return s.arrival_ns != 0; });
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const ImuSample& s = samples[i];
    if (!std::isfinite(s.dt_s) || !s.dtheta_rad.allFinite() || !s.dv_mps.allFinite()) {
      return make_error("nav::write_imu_csv(): sample ", i, " (t_ns ", s.t_ns, "): a value is not finite");
    }
  }
  write_metadata(out, "IMU log", options);
  out << join(kImuColumns) << (arrival ? ",arrival_ns\n" : "\n");
  for (const ImuSample& s : samples) {
    out << s.t_ns << ',' << shortest(s.dt_s);
    for (int i = 0; i < 3; ++i) out << ',' << shortest(s.dtheta_rad[i]);
    for (int i = 0; i < 3; ++i) out << ',' << shortest(s.dv_mps[i]);
    if (arrival) out << ',' << s.arrival_ns;
    out << '\n';
  }
  if (!out) return make_error("nav::write_imu_csv(): write failed");
  return {};
}

Status write_imu_csv(const std::string& path, const std::vector<ImuSample>& samples,
                     const CsvWriteOptions& options) {
  return write_file("write_imu_csv", path,
                    [&](std::ostream& o) { return write_imu_csv(o, samples, options); });
}

Expected<NavSolutionLog> parse_nav_solution_csv(std::istream& in, const std::string& name) {
  return parse_nav(in, name, "nav::parse_nav_solution_csv(): ");
}

Expected<NavSolutionLog> read_nav_solution_csv(const std::string& path) {
  auto in = open("read_nav_solution_csv", path, "nav solution log");
  if (!in) return in.error();
  return parse_nav(*in, path, "nav::read_nav_solution_csv(): ");
}

Status write_nav_solution_csv(std::ostream& out, const std::vector<NavSolutionRow>& rows,
                              const CsvWriteOptions& options) {
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const NavSolutionRow& r = rows[i];
    for (double v :
         {r.lat_deg, r.lon_deg, r.h_m, r.vn_mps, r.ve_mps, r.vd_mps, r.yaw_deg, r.pitch_deg, r.roll_deg}) {
      if (!std::isfinite(v)) {
        return make_error("nav::write_nav_solution_csv(): row ", i, " (t_ns ", r.t_ns,
                          "): a position, velocity or attitude value is not finite");
      }
    }
  }
  const bool clock = std::any_of(
      rows.begin(), rows.end(), [](const NavSolutionRow& r) { return std::isfinite(r.imu_clock_offset_ms); });
  write_metadata(out, "navigation solution log", options);
  out << join(kNavColumns) << ',' << join(kNavSigmaColumns) << (clock ? "," + join(kNavClockColumns) : "")
      << '\n';
  const auto opt = [](double v) { return std::isfinite(v) ? shortest(v) : std::string(); };
  for (const NavSolutionRow& r : rows) {
    out << r.t_ns;
    for (double v :
         {r.lat_deg, r.lon_deg, r.h_m, r.vn_mps, r.ve_mps, r.vd_mps, r.yaw_deg, r.pitch_deg, r.roll_deg}) {
      out << ',' << shortest(v);
    }
    for (double v :
         {r.sigma_n_m, r.sigma_e_m, r.sigma_d_m, r.sigma_yaw_deg, r.sigma_pitch_deg, r.sigma_roll_deg}) {
      out << ',' << opt(v);
    }
    if (clock) {
      for (double v : {r.imu_clock_offset_ms, r.imu_clock_drift_ppm, r.sigma_imu_clock_offset_ms,
                       r.sigma_imu_clock_drift_ppm})
        out << ',' << opt(v);
    }
    out << '\n';
  }
  if (!out) return make_error("nav::write_nav_solution_csv(): write failed");
  return {};
}

Status write_nav_solution_csv(const std::string& path, const std::vector<NavSolutionRow>& rows,
                              const CsvWriteOptions& options) {
  return write_file("write_nav_solution_csv", path,
                    [&](std::ostream& o) { return write_nav_solution_csv(o, rows, options); });
}

namespace {

const std::vector<std::string> kFrameColumns = {"sequence", "camera", "t_ns", "file"};
const std::vector<std::string> kPoseColumns = {"sequence", "camera", "t_ns", "t_nav_ns", "x_m", "y_m",
                                               "z_m",      "qw",     "qx",   "qy",       "qz"};
const std::vector<std::string> kPoseOptional = {"sigma_pos_m", "sigma_att_deg", "boom_elevation_deg",
                                                "boom_azimuth_deg", "boom_extension_m"};

std::uint64_t unsigned_field(const Table& t, const std::vector<std::string_view>& f, int col,
                             std::size_t line) {
  const std::int64_t v = t.integer(f, col, line);
  if (v < 0) t.fail(line, "column '" + kFrameColumns[0] + "': expected a count >= 0, got " + quoted(f[col]));
  return static_cast<std::uint64_t>(v);
}

int camera_field(const Table& t, const std::vector<std::string_view>& f, int col, std::size_t line) {
  const std::int64_t v = t.integer(f, col, line);
  if (v < 0 || v > 15) t.fail(line, "column 'camera': expected a camera index 0..15, got " + quoted(f[col]));
  return static_cast<int>(v);
}

}  // namespace

Expected<FrameIndex> parse_frame_index_csv(std::istream& in, const std::string& name) {
  const std::string prefix = "nav::parse_frame_index_csv(): ";
  return guarded(prefix, name, [&]() -> FrameIndex {
    FrameIndex index;
    Table t(prefix, name, kFrameColumns, {});
    t.clock = ClockDomain::kDevice;
    t.read(in, [&](const std::vector<std::string_view>& f, std::size_t line) {
      FrameIndexRow r;
      r.sequence = unsigned_field(t, f, t.column("sequence"), line);
      r.camera = camera_field(t, f, t.column("camera"), line);
      r.t_ns = t.timestamp(f, t.column("t_ns"), line);
      r.file = std::string(f[t.column("file")]);
      if (r.file.empty() || r.file.find("..") != std::string::npos || r.file.front() == '/')
        t.fail(line, "column 'file': expected a path inside the index's folder, got " + quoted(r.file));
      for (auto it = index.rows.rbegin(); it != index.rows.rend(); ++it) {
        if (it->camera != r.camera) continue;
        if (it->sequence >= r.sequence || it->t_ns >= r.t_ns) {
          t.fail(line, "camera " + std::to_string(r.camera) + ": sequence and t_ns must increase, got " +
                           std::to_string(r.sequence) + " at " + std::to_string(r.t_ns) + " ns after " +
                           std::to_string(it->sequence) + " at " + std::to_string(it->t_ns) + " ns");
        }
        break;
      }
      index.rows.push_back(std::move(r));
    });
    index.clock = t.clock;
    index.metadata = t.metadata;
    return index;
  });
}

Expected<FrameIndex> read_frame_index_csv(const std::string& path) {
  auto in = open("read_frame_index_csv", path, "frame index");
  if (!in) return in.error();
  return parse_frame_index_csv(*in, path);
}

Status write_frame_index_csv(const std::string& path, const FrameIndex& index) {
  return write_file("write_frame_index_csv", path, [&](std::ostream& out) -> Status {
    CsvWriteOptions o;
    o.clock = index.clock;
    o.metadata = index.metadata;
    write_metadata(out, "frame index", o);
    out << join(kFrameColumns) << '\n';
    for (const FrameIndexRow& r : index.rows) {
      if (r.file.find(',') != std::string::npos || r.file.find('\n') != std::string::npos)
        return make_error("nav::write_frame_index_csv(): file name '", r.file, "' has a comma or newline");
      out << r.sequence << ',' << r.camera << ',' << r.t_ns << ',' << r.file << '\n';
    }
    return {};
  });
}

Expected<CameraPoseLog> parse_camera_pose_csv(std::istream& in, const std::string& name) {
  const std::string prefix = "nav::parse_camera_pose_csv(): ";
  return guarded(prefix, name, [&]() -> CameraPoseLog {
    CameraPoseLog log;
    Table t(prefix, name, kPoseColumns, kPoseOptional);
    t.read(in, [&](const std::vector<std::string_view>& f, std::size_t line) {
      CameraPoseRow r;
      r.sequence = unsigned_field(t, f, t.column("sequence"), line);
      r.camera = camera_field(t, f, t.column("camera"), line);
      r.t_ns = t.timestamp(f, t.column("t_ns"), line);
      r.t_nav_ns = t.timestamp(f, t.column("t_nav_ns"), line);
      double* const v[] = {&r.x_m, &r.y_m, &r.z_m, &r.qw, &r.qx, &r.qy, &r.qz};
      for (std::size_t i = 0; i < std::size(v); ++i) *v[i] = t.number(f, t.column(kPoseColumns[4 + i]), line);
      const double qn = std::sqrt(r.qw * r.qw + r.qx * r.qx + r.qy * r.qy + r.qz * r.qz);
      if (std::abs(qn - 1.0) > 1e-6)
        t.fail(line, "columns qw..qz: expected a unit quaternion, got norm " + shortest(qn));
      double* const o[] = {&r.sigma_pos_m, &r.sigma_att_deg, &r.boom_elevation_deg, &r.boom_azimuth_deg,
                           &r.boom_extension_m};
      for (std::size_t i = 0; i < std::size(o); ++i)
        if (const int c = t.column(kPoseOptional[i]); c >= 0) *o[i] = t.number(f, c, line, true);
      log.rows.push_back(r);
    });
    log.metadata = t.metadata;
    return log;
  });
}

Expected<CameraPoseLog> read_camera_pose_csv(const std::string& path) {
  auto in = open("read_camera_pose_csv", path, "camera pose file");
  if (!in) return in.error();
  return parse_camera_pose_csv(*in, path);
}

Status write_camera_pose_csv(const std::string& path, const std::vector<CameraPoseRow>& rows,
                             const CsvWriteOptions& options) {
  return write_file("write_camera_pose_csv", path, [&](std::ostream& out) -> Status {
    write_metadata(out, "camera poses", options);
    out << join(kPoseColumns) << ',' << join(kPoseOptional) << '\n';
    const auto opt = [](double v) { return std::isfinite(v) ? shortest(v) : std::string(); };
    for (const CameraPoseRow& r : rows) {
      out << r.sequence << ',' << r.camera << ',' << r.t_ns << ',' << r.t_nav_ns;
      for (double v : {r.x_m, r.y_m, r.z_m, r.qw, r.qx, r.qy, r.qz}) {
        if (!std::isfinite(v)) return make_error("nav::write_camera_pose_csv(): a pose value is not finite");
        out << ',' << shortest(v);
      }
      for (double v :
           {r.sigma_pos_m, r.sigma_att_deg, r.boom_elevation_deg, r.boom_azimuth_deg, r.boom_extension_m})
        out << ',' << opt(v);
      out << '\n';
    }
    return {};
  });
}

}  // namespace augrig::nav
