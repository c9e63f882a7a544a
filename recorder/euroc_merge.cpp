// merge_euroc() (euroc.hpp): EuRoC folders of consecutive ranges of one recording joined into the
// folder one export of the whole range gives. Images are hard-linked (copied only where the file
// system cannot link), tables joined row by row, what every part wrote alike taken once, and what
// depends on the neighbours of a part's first and last frame made again over the whole: the
// receiver's velocities, the phases' seconds and the plot.
#include <algorithm>
#include <charconv>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "recorder/euroc.hpp"
#include "recorder/euroc_export_detail.hpp"
#include "recorder/plot.hpp"
#include "render/stats.hpp"

namespace augrig::recorder {

namespace fs = std::filesystem;
using namespace euroc_detail;

namespace {

constexpr const char* kWhere = "recorder::merge_euroc(): ";

std::vector<std::string> read_lines(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::vector<std::string> v;
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string join_lines(const std::vector<std::string>& lines) {
  std::string s;
  for (const std::string& l : lines) s += l + "\n";
  return s;
}

// The first comma-separated cell as an integer (a timestamp, a sequence number).
std::optional<std::int64_t> first_integer(const std::string& row) {
  std::int64_t v = 0;
  const auto end = row.data() + std::min(row.find(','), row.size());
  const auto r = std::from_chars(row.data(), end, v);
  if (r.ec != std::errc() || r.ptr != end) return std::nullopt;
  return v;
}

// One file of the layout as each part has it (the parts that have it, in order).
struct PartFiles {
  std::vector<fs::path> paths;
};

// A table's rows from every part after the header they share (the lines every part's file starts
// with: a part's rows never equal another's, its frames are its own). A timestamp table's
// (mav0/*/data.csv) first column must increase from part to part: else the parts overlap.
Expected<std::string> join_table(const fs::path& rel, const PartFiles& f) {
  std::vector<std::vector<std::string>> parts;
  for (const fs::path& p : f.paths) parts.push_back(read_lines(p));
  std::size_t header = parts.front().size();
  for (const auto& lines : parts) {
    std::size_t n = 0;
    while (n < header && n < lines.size() && lines[n] == parts.front()[n]) ++n;
    header = n;
  }
  std::vector<std::string> out(parts.front().begin(),
                               parts.front().begin() + static_cast<std::ptrdiff_t>(header));
  const bool timed = rel.filename() == "data.csv" && rel.begin()->string() == "mav0";
  std::optional<std::int64_t> last;
  for (std::size_t i = 0; i < parts.size(); ++i)
    for (std::size_t r = header; r < parts[i].size(); ++r) {
      const std::string& row = parts[i][r];
      if (timed && !row.empty()) {
        const auto t = first_integer(row);
        if (last && t && *t <= *last)
          return make_error(f.paths[i].string(), ":", r + 1, ": timestamp ", *t, " follows ", *last,
                            " of the part before: the parts overlap or are out of order");
        if (t) last = t;
      }
      out.push_back(row);
    }
  return join_lines(out);
}

// Where a file of the layout is: what every part wrote alike (taken once), a table (joined), or a
// part's own image (linked).
enum class Kind { kSame, kTable, kImage, kPhases, kStates, kSkip };

Kind kind_of(const fs::path& rel) {
  const std::string name = rel.filename().string();
  if (name == "INCOMPLETE" || name == "stats.png") return Kind::kSkip;  // said below; plotted again
  if (rel == "phases.csv") return Kind::kPhases;
  if (rel == fs::path("mav0/state_groundtruth_estimate0/data.csv")) return Kind::kStates;
  // imu0 and the nav logs are the whole recording's in every part (the nav option).
  if (rel.begin()->string() == "nav" || rel.parent_path() == fs::path("mav0/imu0")) return Kind::kSame;
  if (rel.parent_path().filename() == "data" && rel.begin()->string() == "mav0") return Kind::kImage;
  if (rel.extension() == ".csv") return Kind::kTable;
  return Kind::kSame;
}

Status link_or_copy(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::create_directories(to.parent_path(), ec);
  if (fs::exists(to, ec)) return make_error(to.string(), ": two parts hold this image: the parts overlap");
  fs::create_hard_link(from, to, ec);
  if (ec) {
    ec.clear();
    fs::copy_file(from, to, ec);
  }
  if (ec) return make_error(to.string(), ": cannot write the file (", ec.message(), ")");
  return {};
}

// mav0/state_groundtruth_estimate0/data.csv over the whole: each row's time, position and rotation
// as a part wrote them, the velocity made again from the neighbouring rows (a part's first and last
// row had one neighbour only).
Status join_states(const PartFiles& f, const fs::path& to) {
  std::vector<std::vector<std::string>> rows;
  std::vector<TimestampNs> times;
  std::vector<Eigen::Vector3d> positions;
  std::string header;
  for (const fs::path& p : f.paths) {
    const auto lines = read_lines(p);
    if (!lines.empty()) header = lines.front();
    for (std::size_t i = 1; i < lines.size(); ++i) {
      std::vector<std::string> cells;
      std::stringstream ss(lines[i]);
      for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
      TimestampNs t = 0;
      double v[4] = {};
      for (std::size_t c = 0; c < 4 && c < cells.size(); ++c) {
        const char *b = cells[c].data(), *e = b + cells[c].size();
        const auto r = c == 0 ? std::from_chars(b, e, t) : std::from_chars(b, e, v[c]);
        if (r.ec != std::errc() || r.ptr != e) cells.clear();
      }
      if (cells.size() != 17)
        return make_error(p.string(), ":", i + 1, ": expected 17 numbers (EuRoC's ground truth), got '",
                          lines[i], "'");
      times.push_back(t);
      positions.emplace_back(v[1], v[2], v[3]);
      rows.push_back(std::move(cells));
    }
  }
  std::string csv = header + "\n";
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Eigen::Vector3d v = central_difference_mps(times, positions, i);
    for (std::size_t c = 0; c < 8; ++c) csv += (c ? "," : "") + rows[i][c];
    for (double x : {v.x(), v.y(), v.z()}) csv += "," + num(x);
    csv += ",0,0,0,0,0,0\n";
  }
  return write_text(to, csv);
}

// OUT/phases.csv: each change of phase once, its seconds from the whole's first statistics row.
Expected<std::vector<PhaseEvent>> join_phases(const PartFiles& f, const fs::path& out, TimestampNs t0_ns) {
  std::vector<PhaseEvent> phases;
  for (const fs::path& p : f.paths) {
    const auto lines = read_lines(p);
    for (std::size_t i = 1; i < lines.size(); ++i) {
      const auto t = first_integer(lines[i]);
      const auto name_at = lines[i].find(',', lines[i].find(',') + 1);
      if (!t || name_at == std::string::npos)
        return make_error(p.string(), ":", i + 1, ": expected t_ns,t_s,phase, got '", lines[i], "'");
      PhaseEvent e{*t, lines[i].substr(name_at + 1)};
      if (std::none_of(phases.begin(), phases.end(),
                       [&](const PhaseEvent& x) { return x.t_ns == e.t_ns && x.name == e.name; }))
        phases.push_back(e);
    }
  }
  std::stable_sort(phases.begin(), phases.end(),
                   [](const PhaseEvent& a, const PhaseEvent& b) { return a.t_ns < b.t_ns; });
  // A shard opens with the phase it starts in; where that goes on from the part before, it is no change.
  phases.erase(std::unique(phases.begin(), phases.end(),
                           [](const PhaseEvent& a, const PhaseEvent& b) { return a.name == b.name; }),
               phases.end());
  std::string csv = "#t_ns,t_s,phase\n";
  for (const PhaseEvent& ph : phases) {
    char t_s[32];
    std::snprintf(t_s, sizeof t_s, "%.6f", ns_to_s(ph.t_ns - t0_ns));
    csv += std::to_string(ph.t_ns) + "," + t_s + "," + ph.name + "\n";
  }
  if (Status s = write_text(out / "phases.csv", csv); !s) return s.error();
  return phases;
}

// Every file of every part, by its path in the layout, the parts in order.
Expected<std::map<fs::path, PartFiles>> list_parts(const std::vector<std::string>& inputs,
                                                   EurocMergeReport& report) {
  std::map<fs::path, PartFiles> files;
  for (const std::string& in : inputs) {
    const fs::path dir(in);
    std::error_code ec;
    if (!fs::is_directory(dir / "mav0", ec)) return make_error(in, ": not a EuRoC folder (no mav0 in it)");
    if (fs::exists(dir / "INCOMPLETE", ec)) {
      const auto why = read_lines(dir / "INCOMPLETE");
      report.problems.push_back(in + ": incomplete" +
                                (why.empty() ? std::string() : " (" + why.front() + ")"));
    }
    for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
         it.increment(ec))
      if (it->is_regular_file()) files[it->path().lexically_relative(dir)].paths.push_back(it->path());
    if (ec) return make_error(in, ": cannot list the folder (", ec.message(), ")");
  }
  return files;
}

// Each file of the layout into OUT by its kind; the receiver's states and the phases last (they
// need the whole).
Status merge_files(const std::map<fs::path, PartFiles>& files, const fs::path& out,
                   EurocMergeReport& report) {
  for (const auto& [rel, f] : files) {
    const fs::path to = out / rel;
    std::error_code ec;
    fs::create_directories(to.parent_path(), ec);
    switch (kind_of(rel)) {
      case Kind::kImage:
        if (f.paths.size() > 1)
          return make_error(f.paths[1].string(), ": ", f.paths[0].string(),
                            " holds this image too: the parts overlap");
        if (Status s = link_or_copy(f.paths.front(), to); !s) return s;
        ++report.images;
        break;
      case Kind::kTable: {
        auto t = join_table(rel, f);
        if (!t) return t.error();
        if (Status s = write_text(to, *t); !s) return s;
        break;
      }
      case Kind::kSame: {
        const std::string first = read_bytes(f.paths.front());
        for (const fs::path& p : f.paths)
          if (read_bytes(p) != first)
            return make_error(p.string(), ": differs from ", f.paths.front().string(),
                              " (each part of one recording writes it alike)");
        if (Status s = write_text(to, first); !s) return s;
        break;
      }
      case Kind::kStates:
        if (Status s = join_states(f, to); !s) return s;
        break;
      case Kind::kPhases:
      case Kind::kSkip:
        break;
    }
  }
  return {};
}

}  // namespace

Status merge_euroc(const std::vector<std::string>& inputs, const std::string& out_dir,
                   const EurocMergeOptions& options, EurocMergeReport& report) {
  report = {};
  if (inputs.empty()) return make_error(kWhere, out_dir, ": no parts to join");
  const fs::path out(out_dir);
  std::error_code ec;
  if (fs::exists(out / "mav0", ec))
    return make_error(kWhere, (out / "mav0").string(), ": exists already; join into a new folder");
  auto files = list_parts(inputs, report);
  if (!files) return make_error(kWhere, files.error().message);
  fs::create_directories(out, ec);
  if (Status s = write_text(out / "INCOMPLETE", "augrig merge_euroc -> " + out_dir +
                                                    ": still running or stopped before the end\n");
      !s)
    return make_error(kWhere, s.error().message);
  auto done = [&](const Status& s) -> Status {
    if (!s) return make_error(kWhere, s.error().message);
    if (report.problems.empty()) {
      fs::remove(out / "INCOMPLETE", ec);
      return {};
    }
    return write_text(out / "INCOMPLETE",
                      "augrig merge_euroc -> " + out_dir + " is incomplete:\n" + join_lines(report.problems));
  };
  if (Status s = merge_files(*files, out, report); !s) return done(s);
  report.frames = read_lines(out / "mav0/cam0/data.csv").size();
  report.frames -= report.frames ? 1 : 0;  // the header
  // The statistics: the phases' seconds count from their first row, the plot spans them all.
  std::vector<OcclusionStats> stats;
  if (fs::exists(out / "stats.csv", ec)) {
    auto s = read_stats_csv((out / "stats.csv").string());
    if (!s) return done(s.error());
    stats = std::move(*s);
  }
  std::vector<PhaseEvent> phases;
  if (const auto p = files->find("phases.csv"); p != files->end() && !stats.empty()) {
    auto joined = join_phases(p->second, out, stats.front().t_ns);
    if (!joined) return done(joined.error());
    phases = std::move(*joined);
  }
  if (options.plot && !stats.empty()) {
    StatsPlotOptions po;
    po.title = "Occlusion statistics: " + options.title;
    po.phases = phase_markers(phases, stats.front().t_ns, stats.back().t_ns);
    if (Status s = plot_occlusion_stats(stats, (out / "stats.png").string(), po); !s)
      report.problems.push_back(strip_function(s.error().message));
    else
      report.plotted = true;
  }
  return done({});
}

}  // namespace augrig::recorder
