// What the augrig commands share (internal to app/): how a command fails (CommandError, exit codes
// 1 and 2), turning library errors into user messages, flag values used by several commands, GL
// context creation and the common outputs (PNG frames, stats.csv).
#pragma once

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <ostream>
#include <string>

#include <Eigen/Core>

#include "app/commands.hpp"
#include "core/expected.hpp"
#include "core/frame.hpp"
#include "recorder/record.hpp"
#include "render/augmenter.hpp"
#include "render/boom_control.hpp"
#include "render/gl_context.hpp"
#include "render/models.hpp"
#include "render/rig.hpp"
#include "render/stats.hpp"

namespace augrig::recorder {
class RecordingReader;
}

namespace augrig::app {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0);
std::string fmt_ms(double ms);

// A command failed for a reason the user can fix in an input (exit 1) or in the flags (exit 2).
struct CommandError {
  int code;
  std::string message;
};
[[noreturn]] void runtime_error(const std::string& what);
[[noreturn]] void usage_error(const std::string& what);

// Library errors read "module::function(): file:line: ..."; the CLI prints its own prefix instead,
// so the user sees "augrig augment: file:line: ...".
std::string user_message(const Error& e);

template <typename T>
T unwrap(Expected<T> e) {
  if (!e) runtime_error(user_message(e.error()));
  return std::move(e).value();
}
void check(const Status& s);

// Parses a command's flags; prints its help and returns nullopt-like `help = true` args for --help.
ParsedArgs parse_or_usage(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs);

// ---- Shared flag values ---------------------------------------------------------------------------

// "default" is the seed paper's rig; anything else a rig file.
Rig load_rig_arg(const std::string& value);
ReceiverDraw parse_receiver_draw(const std::string& v);
PixelFormat parse_bayer(const std::string& v);
// A whole number in [lo, hi] for flag `flag`, else a usage error.
long long parse_integer(const std::string& flag, const std::string& v, long long lo, long long hi);
double parse_real(const std::string& flag, const std::string& v);

// --boom: track (the receptacle, from nav), fixed:EL_DEG,AZ_DEG,EXT_M, or script:FILE.csv
// (render/boom_control.hpp). A script's times are seconds from the run's first frame.
struct BoomArg {
  BoomMode mode = BoomMode::kTrackReceptacle;
  BoomArticulation fixed;
  BoomScript script;
  // The articulation for a frame `t_s` after the first, given what tracking would command.
  BoomCommand command(double t_s, const BoomCommand& tracked, const BoomLimits& limits) const;
};
BoomArg parse_boom_arg(const std::string& v);

// The receiver model and where its receptacle is: the built-in model knows its own receptacle;
// a model file relies on the rig's receiver.receptacle_m.
struct ReceiverSetup {
  std::shared_ptr<const Model> model;  // null: let the Augmenter load the rig's file
  Eigen::Vector3d receptacle_m = Eigen::Vector3d::Zero();
};
ReceiverSetup receiver_setup(const Rig& rig);

std::unique_ptr<GlContext> make_gl_context();
void make_dirs(const fs::path& dir);

// ---- Outputs --------------------------------------------------------------------------------------

// Per-frame file names: left/right keep their own stems, the visualisations use the left one.
struct FrameNames {
  std::string left, right;
};
void write_png(const fs::path& path, const Image& image);
// Everything `augment` and `demo` write for one stereo frame (docs/CLI.md gives the layout); `raw`
// is the frame `r` was made from (its augmented images may be the changed boxes only).
void write_frame_outputs(const fs::path& out, const FrameNames& n, const StereoFrame& raw,
                         const StereoResult& r);

// A frame for the recorder from what the augmenter made: the augmented images as made (whole, or
// only their changed boxes: AugmentedOutput), the masks and the statistics. The caller adds the
// raw frame, the poses and the boom.
recorder::FrameRecord frame_record(const StereoResult& r);

// stats.csv, one row per stereo frame, flushed per row so a failed run keeps what it counted.
class StatsCsv {
 public:
  explicit StatsCsv(const fs::path& path);
  void add(const OcclusionStats& s);

 private:
  fs::path path_;
  std::ofstream out_;
};

// ---- Positional arguments and recordings ------------------------------------------------------

// Parses the flags of `args` and exactly the positionals `names` (a usage error names what is
// missing or extra); `positionals` gets them in order.
ParsedArgs parse_with_positionals(const std::vector<std::string>& args, const std::vector<OptionSpec>& specs,
                                  const std::vector<std::string>& names, std::vector<std::string>& positionals);
// Opens a recording, or fails the command naming it.
std::unique_ptr<recorder::RecordingReader> open_recording(const std::string& dir);
// A problem of the recording as a whole (RecordingReader::problems()), naming its file.
std::string recording_problem(const recorder::RecordingReader& reader, const std::string& problem);

// Runs a command body, turning its errors (and anything unexpected) into one stderr line and an exit code.
template <typename Body>
int guarded(const std::string& command, std::ostream& err, Body&& body) {
  try {
    return body();
  } catch (const CommandError& e) {
    // One line: the message, and for usage errors where to look.
    err << "augrig " << command << ": " << e.message
        << (e.code == kExitUsage ? " (see augrig " + command + " --help)" : std::string()) << "\n";
    return e.code;
  } catch (const std::exception& e) {
    err << "augrig " << command << ": internal error: " << e.what() << "\n";
    return kExitRuntime;
  }
}

}  // namespace augrig::app
