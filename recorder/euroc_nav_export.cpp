// The EuRoC export's nav files: mav0/imu0 (EuRoC's IMU rates) and, per aircraft, the log folder
// `augrig nav` fuses (docs/NAV_FORMATS.md), both from the recording's nav inputs.
#include <algorithm>
#include <span>
#include <sstream>

#include "nav/imu_stream.hpp"
#include "recorder/euroc_export_detail.hpp"
#include "recorder/record.hpp"

namespace augrig::recorder::euroc_detail {

namespace {

constexpr const char* kImuCsvHeader =
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
    "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]";

// A stream's IMU samples: augrig IMU datagrams (BLOB rows, as `augrig run --nav` records them) or
// recorder::imu_input() CSV rows; sorted by t_ns, repeats dropped. arrival_ns: the row's.
struct ImuStreamData {
  std::vector<nav::ImuSample> samples;
  ClockDomain clock = ClockDomain::kGps;
  std::size_t undecodable = 0, repeats = 0;
  std::string first_error;
};

// The binary rows decoded into `out`; the text rows' lines gathered into `text`.
void decode_imu_rows(const std::vector<const NavInputRecord*>& rows, ImuStreamData& out, std::string& text,
                     bool& any_text, bool& any_binary) {
  for (const NavInputRecord* r : rows) {
    if (!r->binary) {
      text += r->data + "\n";
      any_text = true;
      continue;
    }
    any_binary = true;
    auto d = nav::decode_imu_datagram(
        std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(r->data.data()), r->data.size()));
    if (!d) {
      if (out.undecodable++ == 0) out.first_error = d.error().message;
      continue;
    }
    out.clock = d->clock;
    for (nav::ImuSample s : d->samples) {
      s.arrival_ns = r->arrival_ns;
      out.samples.push_back(s);
    }
  }
}

// Sorted by t_ns; a sample not after the one before (a datagram sent or received twice) dropped.
void sort_and_drop_repeats(ImuStreamData& out) {
  std::stable_sort(out.samples.begin(), out.samples.end(),
                   [](const nav::ImuSample& a, const nav::ImuSample& b) { return a.t_ns < b.t_ns; });
  std::vector<nav::ImuSample> kept;
  kept.reserve(out.samples.size());
  for (const nav::ImuSample& s : out.samples) {
    if (!kept.empty() && s.t_ns <= kept.back().t_ns) {
      ++out.repeats;
      continue;
    }
    kept.push_back(s);
  }
  out.samples = std::move(kept);
}

Expected<ImuStreamData> imu_stream_data(const std::vector<const NavInputRecord*>& rows,
                                        const std::string& name) {
  ImuStreamData out;
  std::string text;
  bool any_text = false, any_binary = false;
  decode_imu_rows(rows, out, text, any_text, any_binary);
  if (any_text) {
    std::istringstream in(std::string(imu_input_header()) + "\n" + text);
    auto log = nav::parse_imu_csv(in, name);
    if (!log) return log.error();
    if (!any_binary) out.clock = log->clock;
    out.repeats += log->issues.out_of_order + log->issues.duplicates;
    out.samples.insert(out.samples.end(), log->samples.begin(), log->samples.end());
  }
  sort_and_drop_repeats(out);
  return out;
}

bool ends_in_imu(const std::string& name) {
  return name.size() >= 3 && name.compare(name.size() - 3, 3, "imu") == 0;
}

// The stream exported as imu0: the option's, else "imu", else "tanker.imu", else the only stream
// whose name ends in "imu"; "" (with a note or a problem saying why) when none.
std::string choose_imu_stream(const EurocExportOptions& options, const NavStreams& nav,
                              EurocExportReport& report) {
  const auto& by_stream = nav.by_stream;
  if (!options.imu_stream.empty()) {
    if (by_stream.count(options.imu_stream)) return options.imu_stream;
    report.problems.push_back("nav input stream '" + options.imu_stream +
                              "' is not in the recording; imu0 not exported");
    return {};
  }
  if (by_stream.count("imu")) return "imu";
  if (by_stream.count("tanker.imu")) return "tanker.imu";
  std::vector<std::string> imus;
  for (const auto& [name, rows] : by_stream)
    if (ends_in_imu(name)) imus.push_back(name);
  if (imus.size() == 1) return imus[0];
  if (imus.size() > 1) {
    report.notes.push_back(
        "several IMU streams and none is 'imu' or 'tanker.imu': imu0 not written (choose one)");
    return {};
  }
  std::string names;
  for (const auto& [name, rows] : by_stream) names += (names.empty() ? "" : ", ") + name;
  report.notes.push_back(by_stream.empty()
                             ? "no nav inputs in the recording: imu0 not written"
                             : "no IMU stream among the nav inputs (" + names + "): imu0 not written");
  return {};
}

// imu0/data.csv's rows: the increments' mean rates, stamped at the middle of their interval
// (t_ns - dt/2); their times in `t`.
std::string imu0_csv(const std::vector<nav::ImuSample>& samples, std::vector<TimestampNs>& t) {
  std::string csv = std::string(kImuCsvHeader) + "\n";
  for (const nav::ImuSample& s : samples) {
    if (!(s.dt_s > 0)) continue;
    const TimestampNs tm = s.t_ns - s_to_ns(0.5 * s.dt_s);
    const Eigen::Vector3d w = s.dtheta_rad / s.dt_s, a = s.dv_mps / s.dt_s;
    csv += std::to_string(tm) + "," + num(w.x()) + "," + num(w.y()) + "," + num(w.z()) + "," + num(a.x()) +
           "," + num(a.y()) + "," + num(a.z()) + "\n";
    t.push_back(tm);
  }
  return csv;
}

std::string imu0_yaml(const std::string& stream, double rate_hz, ClockDomain clock) {
  std::ostringstream y;
  y << "# augrig export: nav input stream '" << stream << "' as rates. Each row is the mean rate over one\n"
    << "# recorded increment, stamped at the middle of its interval. The IMU axes are the body axes\n"
    << "# (tanker body FRD), so T_BS is the identity. Noise densities are not known to augrig.\n"
    << "sensor_type: imu\n"
    << "comment: \"augrig " << stream << "\"\n"
    << "T_BS:\n  cols: 4\n  rows: 4\n  data: " << matrix_row_major(Eigen::Matrix4d::Identity()) << "\n"
    << "rate_hz: " << num(rate_hz) << "\n"
    << "augrig:\n  stream: " << stream << "\n  clock: " << to_string(clock) << "\n";
  return y.str();
}

}  // namespace

Status write_imu0(const ExportContext& cx, const NavStreams& nav, ClockDomain frames_clock) {
  EurocExportReport& report = cx.report;
  const std::string stream = choose_imu_stream(cx.options, nav, report);
  if (stream.empty()) return {};
  auto data = imu_stream_data(nav.by_stream.at(stream), cx.nav_reader()->path() + " nav_input '" + stream + "'");
  if (!data) {
    report.problems.push_back(strip_function(data.error().message) + "; imu0 not exported");
    return {};
  }
  const fs::path dir = cx.mav0 / "imu0";
  std::error_code ec;
  fs::create_directories(dir, ec);  // a failure shows in the write below
  std::vector<TimestampNs> t;
  const std::string csv = imu0_csv(data->samples, t);
  report.imu_stream = stream;
  report.imu_samples = t.size();
  if (data->repeats > 0)
    report.notes.push_back("imu0: " + std::to_string(data->repeats) +
                           " out-of-order or repeated samples dropped");
  if (data->undecodable > 0)
    report.problems.push_back(
        "imu0: " + std::to_string(data->undecodable) + " IMU datagram(s) of '" + stream +
        "' do not decode, their samples are missing (first: " + data->first_error + ")");
  if (data->clock != frames_clock)
    report.notes.push_back("imu0 is on the IMU's own clock (" + std::string(to_string(data->clock)) +
                           "), not the frames' (" + std::string(to_string(frames_clock)) + ")");
  if (auto s = write_text(dir / "data.csv", csv); !s) return s;
  return write_text(dir / "sensor.yaml", imu0_yaml(stream, median_rate_hz(t), data->clock));
}

namespace {

// gps.nmea: the stream's NMEA sentences, each with its "<arrival_ns> " prefix when it has one.
std::string nmea_text(const std::string& who, const std::string& stream,
                      const std::vector<const NavInputRecord*>& rows, EurocExportReport& report) {
  std::string nmea;
  std::size_t other = 0;
  for (const NavInputRecord* r : rows) {
    if (r->binary || !is_nmea_line(r->data)) {
      ++other;
      continue;
    }
    if (r->arrival_ns != 0) nmea += std::to_string(r->arrival_ns) + " ";
    nmea += r->data + "\r\n";
  }
  if (other > 0)
    report.notes.push_back("nav/" + who + "/gps.nmea: " + std::to_string(other) + " input(s) of '" + stream +
                           "' are not NMEA sentences (gpsd reports?) and are not in it");
  return nmea;
}

// aircraft.yaml: the option's text, else the recording's; without either a note (defaults).
Status write_aircraft_yaml(const ExportContext& cx, const std::string& who, const fs::path& dir) {
  std::string yaml;
  if (auto it = cx.options.aircraft_yaml.find(who); it != cx.options.aircraft_yaml.end())
    yaml = it->second;
  else
    yaml = cx.nav_reader() ? cx.nav_reader()->meta("aircraft_yaml." + who) : std::string();
  if (!yaml.empty()) return write_text(dir / "aircraft.yaml", yaml);
  cx.report.notes.push_back("nav/" + who + "/aircraft.yaml not written: the recording does not hold the " +
                            who + "'s settings (give them: --aircraft " + who +
                            "=FILE); augrig nav uses defaults (no lever arm)");
  return {};
}

// OUT/nav/<who>/ from its GPS and IMU streams: gps.nmea, imu.csv, aircraft.yaml.
Status write_nav_log(const ExportContext& cx, const std::string& who,
                     const std::pair<const std::string, std::vector<const NavInputRecord*>>& gps,
                     const std::pair<const std::string, std::vector<const NavInputRecord*>>& imu) {
  EurocExportReport& report = cx.report;
  const fs::path dir = cx.out / "nav" / who;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return make_error(dir.string(), ": cannot create the folder (", ec.message(), ")");
  if (auto s = write_text(dir / "gps.nmea", nmea_text(who, gps.first, gps.second, report)); !s) return s;
  auto data = imu_stream_data(imu.second, cx.nav_reader()->path() + " nav_input '" + imu.first + "'");
  if (!data) {
    report.problems.push_back(strip_function(data.error().message) + "; nav/" + who + "/imu.csv not written");
    return {};
  }
  nav::CsvWriteOptions o;
  o.clock = data->clock;
  o.metadata["content"] = "nav input stream '" + imu.first + "' as recorded (augrig export)";
  if (auto s = nav::write_imu_csv((dir / "imu.csv").string(), data->samples, o); !s)
    return make_error(strip_function(s.error().message));
  if (auto s = write_aircraft_yaml(cx, who, dir); !s) return s;
  report.nav_logs.push_back(who);
  return {};
}

}  // namespace

Status write_nav_logs(const ExportContext& cx, const NavStreams& nav) {
  const auto& by_stream = nav.by_stream;
  for (const std::string who : {"tanker", "receiver"}) {
    const auto gps = by_stream.find(who + ".gps"), imu = by_stream.find(who + ".imu");
    if (gps == by_stream.end() && imu == by_stream.end()) continue;
    if (gps == by_stream.end() || imu == by_stream.end()) {
      cx.report.notes.push_back("nav/" + who + " not written: the recording has '" +
                                (gps == by_stream.end() ? imu->first : gps->first) + "' but not '" +
                                (gps == by_stream.end() ? who + ".gps" : who + ".imu") + "'");
      continue;
    }
    if (auto s = write_nav_log(cx, who, *gps, *imu); !s) return s;
  }
  return {};
}

}  // namespace augrig::recorder::euroc_detail
