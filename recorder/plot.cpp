#include "recorder/plot.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include <fcntl.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/file_check.hpp"

extern char** environ;

namespace augrig::recorder {

namespace {

bool is_executable_file(const std::string& p) {
  struct stat st {};
  return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(p.c_str(), X_OK) == 0;
}

void append_value(std::string& s, double v) {
  if (!std::isfinite(v)) {
    s += "NaN";
    return;
  }
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 9);
  s.append(buf, r.ptr);
}

std::string read_text(const std::string& path, std::size_t max) {
  std::ifstream in(path, std::ios::binary);
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  if (s.size() > max) s = "..." + s.substr(s.size() - max);
  return s;
}

// The phase markers' colour (no series uses it; tests find the lines by it).
constexpr const char* kPhaseColour = "#9467bd";

std::string script(const std::vector<OcclusionStats>& frames, const std::string& png,
                   const StatsPlotOptions& o) {
  std::string s;
  // Not "enhanced": a title such as rec_demo keeps its underscore (not a subscript).
  s += gnuplot_png_terminal(o.width_px, o.height_px);
  s += "set output " + gnuplot_quote(png) + "\n";
  // t_s occl_L occl_R overlap recv_L recv_R boom_L boom_R both left_only right_only neither
  s += "$stats << EOD\n";
  const TimestampNs t0 = frames.front().t_ns;
  for (const OcclusionStats& f : frames) {
    append_value(s, ns_to_s(f.t_ns - t0));
    // The stereo classes as % of the left receiver pixels (they add up to 100 where there is a
    // receiver; no value without one).
    const double rl = static_cast<double>(f.receiver_px_left);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    auto cls = [&](std::int64_t px) { return rl > 0 ? 100.0 * static_cast<double>(px) / rl : nan; };
    for (double v : {f.occluded_pct_left, f.occluded_pct_right, f.boom_overlap_pct_union, f.receiver_pct_left,
                     f.receiver_pct_right, f.boom_pct_left, f.boom_pct_right, cls(f.stereo_both_px),
                     cls(f.left_only_px), cls(f.right_only_px), cls(f.neither_px)}) {
      s += ' ';
      append_value(s, v);
    }
    s += '\n';
  }
  s += "EOD\n";
  const bool one = frames.size() == 1;
  // Small points too, so that a sample between two gaps (non-finite neighbours) still shows.
  const std::string style = std::string("linespoints pointtype 7 pointsize ") + (one ? "1.2" : "0.35");
  s += gnuplot_time_panels(3, o.title, 34);
  // The phases: dashed lines on every panel (arrows stay set), their names on the first only.
  for (std::size_t k = 0; k < o.phases.size(); ++k) {
    std::string t;
    append_value(t, o.phases[k].t_s);
    s += "set arrow " + std::to_string(k + 1) + " from " + t + ", graph 0 to " + t +
         ", graph 1 nohead dashtype 2 linewidth 1.5 linecolor rgb '" + kPhaseColour + "' back\n";
    s += "set label " + std::to_string(k + 2) + " " + gnuplot_quote(o.phases[k].name) + " at " + t +
         ", graph 0.97 rotate by 90 right offset 1.1, 0 front font ',9' textcolor rgb '" + kPhaseColour + "'\n";
  }
  s += "set ylabel '%'\nset yrange [0:*]\nset offsets 0, 0, graph 0.05, 0\n";
  s += "set title 'Receiver occlusion by the boom, and boom overlap between the cameras'\n";
  s += "plot $stats using 1:2 with " + style +
       " linewidth 2 linecolor rgb '#1f77b4' title 'occluded % left', \\\n"
       "     $stats using 1:3 with " +
       style +
       " linewidth 2 linecolor rgb '#d62728' title 'occluded % right', \\\n"
       "     $stats using 1:4 with " +
       style + " linewidth 2 linecolor rgb '#2ca02c' title 'boom overlap % of union'\n";
  for (std::size_t k = 0; k < o.phases.size(); ++k) s += "unset label " + std::to_string(k + 2) + "\n";
  s += "set title 'Coverage of each image (% of its pixels)'\n";
  s += "plot $stats using 1:5 with " + style +
       " linewidth 2 linecolor rgb '#1f77b4' title 'receiver left', \\\n"
       "     $stats using 1:6 with " +
       style +
       " linewidth 2 dashtype 2 linecolor rgb '#1f77b4' title 'receiver right', \\\n"
       "     $stats using 1:7 with " +
       style +
       " linewidth 2 linecolor rgb '#ff7f0e' title 'boom left', \\\n"
       "     $stats using 1:8 with " +
       style + " linewidth 2 dashtype 2 linecolor rgb '#ff7f0e' title 'boom right'\n";
  s += "set title 'Stereo classes of the left receiver pixels (% of them)'\n";
  const bool any_receiver = std::any_of(frames.begin(), frames.end(),
                                        [](const OcclusionStats& f) { return f.receiver_px_left > 0; });
  if (!any_receiver) {
    // gnuplot refuses a plot without one defined point: an empty panel that says why.
    s += "set label 1 'no receiver in the left image in any frame' at graph 0.5, 0.5 center\n"
         "set xrange [0:1]\nset yrange [0:100]\nplot 1000 notitle\nunset multiplot\nset output\n";
    return s;
  }
  s += "set yrange [0:100]\n";
  s += "plot $stats using 1:9 with " + style + " linewidth 2 linecolor rgb '#2ca02c' title 'visible to both', \\\n"
       "     $stats using 1:10 with " + style + " linewidth 2 linecolor rgb '#1f77b4' title 'left only', \\\n"
       "     $stats using 1:11 with " + style + " linewidth 2 linecolor rgb '#d62728' title 'right only', \\\n"
       "     $stats using 1:12 with " + style + " linewidth 2 linecolor rgb '#7f7f7f' title 'neither'\n";
  s += "unset multiplot\nset output\n";
  return s;
}

}  // namespace

std::vector<PhaseEvent> phase_events(const std::vector<EventRecord>& events) {
  std::vector<PhaseEvent> out;
  constexpr std::string_view kPrefix = "phase: ";
  for (const EventRecord& e : events)
    if (e.text.size() > kPrefix.size() && e.text.compare(0, kPrefix.size(), kPrefix) == 0)
      out.push_back({e.t_ns, e.text.substr(kPrefix.size())});
  std::stable_sort(out.begin(), out.end(), [](const PhaseEvent& a, const PhaseEvent& b) { return a.t_ns < b.t_ns; });
  return out;
}

std::vector<PhaseMarker> phase_markers(const std::vector<PhaseEvent>& phases, TimestampNs t0_ns,
                                       TimestampNs t_end_ns) {
  std::vector<PhaseMarker> out;
  const PhaseEvent* before = nullptr;  // the phase the plot starts in
  for (const PhaseEvent& p : phases) {
    if (p.t_ns < t0_ns) before = &p;
    if (p.t_ns >= t0_ns && p.t_ns <= t_end_ns) {
      if (before && p.t_ns > t0_ns) out.push_back({0.0, before->name});
      before = nullptr;
      out.push_back({ns_to_s(p.t_ns - t0_ns), p.name});
    }
  }
  if (before && out.empty()) out.push_back({0.0, before->name});
  return out;
}

std::string gnuplot_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("''") : std::string(1, c);
  return q + "'";
}

std::string gnuplot_time_panels(int panels, const std::string& title, int key_margin_chars) {
  return "set multiplot layout " + std::to_string(panels) + ",1 title " + gnuplot_quote(title) +
         " font ',13'\nset grid\nset key outside right top\nset lmargin 10\nset rmargin " +
         std::to_string(key_margin_chars) + "\nset xlabel 'time from the first frame (s)'\n";
}

std::string find_gnuplot() {
  if (const char* e = std::getenv("AUGRIG_GNUPLOT"); e && *e)
    return is_executable_file(e) ? std::string(e) : "";
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(ss, dir, ':')) {
    const std::string p = (dir.empty() ? std::string(".") : dir) + "/gnuplot";
    if (is_executable_file(p)) return p;
  }
  return "";
}

Status plot_occlusion_stats(const std::vector<OcclusionStats>& frames, const std::string& png_path,
                            const StatsPlotOptions& options) {
  if (frames.empty())
    return make_error("recorder::plot_occlusion_stats(): ", png_path, ": no statistics to plot (no frame has them)");
  return run_gnuplot(script(frames, png_path, options), png_path, "recorder::plot_occlusion_stats(): ");
}

std::string gnuplot_png_terminal(int width_px, int height_px) {
  return "if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) {\n  set terminal pngcairo size " +
         std::to_string(width_px) + "," + std::to_string(height_px) +
         " noenhanced font 'sans,10'\n} else {\n  set terminal png size " + std::to_string(width_px) + "," +
         std::to_string(height_px) + "\n}\n";
}

Status run_gnuplot(const std::string& text, const std::string& png_path, const std::string& caller) {
  const std::string where = caller + png_path + ": ";
  // A directory there would be deleted by the fs::remove() below when empty, or left for gnuplot
  // to fail on.
  if (auto d = check_not_directory(caller, png_path); !d) return d.error();
  const std::string gnuplot = find_gnuplot();
  if (gnuplot.empty()) {
    const char* e = std::getenv("AUGRIG_GNUPLOT");
    return make_error(where, "cannot plot: gnuplot ",
                      e && *e ? std::string("($AUGRIG_GNUPLOT=") + e + ") is not an executable file"
                              : std::string("is not installed (no gnuplot on PATH)"),
                      "; the statistics plot needs it (Debian: apt-get install gnuplot-nox)");
  }
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path parent = fs::path(png_path).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  fs::remove(png_path, ec);

  // gnuplot reads the script from a socket (not a pipe): send() with MSG_NOSIGNAL cannot raise
  // SIGPIPE in this process if gnuplot exits early. Its stderr goes to a temporary file.
  char err_path[] = "/tmp/augrig-gnuplot-XXXXXX";
  const int err_fd = ::mkstemp(err_path);
  if (err_fd < 0) return make_error(where, "cannot create a temporary file for gnuplot's messages");
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) {
    ::close(err_fd);
    ::unlink(err_path);
    return make_error(where, "socketpair() failed");
  }
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, sv[1], 0);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, err_fd, 2);
  std::string arg0 = gnuplot;
  char* argv[] = {arg0.data(), nullptr};
  pid_t pid = 0;
  const int rc = ::posix_spawn(&pid, gnuplot.c_str(), &fa, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&fa);
  ::close(sv[1]);
  ::close(err_fd);
  if (rc != 0) {
    ::close(sv[0]);
    ::unlink(err_path);
    return make_error(where, "cannot run ", gnuplot, " (error ", rc, ")");
  }
  bool sent = true;
  for (std::size_t off = 0; off < text.size();) {
    const ssize_t n = ::send(sv[0], text.data() + off, text.size() - off, MSG_NOSIGNAL);
    if (n <= 0) {
      if (n < 0 && errno == EINTR) continue;
      sent = false;
      break;
    }
    off += static_cast<std::size_t>(n);
  }
  ::close(sv[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  const std::string messages = read_text(err_path, 600);
  ::unlink(err_path);
  const bool ok = sent && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (!ok || !fs::exists(png_path, ec) || fs::file_size(png_path, ec) == 0) {
    return make_error(where, gnuplot, " failed",
                      WIFEXITED(status) ? " (exit " + std::to_string(WEXITSTATUS(status)) + ")" : "",
                      messages.empty() ? std::string() : ": " + messages);
  }
  return {};
}

}  // namespace augrig::recorder
