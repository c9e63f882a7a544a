// plot: the occlusion statistics of a run over time as a PNG, drawn by gnuplot (Debian package
// gnuplot-nox, or any gnuplot 5 with the pngcairo or png terminal) driven through a pipe. gnuplot
// is needed only for this plot: without it plot_occlusion_stats() returns an error saying so, and
// everything else works.
#pragma once

#include <string>
#include <vector>

#include "core/expected.hpp"
#include "recorder/record.hpp"
#include "render/stats.hpp"

namespace augrig::recorder {

// gnuplot's path: $AUGRIG_GNUPLOT when set, else the first `gnuplot` on PATH; empty when none.
std::string find_gnuplot();

// A flight phase starting at t_s (seconds from the first frame plotted): a dashed vertical line
// on every panel, named at the top.
struct PhaseMarker {
  double t_s = 0;
  std::string name;
};

struct StatsPlotOptions {
  std::string title = "Occlusion statistics";
  int width_px = 1200;
  int height_px = 1100;
  std::vector<PhaseMarker> phases;
};

// The recorded phase changes ("phase: NAME" events, PipelineParts::phase_of) in time order.
struct PhaseEvent {
  TimestampNs t_ns = 0;  // on the clock of the statistics they were recorded beside
  std::string name;
};
std::vector<PhaseEvent> phase_events(const std::vector<EventRecord>& events);
// Those events as markers on a plot whose time starts at `t0_ns`; markers outside [t0_ns, t_end_ns]
// are left out (a phase that began before the first frame plotted starts at 0).
std::vector<PhaseMarker> phase_markers(const std::vector<PhaseEvent>& phases, TimestampNs t0_ns, TimestampNs t_end_ns);

// Three panels over time (seconds from the first frame): occluded % of the receiver in the left
// and right images and the boom overlap (% of the union of both boom masks); the receiver and boom
// coverage of each image (% of its pixels); the four stereo classes (% of the left receiver
// pixels: both, left only, right only, neither). The phases' markers on each panel. Frames are drawn in the given order; non-finite
// values leave gaps. Errors: no frames, gnuplot missing, gnuplot failing (its message is quoted).
Status plot_occlusion_stats(const std::vector<OcclusionStats>& frames, const std::string& png_path,
                            const StatsPlotOptions& options = {});

// Runs gnuplot on a script that writes `png_path` (other plots, e.g. eval/report.hpp's); errors
// start with `caller` and name the file: gnuplot missing, failing (its message quoted), no image.
Status run_gnuplot(const std::string& script, const std::string& png_path, const std::string& caller);
// The script lines choosing the PNG terminal (pngcairo where gnuplot has it), text not "enhanced"
// (underscores in names stay underscores).
std::string gnuplot_png_terminal(int width_px, int height_px);
// A gnuplot single-quoted string ('' stands for a quote inside).
std::string gnuplot_quote(const std::string& s);
// The script lines that open `panels` plots over time one above the other: the title, a grid, the
// keys outside on the right (`key_margin_chars` wide), the time axis from the first frame.
std::string gnuplot_time_panels(int panels, const std::string& title, int key_margin_chars);

}  // namespace augrig::recorder
