// run_config: the live pipeline configured from typed options and run to its end: what `augrig
// run` does once its flags are parsed, and what `augrig demo` does with a display (the simulated
// flight in real time in the window), filling the same options itself rather than assembling an
// argv for `run`.
#pragma once

#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "app/cli.hpp"
#include "net/foxglove_server.hpp"
#include "render/camera_look.hpp"

namespace augrig::app {

// --nav-fault STREAM=T0-T1: nothing of a simulated nav stream is sent over [t0_s, t1_s] (scenario seconds).
struct NavFault {
  std::string stream;
  double t0_s = 0, t1_s = 0;
};

// `augrig run`'s flags as values; each default is the flag's when not given. Optional where a flag
// given with any value means something (the capture-only refusals name the augmenting flags given).
struct RunOptions {
  // Frames: --source, else the rig's cameras' 'source' keys.
  std::string source_uri;
  std::optional<std::string> rig;  // --rig (load_rig_arg's value)
  bool capture_only = false;       // --capture-only (a rig without a boom section means it too)
  // Poses: --scene, --poses, the live nav (--nav), the recording's own or the simulation's truth.
  std::optional<std::string> scene, poses_csv;
  TimestampNs pose_tolerance_ns = 0;
  bool nav_given = false;                                        // --nav
  bool nav_sim = false;                                          // --nav sim
  std::vector<std::pair<std::string, std::string>> nav_streams;  // --nav STREAM=URI,... (not sim)
  // Read only with streams of both aircraft (nav_sim included), as the live fusion needs them.
  std::vector<std::pair<std::string, std::string>> aircraft;  // --aircraft WHO=FILE, WHO checked
  std::optional<double> nav_stale_s;                          // --nav-stale, > 0
  std::vector<NavFault> nav_faults;                           // --nav-fault (with --nav sim)
  // --camera-clock online: each camera's clock estimated from its images during the run and applied
  // to the poses once its 1-sigma is at most --camera-clock-sigma-ms (pipeline/camera_clock_online.hpp).
  bool camera_clock_online = false;
  double camera_clock_apply_sigma_ms = 0.5;  // --camera-clock-sigma-ms
  double terrain_height_m = 0;               // --terrain-height-m: the ground the cameras see
  // Augmentation and the sinks.
  std::optional<BoomArg> boom;
  std::optional<ReceiverDraw> receiver_draw;
  Look look = Look::kCamera;
  std::vector<std::string> sinks;  // --sink SCHEME:ARG, in the order given
  std::optional<std::string> record;
  bool overwrite = false;
  std::optional<std::string> out;  // stats.csv, the images of every `every`-th pair, screenshots
  int every = 0;                   // 0: no images
  bool ground_truth = false;
  std::optional<net::ServeOptions> serve;  // --serve, --serve-queue-mb (started with the rig known)
  // Stops, status and the window.
  double duration_s = 0;
  std::uint64_t max_pairs = 0;
  double status_every_s = 1.0;
  bool headless = false;
  std::uint64_t screenshot_at = 0;
};

// The flags run and the demo's window share, each parsed as `augrig run` parses it (its messages).
double parse_duration_arg(const std::string& v);          // --duration S, >= 0
std::uint64_t parse_max_pairs_arg(const std::string& v);  // --frames N, >= 1
Look parse_look_arg(const std::string& v);                // --look plain|camera

// Opens the source, configures the pipeline from `o`, prints the run's banner and runs it (the
// window when a display is present and not `headless`), then prints the summary. Returns the exit
// code; errors are CommandErrors (messages prefixed "augrig run:" by the caller's `guarded`).
int run_live(const RunOptions& o, std::ostream& out, std::ostream& err);

}  // namespace augrig::app
